"""Where several objects start: apart, at uniform points of the object box.

One rule for the episodes (`goal_task.ApartPlacer`) and for the check that a configuration
leaves room for it (`TaskConfig.check`): a box too small for its objects made every reset
fail (Composer's EpisodeInitializationError after its retries), long after the env was
made.
"""

from __future__ import annotations

import functools
from typing import Callable, Sequence

import numpy as np

#: Room (m) kept between the footprints of objects placed at an episode's start.
PLACEMENT_MARGIN = 0.01
#: Draws per object before the placement gives up (Composer then retries the episode).
MAX_ATTEMPTS = 100
#: Placements the configuration check simulates; one that gives up refuses the box. A
#: box passes with a chance of giving up below about 1/`CHECKED_PLACEMENTS` per placement;
#: an episode's placement begins again up to `PLACEMENT_RESTARTS` times (and Composer
#: retries the episode 10 times after that): under 1e-20 of resets are retried, none fail.
#: (Begun again by Composer, a reset that succeeds logs an ERROR line: 26 in 3,000 resets
#: of a box that just passes.)
CHECKED_PLACEMENTS = 200
#: Times an episode's placement begins again before the episode is given up to Composer.
PLACEMENT_RESTARTS = 10


def place_apart(draw: Callable[[], np.ndarray], radii: Sequence[float]) -> list | int:
    """Points (x, y) from `draw()`, one per footprint radius in `radii`, each footprint
    `PLACEMENT_MARGIN` or more from those before it (rejection sampling); or the index of
    the first object for which `MAX_ATTEMPTS` draws found no room."""
    placed: list[tuple[np.ndarray, float]] = []
    for index, radius in enumerate(radii):
        for _ in range(MAX_ATTEMPTS):
            xy = np.asarray(draw())
            if all(np.linalg.norm(xy - other) >= radius + other_radius + PLACEMENT_MARGIN
                   for other, other_radius in placed):
                break
        else:
            return index
        placed.append((xy, radius))
    return [xy for xy, _ in placed]


def room_to_place_apart(low, high, radii: Sequence[float]) -> bool:
    """Whether `place_apart` places footprints of `radii` in the box [`low`, `high`] every
    time in `CHECKED_PLACEMENTS` simulated placements (seeded: the same answer each time;
    simulated once per box and footprints, not at every check of a config: 3 ms)."""
    if len(radii) < 2:
        return True
    return _room(tuple(map(float, low)), tuple(map(float, high)), tuple(map(float, radii)))


@functools.lru_cache(maxsize=64)
def _room(low: tuple, high: tuple, radii: tuple) -> bool:
    random = np.random.RandomState(0)
    box = np.asarray(low), np.asarray(high)
    return all(not isinstance(place_apart(lambda: random.uniform(*box), radii), int)
               for _ in range(CHECKED_PLACEMENTS))
