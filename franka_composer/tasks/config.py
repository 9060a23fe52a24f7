"""Every number a task is made of, as data: one frozen record per task, overridable by name.

`load("push", distance_threshold=0.03)` is `build_task(PUSH.replace(distance_threshold=0.03))`.
"""

from __future__ import annotations

import dataclasses

from franka_composer.entities.panda import NEUTRAL_ARM_QPOS
from franka_composer.tasks.rewards import REWARD_TYPES
from franka_composer.validation import (check_bool, check_choice, check_names, check_number,
                                        check_vector)

PROP_KINDS = ("block", "puck")
#: How many numbers `object_size` holds per prop kind: a cube's half-size; a cylinder's
#: radius and half-height.
_OBJECT_SIZE_LENGTH = {"block": 1, "puck": 2}
#: MuJoCo's integrators and friction cones, by their MJCF names.
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
CONES = ("pyramidal", "elliptic")


@dataclasses.dataclass(frozen=True)
class PhysicsSettings:
    """MuJoCo options for a task (see each task module for why its values were chosen).
    Every field is checked when the record is made."""

    timestep: float = 0.002
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    impratio: float = 1.0
    noslip_iterations: int = 0
    iterations: int = 50
    ls_iterations: int = 20

    def __post_init__(self) -> None:
        _set(self, "timestep", check_number("physics.timestep", self.timestep, above=0.0))
        check_choice("physics.integrator", self.integrator, INTEGRATORS)
        check_choice("physics.cone", self.cone, CONES)
        _set(self, "impratio", check_number("physics.impratio", self.impratio, above=0.0))
        for name, minimum in (("noslip_iterations", 0), ("iterations", 1),
                              ("ls_iterations", 1)):
            _set(self, name, check_number(f"physics.{name}", getattr(self, name),
                                          minimum=minimum, integer=True))


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """A task's parameters (SI units, world frame, robot base at the origin).

    Attributes:
      prop_kind: "block" (a cube of half-size `object_size[0]`) or "puck" (a cylinder of
        radius `object_size[0]` and half-height `object_size[1]`).
      object_mass: kg. object_friction: sliding friction of the object.
      floor_friction: sliding friction of the floor.
      actuated_gripper: a 4th action component opens and closes the hand; otherwise the
        fingers are locked closed.
      object_centre, object_range: centre and size (m) of the square the object starts in.
      goal_centre, goal_range: the same for the goal's (x, y).
      goal_max_height: highest lift (m) of a goal above the object's resting height.
      goal_in_air_probability: chance a goal is lifted (else it lies on the surface).
      reward_type: "sparse" (0 / -1) or "dense" (-distance).
      distance_threshold: success radius (m).
      terminate_on_success: end the episode when the goal is reached (the paper); False
        gives Fetch semantics, for which HER relabelling is exact.
      control_timestep: seconds per control step (a multiple of the physics timestep).
      max_tcp_step: metres the end effector is commanded per step at full action.
      max_finger_step: metres the finger width changes per step at full gripper action.
      neutral_arm_qpos: arm joint angles (rad) at reset.
      physics: MuJoCo solver options.
    """

    prop_kind: str
    object_size: tuple[float, ...]
    object_mass: float
    object_friction: float
    floor_friction: float
    actuated_gripper: bool
    goal_centre: tuple[float, float]
    physics: PhysicsSettings
    object_centre: tuple[float, float] = (0.6, 0.0)
    object_range: tuple[float, float] = (0.3, 0.3)
    goal_range: tuple[float, float] = (0.3, 0.3)
    goal_max_height: float = 0.0
    goal_in_air_probability: float = 0.0
    reward_type: str = "sparse"
    distance_threshold: float = 0.05
    terminate_on_success: bool = True
    control_timestep: float = 0.05
    max_tcp_step: float = 0.05
    max_finger_step: float = 0.2
    neutral_arm_qpos: tuple[float, ...] = NEUTRAL_ARM_QPOS

    def __post_init__(self) -> None:
        """Checks every option's type, shape and range, naming the option and what it
        accepts; numbers and sequences are stored as floats and tuples."""
        check_choice("prop_kind", self.prop_kind, PROP_KINDS)
        _set(self, "object_size", check_vector(
            "object_size", self.object_size, _OBJECT_SIZE_LENGTH[self.prop_kind], above=0.0))
        for name in ("object_mass", "distance_threshold", "control_timestep", "max_tcp_step",
                     "max_finger_step"):
            _set(self, name, check_number(name, getattr(self, name), above=0.0))
        for name in ("object_friction", "floor_friction", "goal_max_height"):
            _set(self, name, check_number(name, getattr(self, name), minimum=0.0))
        _set(self, "goal_in_air_probability", check_number(
            "goal_in_air_probability", self.goal_in_air_probability, minimum=0.0, maximum=1.0))
        for name in ("object_centre", "goal_centre"):
            _set(self, name, check_vector(name, getattr(self, name), 2))
        for name in ("object_range", "goal_range"):
            _set(self, name, check_vector(name, getattr(self, name), 2, minimum=0.0))
        _set(self, "neutral_arm_qpos", check_vector("neutral_arm_qpos",
                                                    self.neutral_arm_qpos, 7))
        for name in ("actuated_gripper", "terminate_on_success"):
            check_bool(name, getattr(self, name))
        check_choice("reward_type", self.reward_type, REWARD_TYPES)
        if not isinstance(self.physics, PhysicsSettings):
            raise ValueError(f"physics must be a PhysicsSettings record, got {self.physics!r}")
        substeps = self.control_timestep / self.physics.timestep
        if round(substeps) < 1 or abs(substeps - round(substeps)) > 1e-6 * substeps:
            raise ValueError(f"control_timestep must be a whole multiple of the physics "
                             f"timestep ({self.physics.timestep:g} s), got "
                             f"{self.control_timestep!r}")

    def replace(self, **overrides) -> "TaskConfig":
        """A copy with `overrides`; an unknown name is a ValueError listing the valid ones,
        a bad value one naming the option and what it accepts."""
        check_names("task option", overrides, (f.name for f in dataclasses.fields(self)))
        return dataclasses.replace(self, **overrides)


def _set(record, name: str, value) -> None:
    """Stores a checked, normalised value on a frozen record (from `__post_init__`)."""
    object.__setattr__(record, name, value)
