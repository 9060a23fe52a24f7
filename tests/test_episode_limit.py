"""Episode time limits (environment.py): every task's episodes end with a LAST step after
exactly its episode length, on both stepping paths and at both timings, and the Gymnasium
adapter and Shimmy truncate there."""

from __future__ import annotations

import pickle
import re

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from conftest import SPEC
from franka_composer import environment
from franka_composer.adapters.registration import ENV_IDS, env_id
from franka_composer.controllers import CONTROLS
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.tasks.options import TIMINGS


def _steps_to_last(env, actions) -> tuple[int, object]:
    """Steps from a reset to the LAST step (at most 1000), and that step."""
    timestep = env.reset()
    for steps in range(1, 1001):
        timestep = env.step(actions())
        if timestep.last():
            return steps, timestep
    raise AssertionError("no LAST step in 1000 steps")


def _zeros(env):
    return lambda: np.zeros(env.action_spec().shape, np.float32)


@pytest.mark.parametrize("timing", TIMINGS)
def test_a_time_out_is_a_last_step_with_discount_one_after_exactly_the_episode_length(
        task_name, timing, composer_path):
    # Physics time after 50 steps of 0.05 s is 2.4999999999999463 s: a limit of exactly
    # 2.5 s would make 51 steps.
    env = franka_composer.load(task_name, seed=0, terminate_on_success=False, timing=timing)
    steps = SPEC[task_name]["steps"]
    assert env.episode_steps == steps == TASK_CONFIGS[task_name].max_episode_steps
    assert env.time_limit == steps * TIMINGS[timing]["control_timestep"]
    made, last = _steps_to_last(env, _zeros(env))
    assert made == steps and last.discount == 1.0 and last.reward in (0.0, -1.0)
    assert env.step(_zeros(env)()).first()  # dm_env: the step after LAST starts an episode.


@pytest.mark.parametrize("control", CONTROLS)
def test_an_acme_style_loop_ends_within_the_episode_length_under_random_actions(
        task_name, control):
    env = franka_composer.load(task_name, seed=1, control=control)
    rng = np.random.default_rng(0)
    spec = env.action_spec()
    for _ in range(2):
        made, last = _steps_to_last(env, lambda: rng.uniform(-1, 1, spec.shape).astype(
            spec.dtype))
        assert made <= SPEC[task_name]["steps"]
        # Discount 0 only where the goal was reached; otherwise the time-out, at the limit.
        if env.task.success:
            assert last.discount == 0.0
        else:
            assert last.discount == 1.0 and made == SPEC[task_name]["steps"]


@pytest.mark.parametrize("time_limit, timing, steps", [
    (2.5, "default", 50), (0.12, "default", 3), (0.1, "default", 2), (1e-9, "default", 1),
    (10, "default", 200), (2.5, "reference", 5), (2.6, "reference", 6)])
def test_time_limit_sets_the_episode_length_in_whole_control_steps(time_limit, timing, steps):
    env = franka_composer.load("push", seed=0, terminate_on_success=False, timing=timing,
                               time_limit=time_limit)
    assert env.episode_steps == steps
    made, last = _steps_to_last(env, _zeros(env))
    assert made == steps and last.discount == 1.0


@pytest.mark.parametrize("time_limit", [0, -1.0, float("nan"), "2.5", True, [2.5]])
def test_a_bad_time_limit_is_refused_before_anything_is_built(time_limit, monkeypatch):
    import franka_composer.suite

    monkeypatch.setattr(franka_composer.suite, "build_task",
                        lambda *args, **kwargs: pytest.fail("a task was built"))
    with pytest.raises(ValueError, match=r"time_limit must be a number of seconds > 0, or None "
                                         r"\(or inf, as in Composer\) for no limit, got"):
        franka_composer.load("push", time_limit=time_limit)


def test_control_steps_round_up_to_whole_steps_despite_float_division():
    assert 0.3 / 0.1 < 3 and 2.1 / 0.3 > 7  # The divisions round both ways.
    assert environment.control_steps(0.3, 0.1) == 3
    assert environment.control_steps(2.1, 0.3) == 7
    assert environment.control_steps(2.11, 0.3) == 8
    assert environment.check_time_limit(None) == environment.NO_LIMIT
    assert environment.check_time_limit(float("inf")) == environment.NO_LIMIT
    assert environment.check_time_limit(10**400) == environment.NO_LIMIT  # No float holds it.
    assert environment.control_steps(environment.NO_LIMIT, 0.1) == float("inf")
    assert environment.composer_time_limit(50, 0.05) == pytest.approx(2.475)


def test_the_gymnasium_adapter_truncates_at_the_time_limit_on_its_own():
    env = franka_composer.FrankaGoalEnv("push", terminate_on_success=False)  # No TimeLimit.
    env.reset(seed=0)
    for step in range(1, 51):
        _, _, terminated, truncated, _ = env.step(np.zeros(3, np.float32))
        assert not terminated and truncated == (step == 50)
    with pytest.raises(gym.error.ResetNeeded, match=re.escape(
            "Cannot call env.step() before calling env.reset(): the episode ended at its "
            "last step (terminated or truncated), and reset() begins the next")):
        env.step(np.zeros(3, np.float32))


def test_every_ids_max_episode_steps_is_its_tasks_episode_length(task_name):
    steps = SPEC[task_name]["steps"]
    assert franka_composer.load(task_name).episode_steps == steps
    for id_, registered in ENV_IDS.items():
        if registered.task == task_name:
            assert gym.spec(id_).max_episode_steps == steps
    # Through gym.make the length is TimeLimit's alone, as in Gymnasium-Robotics.
    assert gym.make(env_id(task_name, "sparse")).unwrapped.composer_env.episode_steps is None


def _episode_length(env) -> int:
    env.reset(seed=0)
    for steps in range(1, 1001):
        if any(env.step(np.zeros(env.action_space.shape, np.float32))[2:4]):
            return steps
    raise AssertionError("no end in 1000 steps")


@pytest.mark.parametrize("max_episode_steps, options, steps", [
    (None, {}, 50), (100, {}, 100), (10, {}, 10), (100, {"time_limit": None}, 100),
    # A time limit of the env's own stands beside TimeLimit: the shorter ends the episode.
    (100, {"time_limit": 1.0}, 20), (10, {"time_limit": 5.0}, 10)])
def test_gym_make_sets_the_episode_length_with_max_episode_steps(max_episode_steps, options,
                                                                 steps):
    env = gym.make("FrankaPushSparse-v0", max_episode_steps=max_episode_steps,
                   terminate_on_success=False, **options)
    assert _episode_length(env) == steps
    assert _episode_length(pickle.loads(pickle.dumps(env))) == steps
    vector = gym.make_vec("FrankaPushSparse-v0", 2, vectorization_mode="sync",
                          max_episode_steps=max_episode_steps, terminate_on_success=False,
                          **options)
    vector.reset(seed=0)
    for _ in range(steps - 1):
        assert not np.any(vector.step(np.zeros((2, 3), np.float32))[3])
    assert np.all(vector.step(np.zeros((2, 3), np.float32))[3])


def test_shimmy_sees_the_time_out_as_a_truncation():
    from shimmy import DmControlCompatibilityV0

    env = DmControlCompatibilityV0(franka_composer.load("push", seed=0,
                                                       terminate_on_success=False))
    env.reset()
    ends = [env.step(np.zeros(3, np.float32))[2:4] for _ in range(50)]
    assert ends == [(False, False)] * 49 + [(False, True)]
