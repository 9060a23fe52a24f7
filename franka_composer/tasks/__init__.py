"""The task registry: one name, one `TaskConfig`; everything else iterates over it."""

from __future__ import annotations

from franka_composer.tasks.base import GoalTask, ObservationField
from franka_composer.tasks.builder import build_task
from franka_composer.tasks.config import PhysicsSettings, TaskConfig
from franka_composer.tasks.pick_and_place import PICK_AND_PLACE
from franka_composer.tasks.push import PUSH
from franka_composer.tasks.slide import SLIDE
from franka_composer.validation import check_choice

#: Every task, by the name `franka_composer.load` takes.
TASK_CONFIGS: dict[str, TaskConfig] = {
    "push": PUSH,
    "slide": SLIDE,
    "pick_and_place": PICK_AND_PLACE,
}

ALL_TASKS: tuple[str, ...] = tuple(TASK_CONFIGS)


def task_config(name: str, **overrides) -> TaskConfig:
    """The named task's configuration with `overrides`; clear errors for unknown names."""
    check_choice("task", name, ALL_TASKS)
    return TASK_CONFIGS[name].replace(**overrides)


__all__ = ["ALL_TASKS", "GoalTask", "ObservationField", "PhysicsSettings", "TASK_CONFIGS",
           "TaskConfig", "build_task", "task_config"]
