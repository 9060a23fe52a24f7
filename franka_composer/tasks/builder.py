"""Turns a `TaskConfig` into entities and a `GoalTask` (the one place they are wired)."""

from __future__ import annotations

from franka_composer.arenas import FloorArena
from franka_composer.controllers import ControlSettings
from franka_composer.entities import Block, GoalMarker, Panda, Prop, Puck
from franka_composer.entities.panda import MAX_FINGER_WIDTH
from franka_composer.tasks.base import GoalTask
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.workspaces import Box2D, Workspace


def make_prop(config: TaskConfig) -> Prop:
    """The object the task moves (`TaskConfig` has checked `prop_kind` and `object_size`)."""
    if config.prop_kind == "puck":
        radius, half_height = config.object_size
        return Puck(radius=radius, half_height=half_height, mass=config.object_mass,
                    friction=config.object_friction)
    (half_size,) = config.object_size
    return Block(half_size=half_size, mass=config.object_mass, friction=config.object_friction)


def build_task(config: TaskConfig, *, renderable: bool = True) -> GoalTask:
    """The task `config` describes; `renderable=False` builds the Panda without its visual
    meshes (for envs that never render: ~40 MB less, the same simulation)."""
    workspace = Workspace(
        object_box=Box2D(tuple(config.object_centre), tuple(config.object_range)),
        goal_box=Box2D(tuple(config.goal_centre), tuple(config.goal_range)),
        goal_max_height=config.goal_max_height,
        goal_in_air_probability=config.goal_in_air_probability,
    )
    control = ControlSettings(
        max_tcp_step=config.max_tcp_step,
        max_finger_step=config.max_finger_step,
        actuated_gripper=config.actuated_gripper,
        locked_finger_width=0.0,
    )
    panda = Panda(visual_meshes=renderable)
    panda.check_arm_qpos("neutral_arm_qpos", config.neutral_arm_qpos)
    return GoalTask(
        FloorArena(friction=config.floor_friction),
        panda,
        make_prop(config),
        GoalMarker(),
        workspace=workspace,
        control=control,
        physics=config.physics,
        reward_type=config.reward_type,
        distance_threshold=config.distance_threshold,
        terminate_on_success=config.terminate_on_success,
        control_timestep=config.control_timestep,
        neutral_arm_qpos=config.neutral_arm_qpos,
        # The hand starts open when it can grasp, closed when it is locked.
        initial_finger_width=MAX_FINGER_WIDTH if config.actuated_gripper else 0.0,
    )
