"""Scripted expert policies, one per task, acting on the public observation dict (in the
pixel modes, on the state the task reads, never on the images).

They prove the tasks are solvable through the action interface and generate
demonstrations: `rollout(env, make_expert(env), episodes=100).save("push.npz")`.
"""

from __future__ import annotations

from collections.abc import Mapping

from franka_composer.policies.base import Expert
from franka_composer.policies.flip import FlipExpert
from franka_composer.policies.observations import GOAL_KEY, ExpertInput
from franka_composer.policies.pick_and_place import PickAndPlaceExpert
from franka_composer.policies.push import PushExpert
from franka_composer.policies.reach import ReachExpert
from franka_composer.policies.rollout import Trajectories, rollout
from franka_composer.policies.slide import SlideExpert
from franka_composer.policies.stack import StackExpert
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.validation import check_choice

#: The expert class for each task name in `franka_composer.ALL_TASKS`.
EXPERTS: dict[str, type[Expert]] = {
    "push": PushExpert,
    "slide": SlideExpert,
    "pick_and_place": PickAndPlaceExpert,
    "reach": ReachExpert,
    "stack": StackExpert,
    "flip": FlipExpert,
}


def make_expert(env) -> Expert:
    """A fresh scripted expert for `env`: a Gymnasium env of this package (wrapped or not),
    a dm_env from `franka_composer.load`, or Shimmy's wrapper of one. `expert(obs)` takes
    the observation that env returns, in every observation mode: in the pixel modes the
    expert reads the state through the env's task, never from the images (the true state:
    sensing noise and delay do not reach it). It reads the env's
    observation layout and task configuration; a task without an expert is a ValueError
    naming those with one, and so is an env under joint control (the experts act on dx,
    dy, dz: mocap and osc)."""
    if isinstance(env, str):
        raise TypeError("make_expert takes the environment, whose layout and options the "
                        f"expert reads, not a task name: make_expert(gym.make(...)), got {env!r}")
    unwrapped = getattr(env, "unwrapped", env)
    task = getattr(unwrapped, "task", None)
    if task is None or getattr(task, "config", None) is None:
        raise ValueError("make_expert takes an environment of franka_composer (gym.make of "
                         "one of its ids, franka_composer.load, or Shimmy's wrapper of that), "
                         f"whose task it reads, got {env!r}")
    expert = EXPERTS[check_choice("task", task.config.name, tuple(EXPERTS))]
    check_expert_control(task.config.control)
    _check_expert_gripper(task.config)
    _check_goal_observations(getattr(env, "observation_space", None), task.desired_goal_key)
    composer_env = getattr(unwrapped, "composer_env", unwrapped)
    expert_input = ExpertInput(task.observation_layout, task.desired_goal_key,
                               read_state=lambda: task.state_vector(composer_env.physics))
    return expert(task.observation_layout, task.config, expert_input)


def _check_goal_observations(space, composer_goal_key: str) -> None:
    """A ValueError where a Gymnasium env's observations (`space`; None for a dm_env) are
    not dicts holding the desired goal, which the expert plans towards: a wrapper such as
    FlattenObservation or FilterObservation has changed them."""
    if space is None:
        return
    keys = getattr(space, "spaces", None)
    if not isinstance(keys, Mapping) or not ({GOAL_KEY, composer_goal_key} & set(keys)):
        raise ValueError(
            f"an expert plans towards the desired goal, and this env's observations hold "
            f"none (observation space {space}; a wrapper such as FlattenObservation or "
            f"FilterObservation changed them): make the expert for the env inside that "
            f"wrapper and give it that env's observations")


def _check_expert_gripper(config) -> None:
    """A ValueError where the gripper is not as the task defines it: each expert acts with
    the task's own (its actions' length and last component follow from it)."""
    own = TASK_CONFIGS[config.name].control.actuated_gripper
    if config.control.actuated_gripper != own:
        raise ValueError(f"the {config.name} expert acts with the gripper "
                         f"{'actuated' if own else 'locked'}, as the task defines it, and this "
                         f"env has actuated_gripper={config.control.actuated_gripper}")


def check_expert_control(control) -> None:
    """A ValueError unless the experts can act through `control` (`ControlSettings`)."""
    if not control.moves_the_tcp:
        raise ValueError(f"the scripted experts act on dx, dy, dz, which the {control.kind} "
                         "controller does not take: use control='mocap' or 'osc'")


__all__ = ["EXPERTS", "Expert", "Trajectories", "check_expert_control", "make_expert",
           "rollout"]
