"""Registers the Gymnasium ids, generated from the task registry: one loop, no list.

`Franka{Task}{Sparse,Dense}-v0` for every task (the paper's three are the reference
implementation's ids, so users of `panda_mujoco_gym` switch by changing one import). Each
task has its own class, `Franka{Task}Env`, whose docstring is the task's documentation page
(`pages.page`: spaces, observation table, rewards, episode rules, version history).
"""

from __future__ import annotations

import gymnasium as gym

from franka_composer.adapters.goal_env import FrankaGoalEnv
from franka_composer.adapters.pages import page
from franka_composer.tasks import ALL_TASKS, TASK_CONFIGS
from franka_composer.tasks.rewards import REWARD_TYPES

ENTRY_POINT = "franka_composer.adapters.registration:make_registered"


def _camel(task: str) -> str:
    return "".join(part.capitalize() for part in task.split("_"))


def env_id(task: str, reward_type: str, version: int = 0) -> str:
    """`pick_and_place`, `dense` -> `FrankaPickAndPlaceDense-v0`."""
    return f"Franka{_camel(task)}{reward_type.capitalize()}-v{version}"


#: Every registered id, mapped to its (task, reward type).
ENV_IDS: dict[str, tuple[str, str]] = {
    env_id(task, reward_type): (task, reward_type)
    for task in ALL_TASKS for reward_type in REWARD_TYPES
}


def _task_class(task: str) -> type:
    """`Franka{Task}Env`: the task's Gymnasium env, documented by its page."""
    ids = tuple(id_ for id_, (name, _) in ENV_IDS.items() if name == task)

    def __init__(self, task: str = task, reward_type: str = "sparse", *args, **options):
        FrankaGoalEnv.__init__(self, task, reward_type, *args, **options)

    name = f"Franka{_camel(task)}Env"
    return type(name, (FrankaGoalEnv,), {
        "__init__": __init__, "__module__": __name__, "__qualname__": name,
        "__doc__": page(TASK_CONFIGS[task], ids)})


#: Each task's env class, by task name (also attributes of this module, so they pickle).
TASK_ENV_CLASSES: dict[str, type] = {task: _task_class(task) for task in ALL_TASKS}
globals().update({cls.__name__: cls for cls in TASK_ENV_CLASSES.values()})


def make_registered(registered_id: str, task: str, reward_type: str,
                    **options) -> FrankaGoalEnv:
    """What `gym.make(id, **options)` builds. The id fixes the task and the reward type
    (its spec's kwargs); a `task` or `reward_type` passed to `gym.make` that differs is an
    error naming the id to use instead."""
    fixed_task, fixed_reward_type = ENV_IDS[registered_id]
    if (task, reward_type) != (fixed_task, fixed_reward_type):
        wanted = env_id(task, reward_type) if (task, reward_type) in ENV_IDS.values() else None
        raise ValueError(
            f"{registered_id} is the {fixed_reward_type} {fixed_task} task: its task and "
            f"reward_type cannot be changed" + (f"; use {wanted!r}" if wanted else ""))
    return TASK_ENV_CLASSES[task](task, reward_type, **options)


def register_envs() -> None:
    """Registers every id once (re-importing is harmless)."""
    for id_, (task, reward_type) in ENV_IDS.items():
        if id_ not in gym.registry:
            gym.register(id=id_, entry_point=ENTRY_POINT,
                         kwargs={"registered_id": id_, "task": task,
                                 "reward_type": reward_type},
                         max_episode_steps=TASK_CONFIGS[task].max_episode_steps)
