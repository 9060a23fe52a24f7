"""The one reward function: the step reward and HER's relabelling both call it.

Pure NumPy on goal arrays with any leading batch shape, so HER can relabel thousands of
transitions in one call and the step reward equals `compute_reward` bit for bit: a step
computes `goal_distance` once and derives its reward and success from that distance with
the same `reward_from_distance` and `success_from_distance` that `compute_reward` and
`is_success` use.
"""

from __future__ import annotations

import numpy as np

from franka_composer.validation import check_choice

REWARD_TYPES = ("sparse", "dense")


def goal_distance(achieved_goal, desired_goal) -> np.ndarray:
    """Euclidean distance (m) over the last axis; shape is the leading batch shape.

    `sqrt(add.reduce(d * d, axis=-1))` is exactly what `np.linalg.norm(d, axis=-1)` computes
    for real arrays (the same operations in the same order, so the same bits) without its
    dispatch overhead, which is most of the time for one pair.
    """
    achieved_goal = np.asarray(achieved_goal, dtype=np.float64)
    desired_goal = np.asarray(desired_goal, dtype=np.float64)
    if achieved_goal.shape[-1:] != (3,) or desired_goal.shape[-1:] != (3,):
        raise ValueError(
            "goals must end in an axis of 3 (x, y, z), got shapes "
            f"{achieved_goal.shape} and {desired_goal.shape}"
        )
    difference = achieved_goal - desired_goal
    return np.sqrt(np.add.reduce(difference * difference, axis=-1))


def check_reward_type(reward_type: str) -> str:
    """`reward_type` if valid, else a ValueError naming the valid ones."""
    return check_choice("reward_type", reward_type, REWARD_TYPES)


def reward_from_distance(distance, reward_type: str, distance_threshold: float) -> np.ndarray:
    """Sparse: 0.0 where `success_from_distance`, else -1.0 (a NaN distance is not a
    success). Dense: -distance. Float64."""
    if check_reward_type(reward_type) == "sparse":
        return np.where(success_from_distance(distance, distance_threshold), 0.0, -1.0)
    return -np.asarray(distance, dtype=np.float64)


def success_from_distance(distance, distance_threshold: float) -> np.ndarray:
    """Whether the object is within `distance_threshold` (m) of the goal (False for NaN)."""
    return np.asarray(distance) < distance_threshold


def compute_reward(achieved_goal, desired_goal, reward_type: str,
                   distance_threshold: float) -> np.ndarray:
    """Sparse: 0 within `distance_threshold` of the goal, else -1. Dense: -distance.

    Returns float64 with the leading batch shape of the goals (a 0-d array for one pair).
    """
    return reward_from_distance(goal_distance(achieved_goal, desired_goal), reward_type,
                                distance_threshold)


def is_success(achieved_goal, desired_goal, distance_threshold: float) -> np.ndarray:
    """Whether the object is within `distance_threshold` (m) of the goal."""
    return success_from_distance(goal_distance(achieved_goal, desired_goal), distance_threshold)
