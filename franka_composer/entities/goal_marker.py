"""Visible, non-colliding markers that show the goal in rendered images."""

from __future__ import annotations

import numpy as np
from dm_control import composer, mjcf

from franka_composer.entities.faces import add_coloured_faces

#: A site group MuJoCo does not draw by default (it draws groups 0-2): hidden markers.
HIDDEN_GROUP = 3


class GoalMarker(composer.Entity):
    """Translucent sites the task moves each episode: one sphere (a position goal), one box
    per block (stacked goals), or a box with coloured faces in a body the task turns (an
    orientation goal). Sites, not geoms: they never collide and cost nothing in the step.

    Args:
      shape: "sphere" or "box".
      size: the sphere's radius or the box's half-size (m).
      rgbas: one colour per marker site.
      face_colours: a single box in a body, with its faces coloured like the flip cube's.
    """

    def _build(self, shape: str = "sphere", size: float = 0.02,
               rgbas=((0.9, 0.1, 0.1, 0.6),), face_colours: bool = False,
               name: str = "goal") -> None:
        self._mjcf_root = mjcf.RootElement(model=name)
        self._body = None
        parent = self._mjcf_root.worldbody
        if face_colours:
            self._body = parent.add("body", name="marker_body")
            parent = self._body
        sizes = (size,) if shape == "sphere" else (size,) * 3
        self._sites = [
            parent.add("site", name="marker" if len(rgbas) == 1 else f"marker{index + 1}",
                       type=shape, size=sizes, rgba=tuple(rgba), group=0)
            for index, rgba in enumerate(rgbas)]
        if face_colours:
            add_coloured_faces(self._body, size, alpha=0.5)

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        return self._mjcf_root

    @property
    def sites(self) -> list:
        """The marker sites, in the order of `rgbas`."""
        return list(self._sites)

    def hide(self) -> None:
        """Leaves the marker out of every image (cameras and `render`): its sites go to a
        group that is not drawn. Sites have no physics, so nothing else changes."""
        for site in self._mjcf_root.find_all("site"):
            site.group = HIDDEN_GROUP

    def set_position(self, physics, position: np.ndarray) -> None:
        """Moves the marker to `position` (m, world frame; the marker sits at the origin of
        its attachment frame, so the site offset is the world position)."""
        physics.bind(self._sites[0]).pos = position

    def set_positions(self, physics, positions) -> None:
        """Moves each marker site to its position (m, world frame)."""
        for site, position in zip(self._sites, positions):
            physics.bind(site).pos = position

    def set_pose(self, physics, position, quaternion) -> None:
        """Puts the marker body (with its faces) at `position`, turned by `quaternion`
        (w, x, y, z); takes effect at the next forward kinematics."""
        body = physics.bind(self._body)
        body.pos = position
        body.quat = quaternion
