"""Where objects start and goals lie: plain data, one record per task."""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Box2D:
    """An axis-aligned rectangle on the surface: `centre` (x, y) and full `size` (m)."""

    centre: tuple[float, float]
    size: tuple[float, float] = (0.3, 0.3)

    @property
    def low(self) -> np.ndarray:
        return np.asarray(self.centre) - np.asarray(self.size) / 2

    @property
    def high(self) -> np.ndarray:
        return np.asarray(self.centre) + np.asarray(self.size) / 2

    def contains(self, xy, tolerance: float = 1e-9) -> bool:
        xy = np.asarray(xy)[:2]
        return bool(np.all(xy >= self.low - tolerance) and np.all(xy <= self.high + tolerance))


@dataclasses.dataclass(frozen=True)
class Workspace:
    """Object and goal ranges (world frame, m) and the goal-height rule.

    Attributes:
      object_box: where the object's centre starts, on the surface.
      goal_box: where the goal's (x, y) is drawn.
      goal_max_height: the highest a goal is lifted above the object's resting height;
        0 keeps every goal on the surface.
      goal_in_air_probability: chance that a goal is lifted, uniformly in
        [0, goal_max_height], rather than left on the surface.
    """

    object_box: Box2D
    goal_box: Box2D
    goal_max_height: float = 0.0
    goal_in_air_probability: float = 0.0


PUSH = Workspace(object_box=Box2D((0.6, 0.0)), goal_box=Box2D((0.6, 0.0)))
SLIDE = Workspace(object_box=Box2D((0.6, 0.0)), goal_box=Box2D((1.0, 0.0)))
PICK_AND_PLACE = Workspace(object_box=Box2D((0.6, 0.0)), goal_box=Box2D((0.6, 0.0)),
                           goal_max_height=0.2, goal_in_air_probability=0.7)
