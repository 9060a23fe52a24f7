"""Episode time limits: seconds as users give them, whole control steps as episodes run.

Composer ends an episode at the first control step whose physics time is >= its time limit.
Physics time is a float sum of physics timesteps (1250 additions of 0.002 s in a 50-step
episode), which can land a hair either side of N control periods, so a limit of exactly
N periods could make N or N + 1 steps. The limit handed to Composer therefore lies halfway
through the last step (`composer_time_limit`): exactly N steps happen whatever the rounding.
"""

from __future__ import annotations

import math
import numbers

#: No time limit (Composer's own default).
NO_LIMIT = float("inf")


def check_time_limit(time_limit) -> float:
    """`time_limit` as seconds (None: `NO_LIMIT`), or a ValueError saying what it may be."""
    if time_limit is None:
        return NO_LIMIT
    if (isinstance(time_limit, bool) or not isinstance(time_limit, numbers.Real)
            or not time_limit > 0):
        raise ValueError(f"time_limit must be a number of seconds > 0, or None for no limit, "
                         f"got {time_limit!r}")
    return float(time_limit)


def episode_steps(time_limit: float, control_timestep: float) -> float:
    """Control steps an episode of `time_limit` seconds makes: up to the first step that
    ends at or after it (an int; `NO_LIMIT` without a limit)."""
    if time_limit == NO_LIMIT:
        return NO_LIMIT
    # A millionth of a step: 2.5 s / 0.05 s is 50 steps even where the division rounds up.
    return max(1, math.ceil(time_limit / control_timestep - 1e-6))


def composer_time_limit(steps: float, control_timestep: float) -> float:
    """The time limit that makes Composer end episodes after exactly `steps` control steps:
    half a step before the last one ends."""
    return NO_LIMIT if steps == NO_LIMIT else (steps - 0.5) * control_timestep
