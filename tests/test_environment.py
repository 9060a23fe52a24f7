"""The batched-substep environment steps exactly as Composer's own substep loop does."""

from __future__ import annotations

import numpy as np
from dm_control import composer

import franka_composer
from franka_composer import suite
from franka_composer.environment import Environment
from franka_composer.tasks import build_task, task_config


def _composer_reference(name: str, seed: int) -> composer.Environment:
    task = build_task(task_config(name, terminate_on_success=False))
    return composer.Environment(task, random_state=seed, time_limit=float("inf"),
                                strip_singleton_obs_buffer_dim=True)


def test_batched_substeps_match_composers_loop_bit_for_bit(task_name):
    ours = franka_composer.load(task_name, seed=4, terminate_on_success=False)
    reference = _composer_reference(task_name, seed=4)
    assert isinstance(ours, Environment)
    ours.reset(), reference.reset()
    assert ours._batch_substeps  # The fast path is the one under test.
    rng = np.random.default_rng(0)
    for _ in range(30):
        action = rng.uniform(-1, 1, ours.action_spec().shape).astype(np.float32)
        a, b = ours.step(action), reference.step(action)
        assert a.reward == b.reward
        for key in b.observation:
            np.testing.assert_array_equal(a.observation[key], b.observation[key])
    np.testing.assert_array_equal(ours.physics.data.qpos, reference.physics.data.qpos)
    np.testing.assert_array_equal(ours.physics.data.qvel, reference.physics.data.qvel)


def test_a_substep_hook_falls_back_to_composers_loop():
    env = franka_composer.load("push", seed=0)
    calls = []
    env.add_extra_hook("before_substep", lambda physics, action, random_state: calls.append(1))
    env.reset()
    assert not env._batch_substeps
    env.step(np.zeros(3, np.float32))
    assert len(calls) == round(env.control_timestep() / env.physics.timestep())


def test_load_builds_the_batched_environment_with_no_time_limit():
    env = suite.load("slide", seed=0)
    assert isinstance(env, Environment)
    assert env.control_timestep() == 0.05 and env.physics.timestep() == 0.002
