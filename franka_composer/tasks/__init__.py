"""The task registry: one `TaskConfig` per task, named; everything else iterates over it.

Adding a task is a config record here (and its scripted expert in `policies`): the
Gymnasium ids, the test cases and the command line's choices all come from `ALL_TASKS`.
"""

from __future__ import annotations

from franka_composer.tasks.builder import build_task
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.options import OPTIONS
from franka_composer.tasks.records import PhysicsSettings
from franka_composer.tasks.goal_task import GoalTask
from franka_composer.tasks.layout import ObservationField, ObservationLayout
from franka_composer.tasks.flip import FLIP
from franka_composer.tasks.pick_and_place import PICK_AND_PLACE
from franka_composer.tasks.push import PUSH
from franka_composer.tasks.reach import REACH
from franka_composer.tasks.slide import SLIDE
from franka_composer.tasks.stack import STACK
from franka_composer.validation import check_choice

#: Every task, by the name `franka_composer.load` takes.
TASK_CONFIGS: dict[str, TaskConfig] = {
    config.name: config for config in (PUSH, SLIDE, PICK_AND_PLACE, REACH, STACK, FLIP)}

ALL_TASKS: tuple[str, ...] = tuple(TASK_CONFIGS)


def task_config(name: str, **options) -> TaskConfig:
    """The named task's configuration with `options` (names of `OPTIONS`); clear errors for
    unknown names and bad values."""
    check_choice("task", name, ALL_TASKS)
    return TASK_CONFIGS[name].replace(**options)


__all__ = ["ALL_TASKS", "GoalTask", "OPTIONS", "ObservationField", "ObservationLayout",
           "PhysicsSettings", "TASK_CONFIGS", "TaskConfig", "build_task", "task_config"]
