"""The controllers: the `control` option, osc's torque law and the joint servos, pinned with
numbers (controllers/, entities/panda.py). Pressing under osc is in test_contacts.py."""

from __future__ import annotations

import re

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from conftest import grasp_block, hand_tilt_degrees, move_tcp_to
from franka_composer.controllers import JointController, MocapController, OscController
from franka_composer.policies import make_expert, rollout

#: Least fraction of a full 5 cm command the first osc step from rest covers, per direction.
#: Measured 0.80, 0.65, 0.70, 0.30; the torque limits allow at most 6.3, 4.0, 3.9 and 1.4 cm
#: flat out for the whole step (experiments/torque_reach.py): up, gravity takes 41 of joint
#: 2's 87 N m.
OSC_FIRST_STEP = {(1, 0, 0): 0.75, (0, -1, 0): 0.6, (0, 0, -1): 0.6, (0, 0, 1): 0.25}


def _arm_torque_ratio(env) -> float:
    """The largest |torque the law commands| / limit over the arm's motors now: the motors'
    ctrl, which MuJoCo would clamp to their range only when applying it."""
    commanded = env.physics.bind(env.task.panda.arm_actuators).ctrl
    return float(np.max(np.abs(commanded) / np.asarray(env.task.panda.arm_torque_limits)))


@pytest.mark.parametrize("control, controller, actuation, action, name", [
    ("mocap", MocapController, "none", 4, "tcp_delta_and_gripper"),
    ("osc", OscController, "torque", 4, "tcp_delta_and_gripper"),
    ("joints", JointController, "position", 8, "joint_delta_and_gripper"),
])
def test_the_control_option_builds_its_controller_and_action(control, controller, actuation,
                                                             action, name):
    env = franka_composer.load("pick_and_place", seed=0, control=control)
    assert type(env.task.controller) is controller
    assert env.task.panda.arm_actuation == actuation
    assert len(env.task.panda.arm_actuators) == (0 if actuation == "none" else 7)
    spec = env.action_spec()
    assert spec.shape == (action,) and spec.name == name
    assert env.task.config.options["control"] == control


def test_bad_controls_and_actions_are_refused_clearly():
    with pytest.raises(ValueError, match="unknown control 'impedance'; valid controls: "
                                         "mocap, osc, joints"):
        franka_composer.load("push", control="impedance")
    env = franka_composer.load("push", seed=0, control="joints")
    env.reset()
    with pytest.raises(ValueError, match=r"action must have shape \(7,\) \(dq1\.\.dq7\), "
                                         r"got shape \(3,\)"):
        env.step(np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="scripted experts act on dx, dy, dz, which the "
                                         "joints controller does not take"):
        make_expert(gym.make("FrankaPushJointsSparse-v1"))
    # Its actions were of the wrong length, a broadcast error at the first step. (Locked
    # fingers on pick-and-place: with its goals on the floor, none needing a grasp.)
    for id_, actuated, options in (
            ("FrankaPushSparse-v0", True, {}),
            ("FrankaPickAndPlaceSparse-v0", False, dict(goal_in_air_probability=0.0))):
        with pytest.raises(ValueError, match=re.escape(
                f"expert acts with the gripper {'locked' if actuated else 'actuated'}, as the "
                f"task defines it, and this env has actuated_gripper={actuated}")):
            make_expert(gym.make(id_, actuated_gripper=actuated, **options))


def test_osc_motors_have_the_real_panda_torque_limits():
    env = franka_composer.load("push", seed=0, control="osc")
    physics = env.physics
    motors = physics.bind(env.task.panda.arm_actuators)
    limits = np.array([87, 87, 87, 87, 12, 12, 12], dtype=float)
    np.testing.assert_array_equal(motors.forcerange, np.stack([-limits, limits], axis=1))
    np.testing.assert_array_equal(motors.ctrlrange, np.stack([-limits, limits], axis=1))
    # The links carry their own weight: the law holds the arm up, within those limits.
    assert not physics.model.body_gravcomp.any()


@pytest.mark.parametrize("direction", list(OSC_FIRST_STEP))
def test_osc_tracks_a_full_command_as_fast_as_the_torque_limits_allow(direction):
    env = franka_composer.load("push", seed=0, terminate_on_success=False, control="osc")
    timestep = env.reset()
    axis = np.asarray(direction, dtype=float)
    moves, sideways, tilts = [], [], []
    for _ in range(3):
        start = timestep.observation["panda/tcp_position"].copy()
        timestep = env.step(axis.astype(np.float32))
        moved = timestep.observation["panda/tcp_position"] - start
        moves.append(moved @ axis)
        sideways.append(np.linalg.norm(moved - (moved @ axis) * axis))
        tilts.append(hand_tilt_degrees(env))
    assert OSC_FIRST_STEP[direction] * 0.05 <= moves[0] <= 1.1 * 0.05
    for moved in moves[1:]:  # Measured 0.77-1.09 of a full step.
        assert 0.75 * 0.05 <= moved <= 1.15 * 0.05
    assert max(sideways) < 0.005  # Measured < 3.5 mm (going down, joints 2 and 4 saturated).
    assert max(tilts) < 5.0  # Measured < 0.3 deg.


def test_osc_zero_action_holds_the_hand_still():
    env = franka_composer.load("pick_and_place", seed=0, terminate_on_success=False,
                               control="osc")
    timestep = env.reset()
    timestep = move_tcp_to(env, timestep,
                           timestep.observation["panda/tcp_position"] + [0, 0.05, 0.05])
    start = timestep.observation["panda/tcp_position"].copy()
    for _ in range(10):
        timestep = env.step(np.zeros(4, np.float32))
    assert np.linalg.norm(timestep.observation["panda/tcp_position"] - start) < 0.002
    assert hand_tilt_degrees(env) < 5.0


def test_osc_torques_never_exceed_the_limits_and_do_reach_them():
    env = franka_composer.load("push", seed=3, terminate_on_success=False, control="osc")
    rng = np.random.default_rng(0)
    ratios = []
    for _ in range(2):
        env.reset()
        for _ in range(50):
            env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            ratios.append(_arm_torque_ratio(env))
    assert max(ratios) <= 1.0 + 1e-12
    assert max(ratios) > 0.999  # Full commands saturate a joint: the limits are live.


def test_osc_runs_its_torque_law_at_250_hz(monkeypatch):
    env = franka_composer.load("push", seed=0, control="osc")
    env.reset()
    law = env.task.controller.law
    updates = []
    update = law._update_torques  # pylint: disable=protected-access
    monkeypatch.setattr(law, "_update_torques", lambda: updates.append(1) or update())
    for _ in range(4):
        env.step(np.zeros(3, np.float32))
    # 4 steps of 0.05 s, 25 physics steps each: an update every other one, starting with the
    # first.
    assert len(updates) == 50


def test_osc_grasp_holds_through_a_lift_and_a_carry():
    env = franka_composer.load("pick_and_place", seed=1, terminate_on_success=False,
                               control="osc")
    timestep = grasp_block(env)
    assert timestep.observation["panda/finger_width"][0] == pytest.approx(0.04, abs=0.003)
    start = timestep.observation["block/position"].copy()
    gaps = []
    for action, axis, distance in (([0, 0, 0.3, -1], 2, 0.15), ([0, 0.2, 0, -1], 1, 0.1)):
        origin = timestep.observation["panda/tcp_position"][axis]
        for _ in range(15):  # Until the hand has gone the distance.
            if timestep.observation["panda/tcp_position"][axis] - origin >= distance:
                break
            timestep = env.step(np.array(action, np.float32))
            gaps.append(np.linalg.norm(timestep.observation["panda/tcp_position"]
                                       - timestep.observation["block/position"]))
    moved = timestep.observation["block/position"] - start
    assert moved[2] > 0.13 and moved[1] > 0.09
    assert max(gaps) < 0.02  # Measured ~1 mm.


@pytest.mark.parametrize("joint", range(7))
def test_a_full_joint_action_moves_that_joint_most_of_a_step(joint):
    env = franka_composer.load("push", seed=0, terminate_on_success=False, control="joints")
    start = env.reset().observation["panda/joints_pos"].copy()
    action = np.zeros(7, np.float32)
    action[joint] = 1.0
    moved = env.step(action).observation["panda/joints_pos"] - start
    assert 0.8 * 0.05 <= moved[joint] <= 1.1 * 0.05  # Measured 0.83-1.01.
    assert np.max(np.abs(np.delete(moved, joint))) < 0.01  # Measured < 0.008.


def test_zero_joint_actions_hold_every_joint():
    env = franka_composer.load("push", seed=0, terminate_on_success=False, control="joints")
    timestep = env.reset()
    for start_action in (np.zeros(7), np.eye(7)[1]):  # At rest, then after a move.
        timestep = env.step(start_action.astype(np.float32))
        for _ in range(5):  # Let a move settle.
            timestep = env.step(np.zeros(7, np.float32))
        start = timestep.observation["panda/joints_pos"].copy()
        for _ in range(10):
            timestep = env.step(np.zeros(7, np.float32))
        assert np.max(np.abs(timestep.observation["panda/joints_pos"] - start)) < 0.005


def test_joint_control_observes_the_joint_angles_last():
    env = gym.make("FrankaPickAndPlaceJointsSparse-v1")
    obs, _ = env.reset(seed=0)
    layout = env.unwrapped.observation_layout
    assert layout.names[-1] == "joint_angles" and layout.slice("joint_angles").stop == 26
    physics = env.unwrapped.composer_env.physics
    np.testing.assert_array_equal(
        obs["observation"][-7:], physics.bind(env.unwrapped.task.panda.joints).qpos)
    # Every other field keeps its index: the mocap layout is a prefix.
    mocap = gym.make("FrankaPickAndPlaceSparse-v0").unwrapped.observation_layout
    assert layout.fields[:len(mocap.fields)] == mocap.fields


@pytest.mark.slow
@pytest.mark.parametrize("task", ["push", "slide", "pick_and_place"])
def test_scripted_experts_reach_90_percent_under_osc(task):
    """The same experts act on dx, dy, dz under osc (measured over 50 episodes: push 96 %,
    slide 98 %, pick_and_place 100 %)."""
    env = gym.make(f"Franka{''.join(p.capitalize() for p in task.split('_'))}OscSparse-v0")
    assert rollout(env, make_expert(env), 20, seed=0).success_rate >= 0.9
