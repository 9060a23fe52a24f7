"""Registers the Gymnasium ids, generated from the task and controller registries: one
loop, no list.

`Franka{Task}{Sparse,Dense}-v<version>` for every task under the default (mocap) controller (the
paper's three are the reference implementation's ids, so users of `panda_mujoco_gym` switch
by changing one import), and `Franka{Task}{Osc,Joints}{Sparse,Dense}-v<version>` under the
others, panda-gym's naming. The suffix is the task's version (`TaskConfig.version`) plus the
controller's (`CONTROL_VERSIONS`): -v0, except flip's -v1 (reachable goals) and stack's
-v1 (a carried block part of the hand for the surface guard), and the Joints ids' one more (the surface guard under joints); an older suffix is not registered, so
`gym.make` of it raises Gymnasium's "deprecated, use -v1" error. Each task has its own class,
`Franka{Task}Env`, whose docstring is the task's documentation page (`pages.page`: spaces,
observation table, rewards, episode rules, version history).
"""

from __future__ import annotations

from typing import NamedTuple

import gymnasium as gym

from franka_composer.adapters.goal_env import (ENV_ARGUMENTS, FrankaGoalEnv,
                                              check_not_loads_own)
from franka_composer.adapters.pages import page
from franka_composer.controllers import CONTROL_VERSIONS, CONTROLS, DEFAULT_CONTROL
from franka_composer.tasks import ALL_TASKS, TASK_CONFIGS
from franka_composer.tasks.options import OPTION_NAMES
from franka_composer.tasks.rewards import REWARD_TYPES
from franka_composer.validation import check_choice, check_names, named_parameters


def _camel(task: str) -> str:
    return "".join(part.capitalize() for part in task.split("_"))


def env_id(task: str, reward_type: str, control: str = DEFAULT_CONTROL) -> str:
    """`pick_and_place`, `dense` -> `FrankaPickAndPlaceDense-v0`; with `osc` ->
    `FrankaPickAndPlaceOscDense-v0`, with `joints` -> `FrankaPickAndPlaceJointsDense-v1`.
    The suffix is the task's `TaskConfig.version` (flip's and stack's are 1: flip's goals
    changed, and stack's surface guard) plus the controller's (`CONTROL_VERSIONS`: joints'
    is 1, its surface guard). An unknown task, reward type or controller is a ValueError
    naming the valid ones."""
    check_choice("task", task, ALL_TASKS)
    check_choice("reward_type", reward_type, REWARD_TYPES)
    check_choice("control", control, CONTROLS)
    controller = "" if control == DEFAULT_CONTROL else control.capitalize()
    version = TASK_CONFIGS[task].version + CONTROL_VERSIONS[control]
    return f"Franka{_camel(task)}{controller}{reward_type.capitalize()}-v{version}"


def split_version(id_: str) -> tuple[str, int]:
    """`FrankaPushJointsSparse-v1` -> ("FrankaPushJointsSparse", 1); -1 for no version."""
    name, _, suffix = id_.rpartition("-v")
    return (name, int(suffix)) if name and suffix.isdigit() else (id_, -1)


def other_version(id_: str) -> str | None:
    """The registered id that `id_`, not registered, is another version of (its name with
    another suffix), or None."""
    name = split_version(id_)[0]
    return next((registered for registered in ENV_IDS
                 if split_version(registered)[0] == name), None)


class RegisteredEnv(NamedTuple):
    """What an id fixes."""

    task: str
    reward_type: str
    control: str


#: Every registered id, mapped to what it fixes.
ENV_IDS: dict[str, RegisteredEnv] = {
    env_id(task, reward_type, control): RegisteredEnv(task, reward_type, control)
    for task in ALL_TASKS for control in CONTROLS for reward_type in REWARD_TYPES
}


def _task_class(task: str) -> type:
    """`Franka{Task}Env`: the task's Gymnasium env, documented by its page."""
    ids = tuple(id_ for id_, registered in ENV_IDS.items() if registered.task == task)

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
                    control: str = DEFAULT_CONTROL,
                    **options) -> FrankaGoalEnv:
    """What `gym.make(id, **options)` builds. The id fixes the task and the reward type
    (its spec's kwargs), and the controller where its name gives one (`...Osc...`,
    `...Joints...`); the plain ids take any `control` option. A fixed value passed to
    `gym.make` that differs is an error naming the id to use instead. The episode length is
    `TimeLimit`'s (`gym.make(id, max_episode_steps=N)`, the task's by default), which the
    env cannot see: it is built without a time limit of its own unless `time_limit` is
    given (then the shorter ends an episode). Specs recorded before each id had its own
    entry point (`id_maker`), such as Minari datasets', name this function: keep it."""
    fixed = ENV_IDS[registered_id]
    fixed_names = tuple(name for name in RegisteredEnv._fields
                        if name != "control" or fixed.control != DEFAULT_CONTROL)
    asked = RegisteredEnv(task, reward_type, control)
    if any(getattr(asked, name) != getattr(fixed, name) for name in fixed_names):
        wanted = (env_id(*asked) if asked.task in ALL_TASKS and asked.reward_type in
                  REWARD_TYPES and asked.control in CONTROLS else None)
        controlled = ("" if fixed.control == DEFAULT_CONTROL
                      else f", under {fixed.control} control")
        raise ValueError(
            f"{registered_id} is the {fixed.reward_type} {fixed.task} task{controlled}: its "
            f"{', '.join(fixed_names[:-1])} and {fixed_names[-1]} cannot be changed"
            + (f"; use {wanted!r}" if wanted else ""))
    # gym.make's own arguments (after the id) are listed too: a misspelt max_episode_steps
    # lands here. What `load` takes and the adapter sets is said as such first; what the id
    # fixes is not listed, as no other value is taken.
    check_not_loads_own(options)
    check_names("task option", set(options) - set(ENV_ARGUMENTS),
                set(OPTION_NAMES).difference(fixed_names),
                own=("gym.make", set(ENV_ARGUMENTS).union(named_parameters(gym.make)[1:])
                     .difference(fixed_names)))
    options.setdefault("time_limit", None)
    return TASK_ENV_CLASSES[task](task, reward_type, control=control, **options)


#: What `gym.make` reads off the entry point: its render modes, so that it wraps
#: "rgb_array_list" (and "human" where needed) as for any env class.
make_registered.metadata = FrankaGoalEnv.metadata  # type: ignore[attr-defined]


def id_maker(id_: str):
    """`gym.make(id_)`'s entry point: `make_registered` for that id, which no option can
    change (with the id among the spec's kwargs, `gym.make("FrankaPushSparse-v0",
    registered_id="FrankaStackSparse-v1", task="stack")` made a stack env under push's id
    and time limit)."""
    def make(**options) -> FrankaGoalEnv:
        if "registered_id" in options:
            raise ValueError(f"registered_id is not an option of the Gymnasium env: the id "
                             f"({id_}) is")
        return make_registered(id_, **options)

    make.__name__ = make.__qualname__ = "make_" + id_.replace("-", "_")
    make.metadata = FrankaGoalEnv.metadata  # type: ignore[attr-defined]
    return make


#: Each id's entry point (also attributes of this module, which the specs name).
ID_MAKERS = {id_: id_maker(id_) for id_ in ENV_IDS}
globals().update({maker.__name__: maker for maker in ID_MAKERS.values()})


def register_envs() -> None:
    """Registers every id once (re-importing is harmless)."""
    for id_, registered in ENV_IDS.items():
        if id_ not in gym.registry:
            kwargs = {"task": registered.task, "reward_type": registered.reward_type}
            if registered.control != DEFAULT_CONTROL:
                kwargs["control"] = registered.control
            gym.register(id=id_, entry_point=f"{__name__}:{ID_MAKERS[id_].__name__}",
                         kwargs=kwargs,
                         max_episode_steps=TASK_CONFIGS[registered.task].max_episode_steps)
