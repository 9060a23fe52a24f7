"""Scripted expert policies, one per task, acting only on the public observation dict.

They prove the tasks are solvable through the action interface and generate
demonstrations: `rollout(env, make_expert("push"), episodes=100).save("push.npz")`.
"""

from __future__ import annotations

from franka_composer.policies.base import Expert
from franka_composer.policies.pick_and_place import PickAndPlaceExpert
from franka_composer.policies.push import PushExpert
from franka_composer.policies.rollout import Trajectories, rollout
from franka_composer.policies.slide import SlideExpert
from franka_composer.validation import check_choice

#: The expert class for each task name in `franka_composer.ALL_TASKS`.
EXPERTS: dict[str, type[Expert]] = {
    "push": PushExpert,
    "slide": SlideExpert,
    "pick_and_place": PickAndPlaceExpert,
}


def make_expert(task: str) -> Expert:
    """A fresh expert for `task`; unknown names are a ValueError listing the valid ones."""
    return EXPERTS[check_choice("task", task, tuple(EXPERTS))]()


__all__ = ["EXPERTS", "Expert", "Trajectories", "make_expert", "rollout"]
