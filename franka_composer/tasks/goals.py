"""What a task asks for: one `Goal` per kind, chosen by name in the task's configuration.

A goal samples the desired goal each episode (from Composer's seeded random state only),
reads the achieved goal from MuJoCo through NumPy views (every step), names the distance
that measures them (`rewards.METRICS`: the reward is a function of the two goals alone, so
HER relabelling is exact) and shows the desired goal with a marker in rendered images.

- "object_position" (push, slide, pick and place): the object's centre to a point on the
  surface, or lifted above it with some probability.
- "tcp_position" (reach): the tool centre point to a point in the box above the object
  square.
- "stacked" (stack): block 1 on the surface at a point of the goal square, block 2 right on
  top of it; the achieved goal is both blocks' positions (6 numbers).
- "orientation" (flip): the cube to an orientation (w, x, y, z): by default a face up at a
  yaw near the heading the fewest tips give it (`config.orientation_goal`), or panda-gym's
  uniformly random orientation.
"""

from __future__ import annotations

import abc
from typing import Callable

import mujoco
import numpy as np
from dm_control.composer.variation import distributions, rotations

from franka_composer.entities.goal_marker import GoalMarker

#: Where the flip task's goal cube is shown (m, world frame): beside the object square,
#: in the air, where the workspace camera sees it and nothing runs into it.
ORIENTATION_MARKER_POSITION = (0.6, 0.24, 0.12)


class Goal(abc.ABC):
    """One kind of goal for a task with `props` (its objects, possibly none)."""

    #: How the achieved and desired goals are compared (`rewards.METRICS`).
    metric = "euclidean"
    #: How many numbers a goal holds.
    size = 3

    def __init__(self, config, arena, panda, props) -> None:
        self._config, self._arena, self._panda, self._props = config, arena, panda, props
        self.marker = self._make_marker()
        self._views: list[np.ndarray] = []

    @abc.abstractmethod
    def _elements(self) -> list:
        """The MJCF elements (with their attribute) the achieved goal is read from."""

    @abc.abstractmethod
    def sample(self, random_state: np.random.RandomState) -> np.ndarray:
        """This episode's desired goal."""

    def _make_marker(self) -> GoalMarker:
        return GoalMarker()

    def marker_sites_by_prop(self) -> list:
        """The marker sites drawn in their objects' colours, one per object in order (none
        where the marker has a colour of its own): `object_rgb` recolours each with its
        object, so that a pixel policy can still tell which object goes where."""
        return []

    def show(self, physics, desired: np.ndarray) -> None:
        """Puts the marker on the desired goal."""
        self.marker.set_position(physics, desired)

    def bind(self, physics) -> None:
        """Takes the views `achieved` reads (valid while this physics lives)."""
        self._views = [getattr(physics.bind(element), attribute).view(np.ndarray)
                       for element, attribute in self._elements()]

    def achieved(self) -> np.ndarray:
        """The achieved goal now (a view for one element: read, do not keep)."""
        if len(self._views) == 1:
            return self._views[0]
        return np.concatenate(self._views)

    def _surface(self) -> float:
        return self._arena.surface_height


class ObjectPositionGoal(Goal):
    """The object's centre to a point of the goal square, on the surface or, with
    `goal_in_air_probability`, lifted uniformly up to `goal_max_height` above it."""

    def __init__(self, config, arena, panda, props) -> None:
        super().__init__(config, arena, panda, props)
        workspace = config.workspace
        self._xy = distributions.Uniform(low=workspace.goal_box.low,
                                         high=workspace.goal_box.high)
        self._in_air = distributions.Bernoulli(prob=workspace.goal_in_air_probability)
        self._lift = distributions.Uniform(low=0.0, high=workspace.goal_max_height)

    def _elements(self) -> list:
        return [(self._props[0].position, "sensordata")]

    def _base_height(self) -> float:
        return self._props[0].resting_height + self._surface()

    def sample(self, random_state: np.random.RandomState) -> np.ndarray:
        height = self._base_height()
        xy = self._xy(random_state=random_state)
        if (self._config.workspace.goal_max_height > 0
                and self._in_air(random_state=random_state)):
            height += self._lift(random_state=random_state)
        return np.array([xy[0], xy[1], height])


class TcpPositionGoal(ObjectPositionGoal):
    """The tool centre point to a point above the goal square (reach): the same rule as
    `ObjectPositionGoal` from the surface up (a lift probability of 1 makes it uniform in
    the box up to `goal_max_height`)."""

    def _elements(self) -> list:
        return [(self._panda.tcp_site, "xpos")]

    def _base_height(self) -> float:
        return self._surface()


class StackedGoal(Goal):
    """Block 1 resting on the surface at a point of the goal square, block 2 right on top
    of it; the achieved goal is both blocks' centres (6 numbers, compared as one vector:
    panda-gym's rule)."""

    size = 6

    def __init__(self, config, arena, panda, props) -> None:
        super().__init__(config, arena, panda, props)
        workspace = config.workspace
        self._xy = distributions.Uniform(low=workspace.goal_box.low,
                                         high=workspace.goal_box.high)

    def _make_marker(self) -> GoalMarker:
        return GoalMarker(shape="box", size=self._props[0].resting_height,
                          rgbas=[prop.rgba[:3] + (0.35,) for prop in self._props])

    def marker_sites_by_prop(self) -> list:
        return self.marker.sites

    def _elements(self) -> list:
        return [(prop.position, "sensordata") for prop in self._props]

    def sample(self, random_state: np.random.RandomState) -> np.ndarray:
        xy = self._xy(random_state=random_state)
        half = self._props[0].resting_height
        bottom = np.array([xy[0], xy[1], self._surface() + half])
        return np.concatenate([bottom, bottom + [0.0, 0.0, 2 * half]])

    def show(self, physics, desired: np.ndarray) -> None:
        self.marker.set_positions(physics, desired.reshape(-1, 3))


_HALF_TURN = np.sqrt(0.5)
#: The smallest rotation from the cube's starting orientation (upright, body axes along the
#: world's) that turns each face up (w, x, y, z), faces in `faces.FACE_COLOURS`' order +x,
#: -x, +y, -y, +z, -z: a quarter turn about the horizontal axis the cube tips over for a
#: side face; half a turn about y (two tips towards +x) for the bottom face.
FACE_UP_QUATERNIONS = np.array([
    (_HALF_TURN, 0.0, -_HALF_TURN, 0.0), (_HALF_TURN, 0.0, _HALF_TURN, 0.0),
    (_HALF_TURN, _HALF_TURN, 0.0, 0.0), (_HALF_TURN, -_HALF_TURN, 0.0, 0.0),
    (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)])


def face_up_orientation(face: int, yaw: float) -> np.ndarray:
    """Face `face` (an index of `FACE_UP_QUATERNIONS`) up, turned `yaw` rad about world z
    from the heading the fewest tips give it (w, x, y, z)."""
    turn = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    quaternion = np.zeros(4)
    mujoco.mju_mulQuat(quaternion, turn, FACE_UP_QUATERNIONS[face])
    return quaternion


class OrientationGoal(Goal):
    """The cube to an orientation (w, x, y, z); the marker is a translucent copy of the cube
    shown in that orientation beside the workspace.

    "face_up" goals (`OrientationGoalSettings`): a face drawn uniformly from the six, up,
    turned a uniform yaw in [-yaw_range, yaw_range] about world z; orientations a cube
    resting on the floor has, which a top-down hand reaches by tipping and pushing it.
    "uniform": panda-gym's uniformly random orientation, mostly out of this hand's reach.
    """

    metric = "rotation_angle"
    size = 4

    def __init__(self, config, arena, panda, props) -> None:
        super().__init__(config, arena, panda, props)
        settings = config.orientation_goal
        self._uniform = settings.kind == "uniform"
        self._orientation = rotations.UniformQuaternion()
        self._face = distributions.UniformInteger(low=0, high=len(FACE_UP_QUATERNIONS))
        self._yaw = distributions.Uniform(low=-settings.yaw_range, high=settings.yaw_range)

    def _make_marker(self) -> GoalMarker:
        cube = self._props[0]
        return GoalMarker(shape="box", size=cube.resting_height,
                          rgbas=[cube.rgba[:3] + (0.35,)], face_colours=True)

    def marker_sites_by_prop(self) -> list:
        return self.marker.sites

    def _elements(self) -> list:
        return [(self._props[0].orientation, "sensordata")]

    def sample(self, random_state: np.random.RandomState) -> np.ndarray:
        if self._uniform:
            return np.asarray(self._orientation(random_state=random_state), dtype=np.float64)
        face = int(self._face(random_state=random_state))
        return face_up_orientation(face, float(self._yaw(random_state=random_state)))

    def show(self, physics, desired: np.ndarray) -> None:
        self.marker.set_pose(physics, ORIENTATION_MARKER_POSITION, desired)


#: Every kind of goal, by the name a `TaskConfig` gives.
GOALS: dict[str, Callable[..., Goal]] = {
    "object_position": ObjectPositionGoal, "tcp_position": TcpPositionGoal,
    "stacked": StackedGoal, "orientation": OrientationGoal}
