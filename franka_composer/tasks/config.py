"""Every number a task is made of, as data: one frozen record per task, overridable by name.

`load("push", distance_threshold=0.03)` is `build_task(PUSH.replace(distance_threshold=0.03))`.
"""

from __future__ import annotations

import dataclasses

from franka_composer.entities.panda import NEUTRAL_ARM_QPOS
from franka_composer.tasks.base import PhysicsSettings

PROP_KINDS = ("block", "puck")


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

    def replace(self, **overrides) -> "TaskConfig":
        """A copy with `overrides`; an unknown name is a ValueError listing the valid ones."""
        valid = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(overrides) - valid)
        if unknown:
            raise ValueError(
                f"unknown task option(s) {', '.join(map(repr, unknown))}; "
                f"valid options: {', '.join(sorted(valid))}"
            )
        return dataclasses.replace(self, **overrides)
