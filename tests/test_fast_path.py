"""The fast path steps exactly as Composer's stock stepping does, falls back to it when the
installed dm_control lacks a private name, and can be switched off."""

from __future__ import annotations

import numpy as np
import pytest

import franka_composer
from franka_composer import fast_path
from franka_composer.environment import GoalEnvironment
from franka_composer.fast_path import FastEnvironment
from franka_composer.policies import make_expert

from conftest import batches_substeps


def _load(path: str, monkeypatch, name: str, **options):
    monkeypatch.setenv(fast_path.ENV_VARIABLE, "1" if path == "fast" else "0")
    return franka_composer.load(name, **options)


def _rollout(env, task: str, episodes: int = 3, steps: int = 40) -> list:
    """Every timestep of expert and random episodes (random only under joint control, which
    has no expert), resets included, as plain data."""
    records = []
    layout = env.task.observation_layout
    expert = make_expert(env) if env.task.config.control.moves_the_tcp else None
    rng = np.random.default_rng(0)
    for episode in range(episodes):
        timestep = env.reset()
        if expert:
            expert.reset()
        for _ in range(steps):
            records.append((timestep.step_type, timestep.reward, timestep.discount,
                            {k: np.array(v) for k, v in timestep.observation.items()}))
            if timestep.last():
                break
            observation = {"observation": layout.flatten(timestep.observation),
                           "desired_goal": timestep.observation["goal"]}
            action = (expert(observation) if expert and episode % 2 == 0 else
                      rng.uniform(-1, 1, env.action_spec().shape).astype(np.float32))
            timestep = env.step(action)
    return records


def test_load_takes_the_fast_path_unless_it_is_switched_off(monkeypatch):
    assert type(_load("fast", monkeypatch, "push")) is FastEnvironment
    stock = _load("stock", monkeypatch, "push")
    assert type(stock) is GoalEnvironment  # Composer's own stepping.
    assert stock.control_timestep() == 0.05 and stock.physics.timestep() == 0.002


@pytest.mark.parametrize("control", ["mocap", "osc", "joints"])
def test_fast_and_stock_paths_give_the_same_episodes_bit_for_bit(task_name, control,
                                                                monkeypatch):
    """Under osc the fast path runs the torque law itself between physics steps."""
    fast_env = _load("fast", monkeypatch, task_name, seed=4, control=control)
    fast = _rollout(fast_env, task_name)
    assert batches_substeps(fast_env)
    stock = _rollout(_load("stock", monkeypatch, task_name, seed=4, control=control),
                     task_name)
    assert len(fast) == len(stock)
    for a, b in zip(fast, stock):
        assert a[:3] == b[:3]
        assert a[3].keys() == b[3].keys()
        for key in a[3]:
            np.testing.assert_array_equal(a[3][key], b[3][key], err_msg=key)
            assert a[3][key].dtype == b[3][key].dtype


def test_a_missing_private_name_falls_back_to_stock_stepping_with_one_warning(monkeypatch,
                                                                             caplog):
    """As if a dm_control release had renamed a private function the fast path calls."""
    assert fast_path.probe() == []  # The installed dm_control has everything.
    monkeypatch.setattr(fast_path, "_MODULE_FUNCTIONS",
                        fast_path._MODULE_FUNCTIONS + ("_renamed_in_a_future_release",))
    monkeypatch.setattr(fast_path, "_warned", False)
    assert fast_path.probe() == [
        "dm_control.composer.environment._renamed_in_a_future_release"]
    with caplog.at_level("WARNING"):
        envs = [_load("fast", monkeypatch, "push", seed=0) for _ in range(2)]
    assert all(type(env) is GoalEnvironment for env in envs)
    warnings = [r.getMessage() for r in caplog.records if "stock stepping" in r.getMessage()]
    assert len(warnings) == 1 and "_renamed_in_a_future_release" in warnings[0]
    timestep = envs[0].reset()
    assert envs[0].step(np.zeros(3, np.float32)).mid() and timestep.first()


def test_a_missing_instance_attribute_falls_back_too(monkeypatch, caplog):
    monkeypatch.setattr(fast_path, "_ENVIRONMENT_ATTRIBUTES",
                        fast_path._ENVIRONMENT_ATTRIBUTES + ("_renamed_in_a_future_release",))
    monkeypatch.setattr(fast_path, "_warned", False)
    with caplog.at_level("WARNING"):
        env = _load("fast", monkeypatch, "push", seed=0)
    assert type(env) is GoalEnvironment
    assert any("_renamed_in_a_future_release" in r.getMessage() for r in caplog.records)


def test_a_substep_hook_falls_back_to_composers_loop(monkeypatch):
    env = _load("fast", monkeypatch, "push", seed=0)
    calls = []
    env.add_extra_hook("before_substep", lambda physics, action, random_state: calls.append(1))
    env.reset()
    assert not env._batch_substeps
    env.step(np.zeros(3, np.float32))
    assert len(calls) == round(env.control_timestep() / env.physics.timestep())


@pytest.mark.parametrize("path", ["fast", "stock"])
def test_a_diverged_step_ends_the_episode_with_the_tasks_reward(path, monkeypatch, caplog):
    """Composer would give a diverged step a reward of 0, the sparse reward for success."""
    env = _load(path, monkeypatch, "push", seed=0)
    env.reset()
    env.physics.data.qvel[-6:] = 1e12  # Fling the block: MuJoCo flags a bad acceleration.
    with caplog.at_level("WARNING"):
        timestep = env.step(np.zeros(3, np.float32))
    assert timestep.last() and timestep.discount == 0.0
    assert any("Warning(s) raised" in r.getMessage() for r in caplog.records)
    assert not env.task.success and timestep.reward == -1.0
    assert timestep.reward == env.task.compute_reward(timestep.observation["block/position"],
                                                      timestep.observation["goal"])
    timestep = env.reset()
    timestep = env.step(np.zeros(3, np.float32))
    assert timestep.mid() and np.all(np.isfinite(timestep.observation["block/position"]))


@pytest.mark.parametrize("path", ["fast", "stock"])
def test_suppressed_physics_errors_do_not_end_the_episode(path, monkeypatch):
    env = _load(path, monkeypatch, "push", seed=0)
    env.reset()
    env.physics.data.qvel[-6:] = 1e12
    with env.physics.suppress_physics_errors():
        timestep = env.step(np.zeros(3, np.float32))
    assert timestep.mid() and timestep.discount == 1.0


def test_the_mjcf_is_compiled_once(monkeypatch):
    env = _load("fast", monkeypatch, "push", seed=0)
    physics = env.physics
    env.reset()
    env.reset()
    assert env.physics is physics


def test_an_observable_enabled_between_episodes_appears_after_the_next_reset(monkeypatch):
    env = _load("fast", monkeypatch, "push", seed=0)
    env.reset()
    env.step(np.zeros(3, np.float32))
    env.task.panda.observables.joints_pos.enabled = True
    assert "panda/joints_pos" in env.reset().observation
    assert env.step(np.zeros(3, np.float32)).observation["panda/joints_pos"].shape == (7,)


def _tcp_readings(path: str, monkeypatch, configure) -> list:
    """The first episode's goal and its hand positions over three full pushes in x, on a
    push env `configure` changed before its first reset."""
    env = _load(path, monkeypatch, "push", seed=0)
    configure(env.task)
    timestep = env.reset()
    readings = [timestep.observation["goal"], timestep.observation["panda/tcp_position"]]
    for _ in range(3):
        timestep = env.step(np.array([1.0, 0.0, 0.0], np.float32))
        readings.append(timestep.observation["panda/tcp_position"])
    return readings


def test_an_observable_buffering_substeps_reads_the_last_substeps_as_composer_does(
        monkeypatch):
    """A buffer of 2 takes the last two substeps' readings. The fast path batched such an
    observable as if only the last substep were due, and it never updated again: each step
    gave the reading taken at the reset."""
    def buffer_two(task):
        task.panda.observables.tcp_position.buffer_size = 2

    fast = _tcp_readings("fast", monkeypatch, buffer_two)
    stock = _tcp_readings("stock", monkeypatch, buffer_two)
    for a, b in zip(fast, stock, strict=True):
        np.testing.assert_array_equal(a, b)
    hand_x = [reading[:, 0] for reading in fast[2:]]
    assert all(reading.shape == (2, 3) for reading in fast[1:])
    for before, after in zip(hand_x, hand_x[1:]):
        assert after[0] - before[1] > 0.04  # A full x action moves the hand ~47 mm a step.
    assert all(0 < x[1] - x[0] < 0.002 for x in hand_x)  # One substep (2 ms) apart.


def test_a_corruptor_drawing_from_the_random_state_gives_the_stock_paths_episode(
        monkeypatch):
    """Composer's first reset reads every observable once before it initialises the
    episode, and a corruptor draws from the environment's random state there: the fast
    path, which skipped that reset's compilation and what came with it, drew another first
    episode from the same seed."""
    def noisy(task):
        task.prop.observables.position.corruptor = (
            lambda value, random_state: value + random_state.normal(0, 1e-3, value.shape))

    fast = _tcp_readings("fast", monkeypatch, noisy)
    stock = _tcp_readings("stock", monkeypatch, noisy)
    for a, b in zip(fast, stock, strict=True):
        np.testing.assert_array_equal(a, b)
    unnoised = _tcp_readings("stock", monkeypatch, lambda task: None)
    assert not np.array_equal(stock[0], unnoised[0])  # The corruptor's draws moved the goal.
