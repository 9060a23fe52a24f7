"""Turns a `TaskConfig` into entities and a `GoalTask` (the one place they are wired)."""

from __future__ import annotations

from franka_composer.arenas import FloorArena
from franka_composer.controllers import CONTROLLERS
from franka_composer.entities import Panda
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.goal_task import GoalTask


def build_task(config: TaskConfig, *, renderable: bool | None = True) -> GoalTask:
    """The task `config` describes; `renderable=False` builds the Panda without its visual
    meshes (for envs that never render: ~50 MB less, the same simulation), None only where
    the camera observations draw them."""
    if renderable is None:
        renderable = config.observations.needs_visual_meshes
    elif config.observations.needs_visual_meshes and not renderable:
        raise ValueError("camera_meshes='visual' draws the Panda's visual meshes in the "
                         "camera observations: renderable=False leaves them out")
    panda = Panda(visual_meshes=renderable,
                  arm_actuation=CONTROLLERS[config.control.kind].ARM_ACTUATION)
    return GoalTask(FloorArena(friction=config.floor_friction), panda,
                    [spec.make() for spec in config.objects], config)
