"""The batched-substep environment steps exactly as Composer's own substep loop does."""

from __future__ import annotations

import numpy as np
from dm_control import composer

import franka_composer
from franka_composer import seeding, suite
from franka_composer.environment import Environment
from franka_composer.tasks import build_task, task_config


def _composer_reference(name: str, seed: int) -> composer.Environment:
    task = build_task(task_config(name, terminate_on_success=False))
    return composer.Environment(task, random_state=seeding.random_state(seed),
                                time_limit=float("inf"), strip_singleton_obs_buffer_dim=True)


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


def _binding_reads(env) -> dict:
    """Every observation of the task read afresh through dm_control bindings, after a full
    `mj_forward` (what plain `MJCFFeature` observables would return on a clean physics)."""
    physics, task = env.physics, env.task
    physics.forward()
    panda, prop = task.panda, task.prop
    prop_name = prop.mjcf_model.model
    reads = {
        "panda/tcp_pos": physics.bind(panda.tcp_site).xpos,
        "panda/tcp_velp": physics.bind(panda.tcp_velocity).sensordata,
        "panda/finger_width": [np.sum(physics.bind(panda.finger_joints).qpos)],
        f"{prop_name}/position": physics.bind(prop.position).sensordata,
        f"{prop_name}/linear_velocity": physics.bind(prop.linear_velocity).sensordata,
        f"{prop_name}/angular_velocity": physics.bind(prop.angular_velocity).sensordata,
        "goal": task.goal,
    }
    return {key: np.array(value) for key, value in reads.items()}


def test_observables_read_through_views_equal_fresh_binding_reads(task_name):
    env = franka_composer.load(task_name, seed=2, terminate_on_success=False)
    rng = np.random.default_rng(1)
    timestep = env.reset()
    for step in range(25):
        observation = {k: np.array(v) for k, v in timestep.observation.items()}
        reads = _binding_reads(env)
        compared = [key for key in reads if key in observation]
        assert len(compared) == (7 if task_name == "pick_and_place" else 6), compared
        for key in compared:
            np.testing.assert_array_equal(observation[key], reads[key], err_msg=f"{key} @ {step}")
        # Readings are copies: stepping must not change an observation already returned.
        held = timestep.observation[f"{env.task.prop.mjcf_model.model}/position"]
        before = held.copy()
        timestep = env.step(rng.uniform(-1, 1, env.action_spec().shape).astype(np.float32))
        np.testing.assert_array_equal(held, before)


def test_reward_discount_and_success_come_from_one_distance_per_step():
    env = franka_composer.load("push", seed=3, reward_type="dense", terminate_on_success=False)
    timestep = env.reset()
    rng = np.random.default_rng(2)
    for _ in range(10):
        timestep = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        difference = timestep.observation["block/position"] - env.task.goal
        distance = np.sqrt(np.sum(difference * difference))
        assert timestep.reward == -distance
        assert env.task.success == (distance < 0.05)
        assert timestep.discount == 1.0
