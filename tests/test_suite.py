"""The dm_env interface over every task: spec conformity, reset state, determinism, errors."""

from __future__ import annotations

import os
import re
import unittest

import dm_env
import gymnasium as gym
import numpy as np
import pytest
from dm_env import test_utils

import franka_composer
from franka_composer import fast_path
from conftest import SPEC
from franka_composer.controllers import CONTROLS
from franka_composer.entities.panda import NEUTRAL_ARM_QPOS


def _make_conformance_case(name: str, path: str, control: str) -> type:
    class Conformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
        def setUp(self):
            self._previous = os.environ.get(fast_path.ENV_VARIABLE)
            os.environ[fast_path.ENV_VARIABLE] = "1" if path == "fast" else "0"
            super().setUp()

        def tearDown(self):
            super().tearDown()
            if self._previous is None:
                os.environ.pop(fast_path.ENV_VARIABLE, None)
            else:
                os.environ[fast_path.ENV_VARIABLE] = self._previous

        def make_object_under_test(self):
            return franka_composer.load(name, seed=0, control=control)

        def make_action_sequence(self):
            # Long enough to cross an episode boundary: a success on some seeds, the time
            # limit on the others.
            rng = np.random.default_rng(0)
            spec = self.environment.action_spec()
            for _ in range(SPEC[name]["steps"] + 10):
                yield rng.uniform(-1, 1, spec.shape).astype(spec.dtype)

    Conformance.__name__ = Conformance.__qualname__ = _conformance_name(name, path, control)
    return Conformance


def _conformance_name(name: str, path: str, control: str) -> str:
    return f"TestDmEnvConformance_{name}_{control}_{path}"


# dm_env's own conformance tests: every task under every controller on the fast path, and
# every task on Composer's stock stepping.
for _name in franka_composer.ALL_TASKS:
    for _control in CONTROLS:
        for _path in ("fast", "stock") if _control == "mocap" else ("fast",):
            globals()[_conformance_name(_name, _path, _control)] = _make_conformance_case(
                _name, _path, _control)


def test_all_tasks_are_the_papers_and_panda_gyms():
    assert set(franka_composer.ALL_TASKS) == set(SPEC)


def test_observation_layout_sizes_match_the_spec(task_name):
    env = franka_composer.load(task_name)
    layout = env.task.observation_layout
    assert layout.size == SPEC[task_name]["observation"]
    observation = env.reset().observation
    for field in layout.fields:
        assert observation[field.key].shape == (field.size,)
        assert observation[field.key].dtype == np.float64
    assert observation["goal"].shape == (SPEC[task_name]["goal"],)


def test_reset_puts_arm_at_neutral_and_objects_and_goal_in_their_ranges(task_name):
    env = franka_composer.load(task_name, seed=7)
    task = env.task
    workspace = task.workspace
    for _ in range(5):
        timestep = env.reset()
        arm_qpos = env.physics.bind(task.panda.joints).qpos
        np.testing.assert_allclose(arm_qpos, NEUTRAL_ARM_QPOS, atol=1e-3)
        positions = [timestep.observation[f"{prop.mjcf_model.model}/position"]
                     for prop in task.props]
        for prop, position in zip(task.props, positions):
            assert workspace.object_box.contains(position)
            assert position[2] == pytest.approx(prop.resting_height, abs=1e-6)
            _, quaternion = prop.get_pose(env.physics)
            np.testing.assert_allclose(np.abs(quaternion), [1, 0, 0, 0], atol=1e-9)  # Upright.
        for i, a in enumerate(positions):  # Apart: no object inside another.
            for b in positions[i + 1:]:
                assert np.linalg.norm(a[:2] - b[:2]) > 2 * np.hypot(0.02, 0.02)
        goal = timestep.observation["goal"]
        if task.config.goal == "orientation":
            assert np.linalg.norm(goal) == pytest.approx(1.0, abs=1e-12)
        elif task.config.goal == "stacked":
            half = task.props[0].resting_height
            assert workspace.goal_box.contains(goal[:3]) and goal[2] == pytest.approx(half)
            np.testing.assert_allclose(goal[3:], goal[:3] + [0, 0, 2 * half], atol=1e-12)
        else:
            base = task.prop.resting_height if task.props else 0.0
            assert workspace.goal_box.contains(goal)
            assert base - 1e-9 <= goal[2] <= base + workspace.goal_max_height + 1e-9


def test_reach_goals_fill_the_box_above_the_object_square():
    env = franka_composer.load("reach", seed=3)
    goals = np.array([env.reset().observation["goal"] for _ in range(300)])
    assert goals[:, 2].min() < 0.03 and goals[:, 2].max() > 0.27  # z uniform in [0, 0.3].
    assert 0.12 < goals[:, 2].mean() < 0.18
    assert np.ptp(goals[:, 0]) > 0.25 and np.ptp(goals[:, 1]) > 0.25


def _face_up_and_yaw(quaternion) -> tuple[int, float]:
    """The face (+x, -x, +y, -y, +z, -z: 0-5) a goal turns up, and its yaw about world z
    from the orientation the fewest tips give (a quarter turn about the horizontal axis
    the cube tips over; half a turn about y for -z), written out here from SPEC's words."""
    import mujoco

    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quaternion, dtype=np.float64))
    matrix = matrix.reshape(3, 3)
    axis = int(np.argmax(np.abs(matrix[2])))
    sign = np.sign(matrix[2, axis])
    np.testing.assert_allclose(abs(matrix[2, axis]), 1.0, atol=1e-12)  # A face exactly up.
    normal = np.zeros(3)
    normal[axis] = sign
    if axis == 2 and sign < 0:
        tipped = np.diag([-1.0, 1.0, -1.0])
    else:
        k = np.cross(normal, [0.0, 0.0, 1.0])
        skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        tipped = np.eye(3) + skew + skew @ skew  # A quarter turn about k.
    turn = matrix @ tipped.T  # What is left: a turn about z.
    np.testing.assert_allclose(turn[2], [0.0, 0.0, 1.0], atol=1e-12)
    return 2 * axis + int(sign < 0), float(np.arctan2(turn[1, 0], turn[0, 0]))


def test_flip_goals_are_a_face_up_at_a_yaw_within_the_range():
    """SPEC: a face up, uniform yaw. Every face comes up, the bottom one too, and the yaw
    fills [-0.3, 0.3] rad and stays inside it."""
    env = franka_composer.load("flip", seed=4)
    drawn = [_face_up_and_yaw(env.reset().observation["goal"]) for _ in range(600)]
    faces, yaws = np.array([f for f, _ in drawn]), np.array([y for _, y in drawn])
    np.testing.assert_allclose(np.bincount(faces, minlength=6) / len(faces), 1 / 6, atol=0.05)
    assert np.all(np.abs(yaws) <= 0.3 + 1e-9)
    assert yaws.min() < -0.28 and yaws.max() > 0.28 and abs(yaws.mean()) < 0.03
    narrow = franka_composer.load("flip", seed=4, goal_yaw_range=0.1)
    assert max(abs(_face_up_and_yaw(narrow.reset().observation["goal"])[1])
               for _ in range(100)) <= 0.1 + 1e-9


def test_flip_episodes_start_solved_as_often_as_its_page_says():
    """1/6 x 0.2/0.3: the upright face drawn at a yaw within the success angle; the page
    states it so that a policy's success is read against it."""
    from franka_composer.adapters.registration import TASK_ENV_CLASSES

    page = " ".join(TASK_ENV_CLASSES["flip"].__doc__.split())
    assert "11.1% of episodes start solved" in page
    env = gym.make("FrankaFlipSparse-v1")
    solved = sum(env.reset(seed=seed)[1]["is_success"] for seed in range(900))
    # Binomial(900, 1/9): mean 100, standard deviation 9.4.
    assert 72 <= solved <= 128, solved
    env.close()


def test_flip_goals_come_from_the_seed_alone():
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    first = [franka_composer.load("flip", seed=9).reset().observation["goal"]
             for _ in range(2)]
    np.testing.assert_array_equal(first[0], first[1])
    np.testing.assert_array_equal(np.random.get_state()[1], before)  # Global RNG untouched.


def test_the_uniform_orientation_goal_option_gives_panda_gyms_goals():
    """A uniform orientation's quaternion is uniform on the 3-sphere: each component's
    square averages 1/4 (face-up goals' do not: a face up has w^2 + z^2 = 1/2 or 1)."""
    env = franka_composer.load("flip", seed=4, orientation_goal="uniform")
    goals = np.array([env.reset().observation["goal"] for _ in range(400)])
    np.testing.assert_allclose((goals ** 2).mean(axis=0), 0.25, atol=0.03)
    assert np.mean(np.abs(goals[:, 0] ** 2 + goals[:, 3] ** 2 - 0.5) < 0.01) < 0.1


def test_objects_rest_and_nothing_jerks_on_the_first_zero_action(object_task_name):
    """Measured over every object task, seeds 0-9: the hand moves at most 5e-13 m, an
    object 6e-7 m, at most 7e-6 m/s."""
    env = franka_composer.load(object_task_name, seed=3, terminate_on_success=False)
    first = env.reset()
    after = env.step(np.zeros(env.action_spec().shape, np.float32))
    assert np.linalg.norm(after.observation["panda/tcp_position"]
                          - first.observation["panda/tcp_position"]) < 1e-9
    for prop in env.task.props:
        name = prop.mjcf_model.model
        assert np.linalg.norm(after.observation[f"{name}/position"]
                              - first.observation[f"{name}/position"]) < 1e-5
        assert np.linalg.norm(after.observation[f"{name}/linear_velocity"]) < 1e-4


def test_pick_and_place_goals_are_in_the_air_about_seventy_percent_of_the_time():
    env = franka_composer.load("pick_and_place", seed=11)
    resting = env.task.prop.resting_height
    lifted = np.mean([env.reset().observation["goal"][2] > resting + 1e-9
                      for _ in range(300)])
    assert 0.62 < lifted < 0.78
    env = franka_composer.load("pick_and_place", seed=11, goal_in_air_probability=0.0)
    assert all(env.reset().observation["goal"][2] == resting for _ in range(20))


def test_same_seed_same_episode(task_name, composer_path):
    def rollout(seed):
        env = franka_composer.load(task_name, seed=seed, terminate_on_success=False)
        rng = np.random.default_rng(123)
        timestep = env.reset()
        trace = [np.concatenate([timestep.observation[k] for k in sorted(timestep.observation)])]
        rewards = []
        for _ in range(20):
            timestep = env.step(rng.uniform(-1, 1, env.action_spec().shape).astype(np.float32))
            trace.append(np.concatenate([timestep.observation[k]
                                         for k in sorted(timestep.observation)]))
            rewards.append(timestep.reward)
        return np.array(trace), rewards

    first, second, other = rollout(5), rollout(5), rollout(6)
    np.testing.assert_array_equal(first[0], second[0])
    assert first[1] == second[1]
    assert not np.array_equal(first[0][0], other[0][0])


def test_terminate_on_success_ends_the_episode_with_zero_discount():
    # A goal radius of 1 m makes the start already successful.
    env = franka_composer.load("push", seed=0, distance_threshold=1.0)
    env.reset()
    timestep = env.step(np.zeros(3, np.float32))
    assert timestep.last() and timestep.reward == 0.0 and timestep.discount == 0.0
    env = franka_composer.load("push", seed=0, distance_threshold=1.0, terminate_on_success=False)
    env.reset()
    timestep = env.step(np.zeros(3, np.float32))
    assert timestep.mid() and timestep.discount == 1.0


@pytest.mark.parametrize("control", ["mocap", "osc", "joints"])
def test_the_action_specs_bounds_are_actions_an_agent_can_take(task_name, control):
    """Scalar bounds (dm_env-legal) were no action: env.step(spec.minimum) was refused, and
    np.random.uniform(spec.minimum, spec.maximum) drew one number. dm_control's suites give
    bounds of the action's shape."""
    env = franka_composer.load(task_name, seed=0, control=control, terminate_on_success=False)
    spec = env.action_spec()
    assert spec.minimum.shape == spec.maximum.shape == spec.shape
    assert spec.minimum.dtype == spec.maximum.dtype == np.float32
    env.reset()
    for action in (spec.minimum, spec.maximum, spec.generate_value(),
                   np.random.default_rng(0).uniform(spec.minimum, spec.maximum)):
        assert env.step(action).step_type == dm_env.StepType.MID


def test_rollout_refuses_a_dm_env_saying_what_it_runs():
    """It said the dm_env's episodes end only on success, which they do not."""
    from franka_composer.policies import make_expert, rollout

    env = franka_composer.load("push", seed=0)
    with pytest.raises(ValueError, match=re.escape(
            "rollout runs a Gymnasium env (gym.make(id), or Shimmy's DmControlCompatibilityV0 "
            "around a dm_env)")):
        rollout(env, make_expert(env), 1, seed=0)


def test_rollout_and_make_expert_refuse_what_is_not_theirs_by_name():
    """An AttributeError ("has no attribute 'task'") and a TypeError ("'NoneType' object
    is not callable", after the reset)."""
    import gymnasium as gym

    from franka_composer.policies import make_expert, rollout

    for other in (gym.make("CartPole-v1"), None):
        with pytest.raises(ValueError, match=re.escape(
                "make_expert takes an environment of franka_composer (gym.make of one of its "
                f"ids, franka_composer.load, or Shimmy's wrapper of that), whose task it "
                f"reads, got {other!r}")):
            make_expert(other)
    env = gym.make("FrankaPushSparse-v0")
    with pytest.raises(ValueError, match=re.escape(
            "policy must be a callable from an observation to an action (make_expert(env), "
            "a trained policy), got None")):
        rollout(env, None, 1, seed=0)
    env.close()


def test_time_limit_none_removes_the_time_limit():
    env = franka_composer.load("push", seed=0, terminate_on_success=False,
                               distance_threshold=1e-6, time_limit=None)
    assert env.episode_steps is None and env.time_limit == float("inf")
    env.reset()
    for _ in range(200):
        assert env.step(np.zeros(3, np.float32)).mid()


def test_mjcf_is_compiled_once():
    env = franka_composer.load("push", seed=0)
    env.reset()
    physics = env.physics
    env.reset()
    assert env.physics is physics


def test_unknown_task_name_lists_valid_tasks():
    with pytest.raises(ValueError, match="unknown task 'lift'.*push, slide, pick_and_place"):
        franka_composer.load("lift")


def test_unknown_option_lists_valid_options():
    with pytest.raises(ValueError, match="unknown task option.*'goal_radius'.*distance_threshold"):
        franka_composer.load("push", goal_radius=0.1)


def test_a_misspelt_argument_of_load_is_listed_among_its_own():
    """`seed`, `renderable` and `time_limit` are no task options, but a misspelling of one
    lands among them: the error lists them too, and no name twice."""
    with pytest.raises(ValueError, match=r"unknown task option\(s\) 'seeed'; valid task options: "
                                         r"[^;]*reward_type[^;]*; load's own arguments: name, "
                                         r"renderable, seed, time_limit$"):
        franka_composer.load("push", seeed=1)


def test_bad_option_values_raise_clear_errors():
    with pytest.raises(ValueError, match="unknown reward_type 'shaped'"):
        franka_composer.load("push", reward_type="shaped")
    with pytest.raises(ValueError, match="distance_threshold must be > 0"):
        franka_composer.load("push", distance_threshold=0.0)
    with pytest.raises(ValueError, match=r"goal_in_air_probability must be >= 0 and <= 1, got 1.5"):
        franka_composer.load("pick_and_place", goal_in_air_probability=1.5)


@pytest.mark.parametrize("action, message", [
    (np.zeros(4), r"action must have shape \(3,\) \(dx, dy, dz\), got shape \(4,\)"),
    (np.zeros((1, 3)), r"got shape \(1, 3\)"),
    (np.array([0.0, np.nan, 0.0]), "action must be finite"),
    (np.array([np.inf, 0.0, 0.0]), "action must be finite"),
])
def test_bad_actions_raise_before_reaching_mujoco(action, message):
    env = franka_composer.load("push", seed=0)
    env.reset()
    before = env.physics.data.time
    with pytest.raises(ValueError, match=message):
        env.step(action)
    assert env.physics.data.time == before


def test_physics_divergence_ends_the_episode_with_a_warning_and_reset_recovers(caplog):
    env = franka_composer.load("push", seed=0)
    env.reset()
    env.physics.data.qvel[-6:] = 1e12  # Fling the block: MuJoCo flags a bad acceleration.
    with caplog.at_level("WARNING"):
        timestep = env.step(np.zeros(3, np.float32))
    assert timestep.step_type == dm_env.StepType.LAST and timestep.discount == 0.0
    assert any("QACC" in record.getMessage() or "unstable" in record.getMessage()
               for record in caplog.records)
    timestep = env.reset()
    timestep = env.step(np.zeros(3, np.float32))
    assert timestep.mid()
    assert np.all(np.isfinite(timestep.observation["block/position"]))


def test_a_diverged_step_is_a_truncation_in_gymnasium():
    """Not a termination: with the sparse reward, ending the episode there would make
    breaking the simulation the cheapest way out (no more -1s)."""
    import gymnasium as gym

    for options in ({}, {"terminate_on_success": False}):
        env = gym.make("FrankaPushSparse-v0", **options)
        env.reset(seed=0)
        env.unwrapped.composer_env.physics.data.qvel[-6:] = 1e12
        _, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
        assert (terminated, truncated, info["diverged"], info["is_success"]) == (
            False, True, True, False)
        assert reward == -1.0
        env.reset(seed=0)
        _, _, terminated, truncated, info = env.step(np.zeros(3, np.float32))
        assert "diverged" not in info and not truncated
        env.close()


def test_a_diverged_step_is_not_rewarded_as_reaching_the_goal():
    """Composer would give a diverged step a reward of 0, the sparse reward for success."""
    env = franka_composer.load("push", seed=0)
    env.reset()
    env.physics.data.qvel[-6:] = 1e12
    timestep = env.step(np.zeros(3, np.float32))
    assert timestep.last() and not env.task.success
    assert timestep.reward == -1.0
    assert timestep.reward == env.task.compute_reward(timestep.observation["block/position"],
                                                      timestep.observation["goal"])

