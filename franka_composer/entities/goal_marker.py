"""A visible, non-colliding marker that shows the goal in rendered images."""

from __future__ import annotations

import numpy as np
from dm_control import composer, mjcf


class GoalMarker(composer.Entity):
    """A translucent sphere site; the task moves it with `set_position` each episode.

    It is a site, not a geom, so it never collides and costs nothing in the physics step.
    """

    def _build(self, radius: float = 0.02, rgba=(0.9, 0.1, 0.1, 0.6), name: str = "goal") -> None:
        self._mjcf_root = mjcf.RootElement(model=name)
        self._site = self._mjcf_root.worldbody.add(
            "site", name="marker", type="sphere", size=(radius,), rgba=rgba, group=0
        )

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        return self._mjcf_root

    @property
    def site(self):
        return self._site

    def set_position(self, physics, position: np.ndarray) -> None:
        """Moves the marker to `position` (m, world frame; the marker sits at the origin of
        its attachment frame, so the site offset is the world position)."""
        physics.bind(self._site).pos = position
