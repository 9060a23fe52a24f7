"""The objects the robot moves: blocks (push, pick_and_place, stack, flip) and a puck (slide).

Both are dm_control `Primitive` props, which bring frame sensors and the free-prop
observables (position, orientation quaternion, linear and angular velocity, world frame),
plus an `orientation_euler` observable for the paper's observation vector.
"""

from __future__ import annotations

import math

import numpy as np
from dm_control.composer import define
from dm_control.entities.props import primitive

from franka_composer.contacts import make_stiff
from franka_composer.entities.faces import add_coloured_faces
from franka_composer.entities.features import ArrayFeature

#: The least mass (kg) a body compiles with: Composer's arena bounds lighter ones up to it
#: (`boundmass` in dm_control/composer/arena.xml), so an object option or a randomised mass
#: below it would not be the mass asked for.
MIN_MASS = 1e-5


class Prop(primitive.Primitive):
    """A single-geom free prop; `resting_height` is its centre's height on a surface, `rgba`
    its colour."""

    resting_height: float
    rgba: tuple[float, ...]

    def _build_observables(self) -> "PropObservables":
        return PropObservables(self)


class Block(Prop):
    """A cube, built by `tasks.records.BlockSpec.make`: the spec holds its defaults."""

    def _build(self, *, half_size: float, mass: float, friction: float, name: str, rgba,
               coloured_faces: bool) -> None:
        """`coloured_faces`: six distinctly coloured faces (`faces.py`), so the cube's
        orientation shows in images."""
        # condim 4 adds torsional friction, so a pushed block turns about z like a real one
        # rather than spinning freely on its contact patch, and a held block cannot pivot
        # between the finger pads.
        super()._build(geom_type="box", size=(half_size,) * 3, name=name, mass=mass,
                       friction=(friction, 0.005, 0.0001), condim=4, rgba=rgba)
        make_stiff(self.geom)
        if coloured_faces:
            add_coloured_faces(self.mjcf_model.worldbody, half_size)
        self.resting_height, self.rgba = half_size, tuple(rgba)


class Puck(Prop):
    """A cylinder that slides on a low-friction surface, built by
    `tasks.records.PuckSpec.make`: the spec holds its defaults, bar the colour, the puck's
    own."""

    def _build(self, *, radius: float, half_height: float, mass: float, friction: float,
               name: str, rgba=(0.9, 0.45, 0.1, 1.0)) -> None:
        # condim 3 (no torsional or rolling friction): the puck glides and spins freely,
        # like an air-hockey puck; its sliding friction alone sets how far it goes.
        super()._build(geom_type="cylinder", size=(radius, half_height), name=name, mass=mass,
                       friction=(friction, 0.0, 0.0), condim=3, rgba=rgba)
        make_stiff(self.geom)
        self.resting_height, self.rgba = half_height, tuple(rgba)


class PropObservables(primitive.PrimitiveObservables):
    """The free-prop observables (world frame, per second), read through views of MjData
    (`features.ArrayFeature`), plus the orientation as Euler angles."""

    @define.observable
    def position(self):
        return ArrayFeature("sensordata", self._entity.position)

    @define.observable
    def orientation(self):
        return ArrayFeature("sensordata", self._entity.orientation)

    @define.observable
    def linear_velocity(self):
        return ArrayFeature("sensordata", self._entity.linear_velocity)

    @define.observable
    def angular_velocity(self):
        return ArrayFeature("sensordata", self._entity.angular_velocity)

    @define.observable
    def orientation_euler(self):
        """Roll, pitch, yaw (rad): x-y-z extrinsic angles of the prop's orientation."""
        return ArrayFeature("sensordata", self._entity.orientation, quat_to_euler)


def quat_to_euler(quat: np.ndarray) -> np.ndarray:
    """(w, x, y, z) unit quaternion to (roll, pitch, yaw) in radians, x-y-z extrinsic:
    yaw is the heading on the floor whatever the tilt. Not Gymnasium-Robotics'
    `rotations.quat2euler` (x-y-z intrinsic, the reference code's): the two agree for a turn
    about one axis (docs/guide/physics.md).

    Scalar `math` on Python floats: 5x faster than NumPy on one quaternion, same libm
    functions and IEEE arithmetic, so the same bits (checked on 200k random quaternions)."""
    w, x, y, z = np.asarray(quat, dtype=np.float64).tolist()
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(max(2.0 * (w * y - z * x), -1.0), 1.0))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.array([roll, pitch, yaw])
