"""The environment `franka_composer.load` returns: Composer's, changed only through its public
surface. `fast_path.FastEnvironment` is the same environment, faster, where the installed
dm_control has what it needs; this one is the stock path it falls back to.

Five things differ from plain `composer.Environment`:
- Its time limit is a whole number of control steps: a time-out is a LAST step with
  discount 1 after exactly that many steps, whatever the float rounding of physics time.
  Composer ends an episode at the first control step whose physics time is >= its time
  limit, and physics time is a float sum of physics timesteps (1250 additions of 0.002 s
  in a 50-step episode: 2.4999999999999463 s), so a limit of exactly N periods could make
  N or N + 1 steps; the limit handed to Composer lies halfway through the last step
  (`composer_time_limit`).
- A closed environment says so: `close()` twice is harmless, and `reset`, `step` or
  `physics` afterwards raise `EnvironmentClosedError` (Composer fails deep inside).
- A step whose physics diverged gets the task's reward for the state it reports (MuJoCo
  has reset it), not Composer's fixed 0.0, which for a sparse task is the reward for
  reaching the goal. Like dm_control, a step diverged when MuJoCo raised a new warning.
- Threads: a reset or step that renders camera observations from a thread other than the
  one that renders the environment raises `render_owner.RenderThreadError` before anything
  moves, and `close()` works from any thread.
- Pickling or copying it is a TypeError saying what to do instead.
"""

from __future__ import annotations

import math
import numbers

import dm_env
import numpy as np
from dm_control import composer

from franka_composer import render_owner
from franka_composer.validation import check_number

#: No time limit (Composer's own default).
NO_LIMIT = float("inf")


class EnvironmentClosedError(RuntimeError):
    """`reset`, `step` or `physics` used after `close()`."""


class GoalEnvironment(composer.Environment):
    """`composer.Environment` with a time limit of whole control steps, clear errors once
    closed and the task's reward on a diverged step."""

    def __init__(self, task, *, time_limit: float = NO_LIMIT, **kwargs) -> None:
        self._episode_steps = control_steps(time_limit, task.control_timestep)
        super().__init__(task, time_limit=composer_time_limit(
            self._episode_steps, task.control_timestep), **kwargs)
        self._closed = False
        # Its resets and steps render (camera observations), on one thread only.
        self._renders_observations = bool(getattr(task, "pixel_keys", ()))

    @property
    def episode_steps(self) -> int | None:
        """Control steps before an episode times out; None: it never does."""
        return None if self._episode_steps == NO_LIMIT else int(self._episode_steps)

    @property
    def time_limit(self) -> float:
        """Seconds of physics before an episode times out (whole control steps; inf: none)."""
        return self._episode_steps * self.control_timestep()

    def set_episode_steps(self, steps: int | None) -> None:
        """Makes episodes time out after `steps` control steps (a whole number >= 1; None:
        never), from the next step on."""
        limit = NO_LIMIT if steps is None else check_number("steps", steps, minimum=1,
                                                            integer=True)
        self._episode_steps = limit
        self._time_limit = composer_time_limit(limit, self.control_timestep())

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def physics(self):
        self._check_open()
        return super().physics

    def close(self) -> None:
        """Frees the physics, from any thread; closing again is harmless."""
        if not self._closed:
            render_owner.release(self, super().physics)
            super().close()
            self._closed = True

    @property
    def reset_due(self) -> bool:
        """Whether the next step resets: no episode is under way (none begun, the last one
        ended, or a reset raised part-way)."""
        return self._reset_next_step

    def reset(self) -> dm_env.TimeStep:
        self._check_can_step()
        # A reset that raises leaves no episode to step, so the next step resets, as after a
        # LAST step: Composer sets this only once a reset has succeeded, and mid-episode a
        # step went on from what the failed reset left (the arm at qpos0, pointing up).
        self._reset_next_step = True
        return super().reset()

    def step(self, action) -> dm_env.TimeStep:
        self._check_can_step()
        warnings = super().physics.data.warning.number.copy()
        timestep = super().step(action)
        if timestep.last() and diverged(super().physics, warnings):
            timestep = timestep._replace(reward=self.task.get_reward(super().physics))
        return timestep

    def __reduce_ex__(self, protocol):
        # (Composer's own failed deep inside: an MJCF element's NotImplementedError, a
        # weakref's TypeError.)
        raise TypeError("a dm_env environment of franka_composer cannot be pickled or copied "
                        "(its MuJoCo physics and MJCF model cannot): make another with "
                        "franka_composer.load (the same arguments and seed give the same "
                        "episodes), or use the Gymnasium env (gym.make), whose pickle and "
                        "copies make a fresh env with the same options")

    def _check_can_step(self) -> None:
        """Open, and on the thread that renders it if its observations are images."""
        self._check_open()
        if self._renders_observations:
            render_owner.claim(self)

    def _check_open(self) -> None:
        if self._closed:
            raise EnvironmentClosedError(
                "this environment is closed (close() freed its physics): make a new one")


def diverged(physics, warnings_before: np.ndarray) -> bool:
    """Whether MuJoCo raised a warning since `warnings_before` (its warning counters), which
    is when dm_control takes the physics to have diverged."""
    return bool((physics.data.warning.number > warnings_before).any())


def ended_by_divergence(timestep: dm_env.TimeStep, task) -> bool:
    """Whether `timestep` is a LAST step that the physics diverging ended: Composer's
    discount 0 with the goal not reached (the goal's discount is 0 with `task.success`, a
    time-out's 1). MuJoCo has reset the simulation there: its observation is no state the
    episode reached."""
    return bool(timestep.last() and timestep.discount == 0 and not task.success)


def check_time_limit(time_limit) -> float:
    """`time_limit` as seconds (None, or inf as in Composer: `NO_LIMIT`), or a ValueError
    saying what it may be."""
    if time_limit is None:
        return NO_LIMIT
    if (isinstance(time_limit, bool) or not isinstance(time_limit, numbers.Real)
            or not time_limit > 0):  # type: ignore[operator]  # (NaN refused too.)
        raise ValueError(f"time_limit must be a number of seconds > 0, or None (or inf, as "
                         f"in Composer) for no limit, got {time_limit!r}")
    try:
        return float(time_limit)
    except OverflowError:  # An int past a float's range: longer than any episode.
        return NO_LIMIT


def control_steps(time_limit: float, control_timestep: float) -> float:
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
