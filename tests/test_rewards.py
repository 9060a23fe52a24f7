"""The reward contract: sparse/dense values, success radius, batch shapes, clear errors."""

import re

import numpy as np
import pytest

from franka_composer.tasks import rewards


def test_sparse_reward_is_zero_inside_threshold_and_minus_one_outside():
    goal = np.zeros(3)
    assert rewards.compute_reward([0.049, 0, 0], goal, "sparse", 0.05) == 0.0
    assert rewards.compute_reward([0.05, 0, 0], goal, "sparse", 0.05) == -1.0
    assert rewards.compute_reward([0, 0.3, 0.4], goal, "sparse", 0.05) == -1.0


def test_dense_reward_is_minus_distance():
    assert rewards.compute_reward([0, 0.3, 0.4], np.zeros(3), "dense", 0.05) == pytest.approx(-0.5)


@pytest.mark.parametrize("reward_type", ["sparse", "dense"])
def test_one_goal_pair_gives_a_0d_float64_array_for_either_reward_type(reward_type):
    """One type for one pair, whichever the reward: code that indexes or writes into the
    result (`reward[...] = ...`) works for both."""
    reward = rewards.compute_reward([0, 0.3, 0.4], np.zeros(3), reward_type, 0.05)
    assert type(reward) is np.ndarray and reward.shape == () and reward.dtype == np.float64


def test_batched_reward_matches_per_pair_values_for_any_leading_shape():
    rng = np.random.default_rng(0)
    achieved, desired = rng.uniform(-0.1, 0.1, (2, 5, 4, 3))
    for reward_type in rewards.REWARD_TYPES:
        batched = rewards.compute_reward(achieved, desired, reward_type, 0.05)
        assert batched.shape == (5, 4)
        assert batched.dtype == np.float64
        singles = [[rewards.compute_reward(a, d, reward_type, 0.05) for a, d in zip(ra, rd)]
                   for ra, rd in zip(achieved, desired)]
        np.testing.assert_array_equal(batched, np.array(singles))


def test_success_is_distance_below_threshold():
    assert rewards.is_success([0.0299, 0, 0], np.zeros(3), 0.03)
    assert not rewards.is_success([0.03, 0, 0], np.zeros(3), 0.03)


def test_an_unknown_metric_is_refused_naming_the_metrics():
    with pytest.raises(ValueError, match="unknown metric 'manhattan'; valid metrics: "
                                         "euclidean, rotation_angle"):
        rewards.compute_reward(np.zeros(3), np.ones(3), "sparse", 0.05, metric="manhattan")


def test_unknown_reward_type_and_bad_goal_shape_raise_clear_errors():
    with pytest.raises(ValueError, match="unknown reward_type 'shaped'.*sparse, dense"):
        rewards.compute_reward(np.zeros(3), np.zeros(3), "shaped", 0.05)
    with pytest.raises(ValueError, match=r"goals must end in an axis of 3"):
        rewards.compute_reward(np.zeros(2), np.zeros(2), "sparse", 0.05)


@pytest.mark.parametrize("metric, size", [("euclidean", 3), ("rotation_angle", 4)])
def test_goal_batches_that_do_not_pair_up_are_refused_and_one_goal_for_many_is_taken(metric,
                                                                                     size):
    """numpy's "operands could not be broadcast together with shapes (3,3) (2,3)"."""
    with pytest.raises(ValueError, match=re.escape(
            "achieved and desired goals must come in batches of one shape (or one that "
            f"broadcasts, such as one goal for many), got shapes (3, {size}) and (2, {size})")):
        rewards.compute_reward(np.zeros((3, size)), np.ones((2, size)), "dense", 0.05,
                               metric=metric, size=size)
    goal = np.ones(size) / np.sqrt(size)  # (A unit quaternion for rotation_angle.)
    one_for_many = rewards.compute_reward(np.tile(goal, (3, 1)), goal, "sparse", 0.05,
                                          metric=metric, size=size)
    np.testing.assert_array_equal(one_for_many, [0.0, 0.0, 0.0])


def test_a_nan_goal_is_not_a_success_and_gets_the_failure_reward():
    goal = np.array([np.nan, 0.0, 0.0])
    assert rewards.compute_reward(np.zeros(3), goal, "sparse", 0.05) == -1.0
    assert not rewards.is_success(np.zeros(3), goal, 0.05)
    assert np.isnan(rewards.compute_reward(np.zeros(3), goal, "dense", 0.05))
    batch = rewards.compute_reward(np.zeros((3, 3)), [[0, 0, 0], [np.nan] * 3, [1, 0, 0]],
                                   "sparse", 0.05)
    np.testing.assert_array_equal(batch, [0.0, -1.0, -1.0])


def test_the_sparse_success_reward_is_positive_zero():
    reward = rewards.compute_reward(np.zeros(3), np.zeros(3), "sparse", 0.05)
    assert reward == 0.0 and not np.signbit(reward)


def test_quaternions_that_are_not_unit_are_refused_naming_which_and_where():
    """A quaternion far from unit is no orientation the task gives (a goal of something
    else, passed by mistake): refused, naming which and where. float32's rounding of a unit
    quaternion is taken."""
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=re.escape(
            "desired goals must be unit quaternions (w, x, y, z), got [0.5 0.  0.  0. ] at "
            "index (1,) (norm 0.5)")):
        rewards.compute_reward(identity, [identity, [0.5, 0, 0, 0]], "sparse", 0.1,
                               metric="rotation_angle", size=4)
    with pytest.raises(ValueError, match=re.escape(
            "achieved goals must be unit quaternions (w, x, y, z), got [2. 0. 0. 0.] "
            "(norm 2)")):
        rewards.is_success([2.0, 0, 0, 0], identity, 0.1, metric="rotation_angle", size=4)
    rng = np.random.default_rng(0)
    quaternions = rng.normal(size=(1000, 4))
    quaternions = (quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True))
    rewards_ = rewards.compute_reward(quaternions.astype(np.float32), identity, "dense", 0.1,
                                      metric="rotation_angle", size=4)
    np.testing.assert_allclose(-rewards_, 2 * np.arccos(np.abs(quaternions[:, 0])), atol=1e-6)


def _about_an_axis(angles, axis):
    axis = np.asarray(axis) / np.linalg.norm(axis)
    return np.concatenate([np.cos(angles / 2)[:, None], np.sin(angles / 2)[:, None] * axis], 1)


def test_the_rotation_angle_is_exact_for_equal_quaternions_and_known_rotations():
    """Equal orientations are exactly 0 apart (2 acos |<q1, q2>| read float32 copies of one
    quaternion up to 8e-4 rad apart, float64 ones up to 6e-8); a rotation by t about any
    axis reads t, and by 2 pi - t (the same orientation the other way round) as well; q and
    -q are equal."""
    rng = np.random.default_rng(0)
    quaternions = rng.normal(size=(1000, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    for stored in (quaternions, quaternions.astype(np.float32)):
        np.testing.assert_array_equal(rewards.rotation_angle(stored, stored), 0.0)
        np.testing.assert_array_equal(rewards.rotation_angle(stored, -stored), 0.0)
    angles = np.linspace(0.0, 2 * np.pi, 2001)
    rotated = _about_an_axis(angles, [0.3, -0.5, 0.8])
    np.testing.assert_allclose(rewards.rotation_angle(rotated, [1.0, 0.0, 0.0, 0.0]),
                               np.minimum(angles, 2 * np.pi - angles), rtol=0, atol=1e-10)


def test_a_quaternion_off_unit_within_the_tolerance_reads_its_orientation_s_angle():
    """A quaternion whose squared norm is 1e-3 off unit (taken: `UNIT_TOLERANCE`) reads the
    angle of the orientation it points to: 2 acos |<q1, q2>| read 0.02 rad as 0.066 or 0
    there, and 0.3 rad as 0.307 or 0.293."""
    angles = np.array([0.02, 0.3, 1.0, 3.0])
    rotated = _about_an_axis(angles, [1.0, 2.0, 2.0])
    for scale in (np.sqrt(1 - 0.999e-3), np.sqrt(1 + 0.999e-3)):
        np.testing.assert_allclose(
            rewards.compute_reward(rotated * scale, [1.0, 0.0, 0.0, 0.0], "dense", 0.2,
                                   metric="rotation_angle", size=4), -angles, rtol=1e-12)
