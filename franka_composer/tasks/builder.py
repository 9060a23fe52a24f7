"""Turns a `TaskConfig` into entities and a `GoalTask` (the one place they are wired)."""

from __future__ import annotations

from franka_composer.arenas import FloorArena
from franka_composer.controllers import ControlSettings
from franka_composer.entities import Block, GoalMarker, Panda, Prop, Puck
from franka_composer.entities.panda import MAX_FINGER_WIDTH
from franka_composer.tasks.base import GoalTask
from franka_composer.tasks.config import PROP_KINDS, TaskConfig
from franka_composer.tasks.workspaces import Box2D, Workspace


def make_prop(config: TaskConfig) -> Prop:
    if config.prop_kind == "block":
        return Block(half_size=config.object_size[0], mass=config.object_mass,
                     friction=config.object_friction)
    if config.prop_kind == "puck":
        return Puck(radius=config.object_size[0], half_height=config.object_size[1],
                    mass=config.object_mass, friction=config.object_friction)
    raise ValueError(f"unknown prop_kind {config.prop_kind!r}; valid: {', '.join(PROP_KINDS)}")


def build_task(config: TaskConfig) -> GoalTask:
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
    return GoalTask(
        FloorArena(friction=config.floor_friction),
        Panda(),
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
