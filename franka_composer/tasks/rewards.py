"""The one reward function: the step reward and HER's relabelling both call it.

Pure NumPy on goal arrays with any leading batch shape, so HER can relabel thousands of
transitions in one call and the step reward equals `compute_reward` bit for bit.
"""

from __future__ import annotations

import numpy as np

REWARD_TYPES = ("sparse", "dense")


def goal_distance(achieved_goal, desired_goal) -> np.ndarray:
    """Euclidean distance (m) over the last axis; shape is the leading batch shape."""
    achieved_goal = np.asarray(achieved_goal, dtype=np.float64)
    desired_goal = np.asarray(desired_goal, dtype=np.float64)
    if achieved_goal.shape[-1:] != (3,) or desired_goal.shape[-1:] != (3,):
        raise ValueError(
            "goals must end in an axis of 3 (x, y, z), got shapes "
            f"{achieved_goal.shape} and {desired_goal.shape}"
        )
    return np.linalg.norm(achieved_goal - desired_goal, axis=-1)


def compute_reward(achieved_goal, desired_goal, reward_type: str,
                   distance_threshold: float) -> np.ndarray:
    """Sparse: 0 within `distance_threshold` of the goal, else -1. Dense: -distance.

    Returns float64 with the leading batch shape of the goals (a 0-d array for one pair).
    """
    distance = goal_distance(achieved_goal, desired_goal)
    if reward_type == "sparse":
        return -(distance >= distance_threshold).astype(np.float64)
    if reward_type == "dense":
        return -distance
    raise ValueError(f"unknown reward_type {reward_type!r}; valid: {', '.join(REWARD_TYPES)}")


def is_success(achieved_goal, desired_goal, distance_threshold: float) -> np.ndarray:
    """Whether the object is within `distance_threshold` (m) of the goal."""
    return goal_distance(achieved_goal, desired_goal) < distance_threshold
