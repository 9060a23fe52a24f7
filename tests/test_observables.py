"""Observables and the step's reward: what the task reads from MuJoCo each step."""

from __future__ import annotations

import numpy as np

import franka_composer


def _binding_reads(env) -> dict:
    """Every observation of the task read afresh through dm_control bindings, after a full
    `mj_forward` (what plain `MJCFFeature` observables would return on a clean physics)."""
    physics, task = env.physics, env.task
    physics.forward()
    panda = task.panda
    reads = {
        "panda/tcp_position": physics.bind(panda.tcp_site).xpos,
        "panda/tcp_linear_velocity": physics.bind(panda.tcp_velocity).sensordata,
        "panda/finger_width": [np.sum(physics.bind(panda.finger_joints).qpos)],
        "goal": task.goal,
    }
    for prop in task.props:
        name = prop.mjcf_model.model
        reads[f"{name}/position"] = physics.bind(prop.position).sensordata
        reads[f"{name}/orientation"] = physics.bind(prop.orientation).sensordata
        reads[f"{name}/linear_velocity"] = physics.bind(prop.linear_velocity).sensordata
        reads[f"{name}/angular_velocity"] = physics.bind(prop.angular_velocity).sensordata
    return {key: np.array(value) for key, value in reads.items()}


def test_observables_read_through_views_equal_fresh_binding_reads(task_name):
    env = franka_composer.load(task_name, seed=2, terminate_on_success=False)
    rng = np.random.default_rng(1)
    timestep = env.reset()
    for step in range(25):
        observation = {k: np.array(v) for k, v in timestep.observation.items()}
        reads = _binding_reads(env)
        compared = [key for key in reads if key in observation]
        # Every field of the vector but the Euler angles (a transform), and the goal.
        expected = [f.key for f in env.task.observation_layout.fields
                    if not f.key.endswith("orientation_euler")] + ["goal"]
        assert sorted(compared) == sorted(expected)
        for key in compared:
            np.testing.assert_array_equal(observation[key], reads[key], err_msg=f"{key} @ {step}")
        # Readings are copies: stepping must not change an observation already returned.
        held = timestep.observation["panda/tcp_position"]
        before = held.copy()
        timestep = env.step(rng.uniform(-1, 1, env.action_spec().shape).astype(np.float32))
        np.testing.assert_array_equal(held, before)


def test_reward_discount_and_success_come_from_one_distance_per_step():
    """Ten random steps, then the scripted expert's push to the goal: both outcomes."""
    from franka_composer.policies import make_expert

    env = franka_composer.load("push", seed=3, reward_type="dense", terminate_on_success=False)
    timestep = env.reset()
    rng = np.random.default_rng(2)
    expert = make_expert(env)
    successes = []
    for step in range(50):
        action = (rng.uniform(-1, 1, 3) if step < 10 else expert(timestep.observation))
        timestep = env.step(np.asarray(action, np.float32))
        difference = timestep.observation["block/position"] - env.task.goal
        distance = np.sqrt(np.sum(difference * difference))
        assert timestep.reward == -distance
        assert env.task.success == (distance < 0.05)
        assert timestep.discount == 1.0
        successes.append(env.task.success)
    assert any(successes) and not all(successes)


def test_the_arms_joint_observables_read_its_angles_and_velocities_when_enabled():
    """Off by default (not in the paper's layout), on for a Composer user who asks."""
    env = franka_composer.load("push", seed=0, terminate_on_success=False)
    observables = env.task.panda.observables
    assert not observables.joints_pos.enabled and not observables.joints_vel.enabled
    observables.joints_pos.enabled = observables.joints_vel.enabled = True
    env.reset()
    timestep = env.step(np.full(3, 0.5, np.float32))
    joints = env.physics.bind(env.task.panda.joints)
    np.testing.assert_array_equal(timestep.observation["panda/joints_pos"], joints.qpos)
    np.testing.assert_array_equal(timestep.observation["panda/joints_vel"], joints.qvel)
    assert np.abs(joints.qvel).max() > 0.1  # The arm is moving: not a reading of zeros.
