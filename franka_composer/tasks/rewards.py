"""The one reward function: the step reward and HER's relabelling both call it.

Pure NumPy on goal arrays with any leading batch shape, so HER can relabel thousands of
transitions in one call and the step reward equals `compute_reward` bit for bit: a step
computes the goal distance once and derives its reward and success from that distance with
the same `reward_from_distance` and `success_from_distance` that `compute_reward` and
`is_success` use.

A task measures its goal with one of `METRICS`: "euclidean" (metres, over the whole goal
vector: one position, or two stacked blocks' six coordinates) or "rotation_angle" (radians
between two orientations given as unit quaternions w, x, y, z, where q and -q are the same).
"""

from __future__ import annotations

import numpy as np

from franka_composer.validation import check_choice

REWARD_TYPES = ("sparse", "dense")
METRICS = ("euclidean", "rotation_angle")


def _goals(achieved_goal, desired_goal, size: int | None, what: str):
    achieved_goal = np.asarray(achieved_goal, dtype=np.float64)
    desired_goal = np.asarray(desired_goal, dtype=np.float64)
    if achieved_goal.shape[-1:] != desired_goal.shape[-1:] or (
            size is not None and achieved_goal.shape[-1:] != (size,)):
        expected = f"an axis of {size} ({what})" if size else "the same last axis"
        raise ValueError(f"goals must end in {expected}, got shapes {achieved_goal.shape} "
                         f"and {desired_goal.shape}")
    if achieved_goal.shape != desired_goal.shape:  # (Pairs of one shape: the step's, HER's.)
        try:
            np.broadcast_shapes(achieved_goal.shape, desired_goal.shape)
        except ValueError:
            raise ValueError(f"achieved and desired goals must come in batches of one shape "
                             f"(or one that broadcasts, such as one goal for many), got shapes "
                             f"{achieved_goal.shape} and {desired_goal.shape}") from None
    return achieved_goal, desired_goal


def euclidean_distance(achieved_goal, desired_goal, size: int | None = 3) -> np.ndarray:
    """Euclidean distance over the last axis (of `size`: 3 for a position); shape is the
    leading batch shape.

    `sqrt(add.reduce(d * d, axis=-1))` is exactly what `np.linalg.norm(d, axis=-1)` computes
    for real arrays (the same operations in the same order, so the same bits) without its
    dispatch overhead, which is most of the time for one pair.
    """
    achieved_goal, desired_goal = _goals(achieved_goal, desired_goal, size,
                                         "x, y, z" if size == 3 else "coordinates")
    difference = achieved_goal - desired_goal
    return np.sqrt(np.add.reduce(difference * difference, axis=-1))


#: How far a quaternion's squared norm may be from 1: a unit quaternion stored in float32
#: is within ~1e-7; one farther off is no orientation the task gives (a goal of something
#: else, passed by mistake), though `_angle` would read it as one.
UNIT_TOLERANCE = 1e-3


def rotation_angle(achieved_goal, desired_goal) -> np.ndarray:
    """The angle (rad, in [0, pi]) of the rotation between two orientations given as unit
    quaternions (w, x, y, z), q and -q the same orientation (`compute_reward` and
    `is_success` refuse others: `_given_distance`)."""
    return _angle(*_goals(achieved_goal, desired_goal, 4, "w, x, y, z"))


def _angle(achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
    """2 atan2(sin, |cos|) of the half angle, not 2 acos |<q1, q2>|: atan2 reads the same
    angle whatever the quaternions' norms (a float32 rounding, a quaternion off unit by
    the tolerance: acos read 0.02 rad as 0.066 there), and equal quaternions give exactly 0.
    With n1, n2 the norms, |<q1, q2>| = n1 n2 cos and n1 n2 sin = sqrt(n1² n2² - <q1, q2>²)
    (the norm of the relative rotation's vector part)."""
    dot = np.add.reduce(achieved_goal * desired_goal, axis=-1)
    norms = (np.add.reduce(achieved_goal * achieved_goal, axis=-1)
             * np.add.reduce(desired_goal * desired_goal, axis=-1))
    return 2.0 * np.arctan2(np.sqrt(np.maximum(norms - dot * dot, 0.0)), np.abs(dot))


def _check_unit(quaternions: np.ndarray, which: str) -> None:
    # (einsum: the squared norms in one pass, half the time of a product and a reduction
    # over an axis of four.)
    squared = np.einsum("...i,...i->...", quaternions, quaternions)
    off = np.abs(squared - 1.0) > UNIT_TOLERANCE
    if off.any():
        index = np.argwhere(off)[0] if off.ndim else ()
        where = f" at index {tuple(int(i) for i in index)}" if off.ndim else ""
        raise ValueError(f"{which} goals must be unit quaternions (w, x, y, z), got "
                         f"{np.array2string(quaternions[tuple(index)], precision=4)}{where} "
                         f"(norm {np.sqrt(squared[tuple(index)]):.4g})")


def distance(achieved_goal, desired_goal, metric: str, size: int) -> np.ndarray:
    """The goal distance by `metric` (one of `METRICS`) for goals of `size` numbers."""
    if metric == "rotation_angle":
        return rotation_angle(achieved_goal, desired_goal)
    if metric != "euclidean":  # Checked only off the hot path: check_choice raises here.
        check_choice("metric", metric, METRICS)
    return euclidean_distance(achieved_goal, desired_goal, size)


def _given_distance(achieved_goal, desired_goal, metric: str, size: int) -> np.ndarray:
    """`distance` of goals a caller gives (HER's, a user's), its quaternions checked unit
    (`_check_unit`; a NaN one gives a NaN angle). A step's own, read from MuJoCo and drawn
    unit, go to `distance` unchecked: the check would cost each flip step twice the
    distance itself."""
    if metric == "rotation_angle":
        achieved_goal, desired_goal = _goals(achieved_goal, desired_goal, 4, "w, x, y, z")
        _check_unit(achieved_goal, "achieved")
        _check_unit(desired_goal, "desired")
        return _angle(achieved_goal, desired_goal)
    return distance(achieved_goal, desired_goal, metric, size)


def check_reward_type(reward_type: str) -> str:
    """`reward_type` if valid, else a ValueError naming the valid ones."""
    return check_choice("reward_type", reward_type, REWARD_TYPES)


def reward_from_distance(distance, reward_type: str, distance_threshold: float) -> np.ndarray:
    """Sparse: 0.0 where `success_from_distance`, else -1.0 (a NaN distance is not a
    success). Dense: -distance. Float64."""
    if check_reward_type(reward_type) == "sparse":
        return np.where(success_from_distance(distance, distance_threshold), 0.0, -1.0)
    return np.asarray(-np.asarray(distance, dtype=np.float64))  # 0-d for one pair, as sparse.


def success_from_distance(distance, distance_threshold: float) -> np.ndarray:
    """Whether the goal is reached: the distance is below `distance_threshold` (not NaN)."""
    return np.asarray(distance) < distance_threshold


def compute_reward(achieved_goal, desired_goal, reward_type: str, distance_threshold: float,
                   metric: str = "euclidean", size: int = 3) -> np.ndarray:
    """Sparse: 0 within `distance_threshold` of the goal, else -1. Dense: -distance.

    Returns float64 with the leading batch shape of the goals (a 0-d ndarray for one pair,
    not a Python float).
    """
    return reward_from_distance(_given_distance(achieved_goal, desired_goal, metric, size),
                                reward_type, distance_threshold)


def is_success(achieved_goal, desired_goal, distance_threshold: float,
               metric: str = "euclidean", size: int = 3) -> np.ndarray:
    """Whether each goal pair is within `distance_threshold` by `metric`."""
    return success_from_distance(_given_distance(achieved_goal, desired_goal, metric, size),
                                 distance_threshold)
