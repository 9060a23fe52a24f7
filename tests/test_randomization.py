"""Domain randomisation (`randomization` option): drawn per episode from the seed, written into
the compiled model without recompiling, reported, and never touching the goals, so rewards and
HER relabelling stay exact (franka_composer/randomization/, tasks/goal_task.py)."""

from __future__ import annotations

import pickle
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from dm_control.composer.variation import distributions, noises

import franka_composer
from franka_composer import fast_path
from franka_composer.adapters.registration import env_id
from franka_composer.controllers import CONTROLS
from franka_composer.environment import GoalEnvironment
from franka_composer.randomization import PARAMETERS, PRESETS
from franka_composer.randomization.parameters import MAX_DELAY
from conftest import (SPEC, UNBOUNDED_OBSERVATIONS, batches_substeps, contact_frictions,
                      env_checker_findings, grasp_block, her_samples)

DEFAULT = PRESETS["default"]
VISUAL = {name: d for name, d in DEFAULT.items() if PARAMETERS[name].group == "visual"}
PHYSICS = {name: d for name, d in DEFAULT.items() if PARAMETERS[name].group == "physics"}


def _make(task="push", control="mocap", **options):
    return gym.make(env_id(task, "sparse", control), **options)


def _rollout(env, seed: int, steps: int, actions=None):
    """Observations, rewards and infos of `steps` steps from `reset(seed)`, with the given
    actions (or the action space's, seeded), resetting without a seed when an episode ends."""
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    records = [(obs, None, info)]
    for step in range(steps):
        action = env.action_space.sample() if actions is None else actions[step]
        obs, reward, terminated, truncated, info = env.step(action)
        records.append((obs, reward, info))
        if terminated or truncated:
            obs, info = env.reset()
            records.append((obs, None, info))
    return records


@pytest.mark.parametrize("control, mode", [(control, "state") for control in CONTROLS]
                         + [("mocap", "pixels"), ("mocap", "state+pixels")])
def test_every_task_controller_and_mode_keeps_the_goal_contract_under_the_default_preset(
        task_name, control, mode):
    env = _make(task_name, control, randomization="default", terminate_on_success=False,
                observation_mode=mode)
    assert env_checker_findings(env) == UNBOUNDED_OBSERVATIONS
    records = _rollout(env, seed=1, steps=SPEC[task_name]["steps"] + 5)
    applied = {name for name in DEFAULT if PARAMETERS[name].episode
               and (mode != "state" or not PARAMETERS[name].observed_cameras)
               and (task_name != "reach" or not PARAMETERS[name].needs_objects)}
    for obs, reward, info in records:
        assert env.observation_space.contains(obs)
        assert set(info["randomization"]) == applied
        if reward is not None:
            assert reward == env.unwrapped.compute_reward(obs["achieved_goal"],
                                                          obs["desired_goal"], info)
    clone = pickle.loads(pickle.dumps(env))
    for key, value in clone.reset(seed=4)[0].items():
        np.testing.assert_array_equal(value, env.reset(seed=4)[0][key])
    env.close()


def test_a_mapping_built_on_a_preset_survives_copies_and_pickles():
    """The guide's idiom, `{**PRESETS["default"], ...}`: its camera entries apply where images
    are observed, and a state env takes them. A pickled or copied env (a spawned or
    forkserver vector env's worker, SB3's SubprocVecEnv) holds copies of them, which were
    told from the preset's by identity and refused there ("camera_position does nothing
    here"); so was `load(task, randomization=copy.deepcopy(PRESETS["default"]))`."""
    import copy

    mapping = {**PRESETS["default"], "object_mass": distributions.Uniform(0.2, 2.0)}
    env = _make(randomization=mapping)
    first = env.reset(seed=0)[0]
    for clone in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        for key, value in clone.reset(seed=0)[0].items():
            np.testing.assert_array_equal(value, first[key])
        clone.close()
    env.close()
    for task in ("push", "reach"):  # Reach: the preset's object entries, copied.
        franka_composer.load(task, randomization=copy.deepcopy(PRESETS["default"])).reset()
    # An entry of one's own is still refused where it does nothing, even one that draws as
    # the preset's does (told apart by the preset's mark, not by what they draw).
    for own in (distributions.Uniform(-0.02, 0.02), distributions.Uniform(-0.01, 0.01)):
        with pytest.raises(ValueError, match=re.escape(
                "randomization 'camera_position' does nothing here: no camera's images are "
                "observed")):
            _make(randomization={"camera_position": own})
    with pytest.raises(ValueError, match=re.escape(
            "randomization 'object_mass' does nothing here: reach has no object")):
        franka_composer.load("reach", randomization={
            "object_mass": distributions.Uniform(0.5, 1.5)})
    # A preset's entry under another parameter is not that parameter's preset entry.
    with pytest.raises(ValueError, match=re.escape("randomization 'camera_rotation' does "
                                                   "nothing here")):
        _make(randomization={"camera_rotation": PRESETS["default"]["camera_position"]})


def test_numpy_constants_are_taken_as_the_numbers_they_hold():
    """np.float32 and np.int64 constants were refused as "not a distribution or a constant"
    (np.float64, a float subclass, was taken); numpy's bools for the bool options too."""
    expected = None
    for mass, delay, flag in ((0.5, 1, False), (np.float32(0.5), np.int64(1), np.False_)):
        env = _make(randomization={"object_mass": mass, "observation_delay": delay},
                    terminate_on_success=flag)
        drawn = env.reset(seed=3)[1]["randomization"]
        assert env.unwrapped.task.config.terminate_on_success is False
        env.close()
        assert drawn["object_mass"] == (0.5,) and drawn["observation_delay"] == 1
        assert expected is None or drawn == expected
        expected = drawn


def test_drawn_parameters_stay_in_their_ranges_and_differ_across_episodes():
    env = _make("stack", randomization="default")
    draws = [env.reset(seed=0)[1]["randomization"]] + [
        env.reset()[1]["randomization"] for _ in range(29)]
    for name, low, high in (("object_mass", 0.5, 1.5), ("object_friction", 0.7, 1.3),
                            ("floor_friction", 0.7, 1.3), ("gripper_gain", 0.8, 1.2),
                            ("joint_damping", 0.5, 1.5), ("controller_gain", 0.8, 1.2),
                            ("object_rgb", 0.05, 0.95), ("floor_tint", 0.6, 1.0),
                            ("robot_tint", 0.7, 1.0), ("light_direction", -0.3, 0.3),
                            ("light_intensity", 0.6, 1.4)):
        values = np.array([draw[name] for draw in draws], dtype=np.float64)
        assert values.min() >= low and values.max() <= high, name
        assert len(np.unique(values)) == values.size, name  # Continuous: all different.
    assert np.array([d["object_mass"] for d in draws]).shape == (30, 2)  # One per block.
    delays = [draw["observation_delay"] for draw in draws]
    assert set(delays) == {0, 1} and all(type(d) is int for d in delays)
    # No camera is observed: the preset's camera jitter moves none, and is not reported
    # (it was, as if applied).
    assert not {"camera_position", "camera_rotation"} & set(draws[0])
    env.close()
    pixels = _make("stack", randomization="default", observation_mode="pixels",
                   pixel_width=32, pixel_height=24)
    cameras = [pixels.reset(seed=0)[1]["randomization"]] + [
        pixels.reset()[1]["randomization"] for _ in range(9)]
    pixels.close()
    for name, low, high in (("camera_position", -0.01, 0.01),
                            ("camera_rotation", -0.035, 0.035)):
        values = np.array([draw[name] for draw in cameras], dtype=np.float64)
        assert values.min() >= low and values.max() <= high, name
        assert len(np.unique(values)) == values.size, name
    # The same visual stream either way: the draws that apply in both are the same.
    assert [draw["light_intensity"] for draw in cameras] == [
        draw["light_intensity"] for draw in draws[:10]]


def test_parameters_are_written_into_the_compiled_model_without_recompiling():
    """Every drawn parameter, against the same env's model unrandomised."""
    env = franka_composer.load("push", seed=0, randomization="default",
                               observation_mode="state+pixels")
    env.reset()
    physics, task = env.physics, env.task
    model = physics.model.ptr
    nominal_mass = task.config.objects[0].mass
    first_model = model
    plain = franka_composer.load("push", seed=0, observation_mode="state+pixels")
    plain.reset()
    nominal = plain.physics.model.ptr
    floor_material = int(model.geom_matid[physics.bind(task.root_entity.floor).element_id])
    panda = np.asarray(physics.bind(task.panda.mjcf_model.find_all("geom")).element_id)
    panda_materials = np.asarray(
        physics.bind(task.panda.mjcf_model.find_all("material")).element_id)
    lights = np.asarray(physics.bind(task.root_entity.mjcf_model.find_all("light")).element_id)
    cameras = [int(physics.bind(task.root_entity.workspace_camera).element_id)]  # The pixels'.
    for _ in range(3):
        env.reset()
        drawn = task.randomization
        # The same physics and compiled model, every episode.
        assert env.physics is physics and env.physics.model.ptr is first_model
        body = physics.bind(task.prop.geom).bodyid
        assert model.body_mass[body] == pytest.approx(nominal_mass * drawn["object_mass"][0],
                                                      rel=1e-12)
        # The block-floor pair's sliding friction, scaled by both surfaces' factors.
        block_on_floor = physics.named.model.pair_friction["block_floor"]
        np.testing.assert_allclose(block_on_floor[:2], 1.0 * drawn["object_friction"][0]
                                   * drawn["floor_friction"], rtol=1e-12)
        np.testing.assert_array_equal(physics.bind(task.prop.geom).rgba[:3],  # float32
                                      np.float32(drawn["object_rgb"][0]))
        damping = physics.bind(task.panda.joints).damping
        np.testing.assert_allclose(damping, drawn["joint_damping"], rtol=1e-12)
        weld = physics.named.model.eq_solref["tcp_weld"]
        assert weld[0] == pytest.approx(0.01 / np.sqrt(drawn["controller_gain"]), rel=1e-12)
        gripper = physics.bind(task.panda.gripper_actuator)
        assert -gripper.biasprm[1] == pytest.approx(1000.0 * drawn["gripper_gain"], rel=1e-12)
        # The geoms keep their nominal friction: the hand's contacts are MuJoCo's own.
        np.testing.assert_array_equal(model.geom_friction, nominal.geom_friction)
        np.testing.assert_allclose(model.mat_rgba[floor_material, :3],
                                   nominal.mat_rgba[floor_material, :3] * drawn["floor_tint"],
                                   rtol=1e-6)
        np.testing.assert_allclose(model.geom_rgba[panda, :3],
                                   nominal.geom_rgba[panda, :3] * drawn["robot_tint"], rtol=1e-6)
        np.testing.assert_allclose(model.mat_rgba[panda_materials, :3],  # What renders.
                                   nominal.mat_rgba[panda_materials, :3] * drawn["robot_tint"],
                                   rtol=1e-6)
        direction = nominal.light_dir[lights] + drawn["light_direction"]
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        np.testing.assert_allclose(model.light_dir[lights], direction, rtol=1e-12)
        # A tracking light keeps the direction it has at qpos0: the same (here mj_setConst,
        # run for the drawn masses, sets it too; the next test holds the write alone).
        np.testing.assert_allclose(model.light_dir0[lights], direction, rtol=1e-12)
        np.testing.assert_allclose(model.light_diffuse[lights], nominal.light_diffuse[lights]
                                   * drawn["light_intensity"], rtol=1e-6)
        moved = np.flatnonzero(np.any(model.cam_pos != nominal.cam_pos, axis=1))
        np.testing.assert_array_equal(moved, cameras)  # The observation's camera, and only it.
        for camera in cameras:
            np.testing.assert_allclose(model.cam_pos[camera], nominal.cam_pos[camera]
                                       + drawn["camera_position"], atol=1e-12)
            cosine = min(1.0, abs(model.cam_quat[camera] @ nominal.cam_quat[camera]))
            assert 2 * np.arccos(cosine) == pytest.approx(abs(drawn["camera_rotation"]),
                                                          abs=1e-7)


@pytest.mark.parametrize("factors", [{"object_friction": 0.7}, {"floor_friction": 0.7},
                                     {"object_friction": 0.7, "floor_friction": 0.8}])
def test_a_friction_factor_below_one_reaches_the_block_floor_contact(factors):
    """Each surface's factor scales the contacts it is in: nominal x object x floor. Written
    into the geoms, a factor below 1 was hidden by the other geom's friction (MuJoCo's
    contact took the larger): under the default preset the block-floor contact was below
    nominal in 24 % of 1000 resets, where half the draws of each factor are."""
    env = franka_composer.load("push", seed=0, randomization=factors)
    env.reset()
    frictions = contact_frictions(env, env.task.prop.geom, env.task.root_entity.floor)
    expected = 1.0 * factors.get("object_friction", 1.0) * factors.get("floor_friction", 1.0)
    assert frictions and frictions == [expected] * len(frictions)


def test_each_blocks_friction_factor_scales_the_stacked_blocks_contact():
    """Block 2 set on block 1: their contact's friction is nominal x factor 1 x factor 2,
    each block's on the floor nominal x its own factor."""
    env = franka_composer.load("stack", seed=0, randomization={
        "object_friction": distributions.Uniform(0.5, 1.5)})
    env.reset()
    first, second = env.task.props
    factors = env.task.randomization["object_friction"]
    assert factors[0] != factors[1]
    physics = env.physics
    position = first.get_pose(physics)[0]
    second.set_pose(physics, position=position + [0.0, 0.0, 0.0399])  # Resting on it.
    physics.forward()
    stacked = contact_frictions(env, first.geom, second.geom)
    assert stacked and stacked == [1.0 * factors[0] * factors[1]] * len(stacked)
    on_floor = contact_frictions(env, first.geom, env.task.root_entity.floor)
    assert on_floor and on_floor == [1.0 * factors[0]] * len(on_floor)


def test_the_finger_pads_keep_their_grip_friction_under_an_object_friction_factor():
    """The hand's contacts are MuJoCo's own: the pads' friction 2 rules the grip whatever
    the block's factor (written into the block's geom, a factor of 2.5 made it 2.5)."""
    env = franka_composer.load("pick_and_place", seed=0, terminate_on_success=False,
                               randomization={"object_friction": 2.5})
    env.reset()
    block = env.task.prop.geom
    on_floor = contact_frictions(env, block, env.task.root_entity.floor)
    assert on_floor and on_floor == [2.5] * len(on_floor)
    grasp_block(env)
    gripping = [friction for pad in env.task.panda.mjcf_model.find_all("geom")
                for friction in contact_frictions(env, block, pad)]
    assert len(gripping) >= 2 and gripping == [2.0] * len(gripping)


def test_a_drawn_light_renders_the_same_with_or_without_mass_randomisation():
    """`mj_setConst` (run for new masses) takes a tracking light's direction from the model:
    the light (Menagerie's trackcom "top" among them) must be written so that it does not
    matter, and an episode's images depend on its draws alone."""
    light = {"light_direction": DEFAULT["light_direction"]}
    images = [_make(observation_mode="pixels", randomization=options).reset(seed=3)[0]
              ["workspace_pixels"] for options in (None, light, {**light, "object_mass": 1.0})]
    assert np.any(images[0] != images[1], axis=-1).sum() > 100  # The light moved.
    np.testing.assert_array_equal(images[1], images[2])


def test_controller_gains_scale_under_every_controller():
    gain = {"controller_gain": 1.44}
    osc = franka_composer.load("push", seed=0, control="osc", randomization=gain)
    osc.reset()
    assert osc.task.controller.law._gains[0] == pytest.approx(4900.0 * 1.44)
    assert osc.task.controller.law._gains[1] == pytest.approx(2 * np.sqrt(4900.0 * 1.44))
    joints = franka_composer.load("push", seed=0, control="joints", randomization=gain)
    joints.reset()
    servos = joints.physics.bind(joints.task.panda.arm_actuators)
    nominal = franka_composer.load("push", seed=0, control="joints")
    nominal.reset()
    reference = nominal.physics.bind(nominal.task.panda.arm_actuators)
    np.testing.assert_allclose(servos.gainprm[:, 0], 1.44 * reference.gainprm[:, 0])
    np.testing.assert_allclose(servos.biasprm[:, 1:3], 1.44 * reference.biasprm[:, 1:3])


def test_identity_randomisation_reproduces_the_unrandomised_trajectory_bit_for_bit():
    """Factors of exactly 1 written every episode (with `mj_setConst`) change nothing."""
    ones = {name: 1.0 for name in PHYSICS}
    plain = _rollout(_make("pick_and_place"), seed=2, steps=60)
    identity = _rollout(_make("pick_and_place", randomization=ones), seed=2, steps=60)
    drawn = identity[0][2]["randomization"]  # The factors were applied, each of them 1.
    assert set(drawn) == set(PHYSICS) and all(np.all(np.equal(value, 1.0))
                                              for value in drawn.values())
    for (a, reward_a, _), (b, reward_b, _) in zip(plain, identity):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
        assert reward_a == reward_b


def test_the_same_seed_gives_the_same_parameters_pixels_and_trajectory():
    options = dict(randomization="default", observation_mode="state+pixels")
    first = _rollout(_make(**options), seed=7, steps=60)
    second = _rollout(_make(**options), seed=7, steps=60)
    for (a, reward_a, info_a), (b, reward_b, info_b) in zip(first, second):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
        assert reward_a == reward_b and info_a == info_b
    other = _rollout(_make(**options), seed=8, steps=0)
    assert other[0][2]["randomization"] != first[0][2]["randomization"]


def test_randomisation_keeps_the_seeds_episodes():
    """The draws come from streams of their own: the same seed starts the same episodes
    (object placements, goals) with or without randomisation."""
    plain, randomised = _make("slide"), _make("slide", randomization="default")
    for seed in range(4):
        a, b = plain.reset(seed=seed)[0], randomised.reset(seed=seed)[0]
        np.testing.assert_array_equal(a["desired_goal"], b["desired_goal"])
        np.testing.assert_array_equal(a["achieved_goal"], b["achieved_goal"])


def test_visual_randomisation_changes_the_images_and_nothing_in_the_state_trajectory():
    plain = _make("pick_and_place", observation_mode="state+pixels", cameras=("workspace",
                                                                               "wrist"))
    visual = _make("pick_and_place", observation_mode="state+pixels",
                   cameras=("workspace", "wrist"), randomization=VISUAL)
    actions = np.random.default_rng(0).uniform(-1, 1, (40, 4)).astype(np.float32)
    changed = []
    for (a, reward_a, _), (b, reward_b, _) in zip(_rollout(plain, 3, 40, actions),
                                                  _rollout(visual, 3, 40, actions)):
        for key in ("observation", "achieved_goal", "desired_goal"):
            np.testing.assert_array_equal(a[key], b[key])
        assert reward_a == reward_b
        for key in ("workspace_pixels", "wrist_pixels"):
            changed.append(np.mean(np.any(a[key] != b[key], axis=-1)))
    assert min(changed) > 0.2  # Every image differs in more than a fifth of its pixels.


@pytest.mark.parametrize("path", ["fast", "stock"])
@pytest.mark.parametrize("steps_late", [1, 3])
def test_an_observation_delay_returns_the_reading_of_k_steps_before(monkeypatch, path,
                                                                    steps_late):
    monkeypatch.setenv(fast_path.ENV_VARIABLE, "1" if path == "fast" else "0")
    options = dict(observation_mode="state+pixels", terminate_on_success=False)
    plain = _make(**options)
    delayed = _make(randomization={"observation_delay": steps_late}, **options)
    actions = np.random.default_rng(1).uniform(-1, 1, (30, 3)).astype(np.float32)
    now = _rollout(plain, 5, 30, actions)
    late = _rollout(delayed, 5, 30, actions)
    for step, (obs, reward, _) in enumerate(late):
        then = now[max(step - steps_late, 0)][0]
        for key in ("observation", "workspace_pixels"):
            np.testing.assert_array_equal(obs[key], then[key])
        # The goals, and with them the reward, are never late.
        for key in ("achieved_goal", "desired_goal"):
            np.testing.assert_array_equal(obs[key], now[step][0][key])
        assert reward == now[step][1]
    assert not np.array_equal(late[10][0]["observation"], now[10][0]["observation"])


@pytest.mark.parametrize("steps_late", [2, 3])
def test_a_delayed_joints_observation_holds_no_live_joint_angles(steps_late):
    """The joint angles were read as a view of qpos, which Composer's delay buffered: for
    the first steps the observation showed the live angles, then went back to the reset's."""
    plain = _make(control="joints", terminate_on_success=False)
    delayed = _make(control="joints", randomization={"observation_delay": steps_late},
                    terminate_on_success=False)
    actions = np.ones((8, 7), np.float32)
    now, late = _rollout(plain, 0, 8, actions), _rollout(delayed, 0, 8, actions)
    for step, (obs, _, _) in enumerate(late):
        np.testing.assert_array_equal(obs["observation"],
                                      now[max(step - steps_late, 0)][0]["observation"])


def test_observation_noise_has_its_spread_per_field_and_leaves_the_goals_exact():
    noise = {"position_noise": distributions.Normal(0.0, 0.002),
             "velocity_noise": distributions.Normal(0.0, 0.01)}
    plain, noisy = _make(terminate_on_success=False), _make(randomization=noise,
                                                          terminate_on_success=False)
    layout = plain.unwrapped.observation_layout
    actions = np.random.default_rng(2).uniform(-1, 1, (200, 3)).astype(np.float32)
    a_records, b_records = _rollout(plain, 0, 200, actions), _rollout(noisy, 0, 200, actions)
    errors = np.array([b[0]["observation"] - a[0]["observation"]
                       for a, b in zip(a_records, b_records)])
    for a, b in zip(a_records, b_records):
        for key in ("achieved_goal", "desired_goal"):
            np.testing.assert_array_equal(a[0][key], b[0][key])
    for field, spread in (("tcp_position", 0.002), ("object_position", 0.002),
                          ("tcp_velocity", 0.01 * 0.05), ("object_linear_velocity", 0.01 * 0.05)):
        assert layout.read(errors, field).std() == pytest.approx(spread, rel=0.1), field
    np.testing.assert_array_equal(layout.read(errors, "object_orientation"), 0.0)


def test_angle_noise_turns_a_quaternion_reading_and_leaves_it_unit():
    """Angle noise was added to a quaternion's components: under the preset's Normal(0,
    0.01) flip's cube read as norm 0.9925, no orientation. It now turns the reading by a
    rotation vector of three draws: unit to rounding, turned by the draws' norm (about
    0.016 rad on average, for 0.01 rad each), and the goals stay exact."""
    noise = {"angle_noise": distributions.Normal(0.0, 0.01)}
    plain = _make("flip", terminate_on_success=False)
    noisy = _make("flip", randomization=noise, terminate_on_success=False)
    layout = plain.unwrapped.observation_layout
    steps, size = 100, plain.action_space.shape[0]
    actions = np.random.default_rng(2).uniform(-1, 1, (steps, size)).astype(np.float32)
    a_records, b_records = _rollout(plain, 0, steps, actions), _rollout(noisy, 0, steps, actions)
    exact = np.array([layout.read(a[0]["observation"], "object_orientation") for a in a_records])
    read = np.array([layout.read(b[0]["observation"], "object_orientation") for b in b_records])
    np.testing.assert_allclose(np.linalg.norm(read, axis=1), 1.0, rtol=0, atol=1e-12)
    turn = 2 * np.arccos(np.clip(np.abs(np.sum(exact * read, axis=1)), 0.0, 1.0))
    assert 0.013 < turn.mean() < 0.019 and turn.max() < 0.06, turn
    for a, b in zip(a_records, b_records):
        for key in ("achieved_goal", "desired_goal"):
            np.testing.assert_array_equal(a[0][key], b[0][key])
    # A scale cannot turn an orientation: as a multiplicative noise it changed nothing.
    with pytest.raises(ValueError, match="^" + re.escape(
            "randomization 'angle_noise' as noises.Multiplicative scales each angle reading, "
            "and flip observes its object's orientation as a unit quaternion, which a scale "
            "cannot turn: give a distribution (three draws a step turn it, in rad) or "
            "noises.Additive") + "$"):
        _make("flip", randomization={"angle_noise": noises.Multiplicative(
            distributions.Normal(1.0, 0.5))})
    _make("flip", randomization={"angle_noise": noises.Additive(
        distributions.Normal(0.0, 0.01))}).close()


def test_composers_noise_wrappers_act_on_the_reading_as_its_corruptors_do():
    """noises.Additive(d) on a reading gave the reading twice plus the noise (the wrapper's
    value, the reading plus d's draw, was added to the reading again); on the action, a
    move twice as long."""
    plain = _make("pick_and_place").reset(seed=0)[0]["observation"]
    for noise, expected in ((noises.Additive(distributions.Normal(0.0, 1e-9)), 1.0),
                            (noises.Multiplicative(distributions.Uniform(1.5, 1.5)), 1.5)):
        obs = _make("pick_and_place", randomization={"position_noise": noise}).reset(
            seed=0)[0]["observation"]
        np.testing.assert_allclose(obs[:3], expected * plain[:3], rtol=1e-6, atol=1e-8)
    moves = []
    # Arithmetic on a distribution is a distribution of what is added, not a wrapper.
    for randomization in (None, {"action_noise": noises.Additive(
            distributions.Normal(0.0, 1e-12))},
                          {"action_noise": 1e-12 * distributions.Normal(0.0, 1.0)}):
        env = franka_composer.load("push", seed=0, randomization=randomization)
        env.reset()
        start = env.physics.bind(env.task.panda.tcp_site).xpos.copy()
        env.step(np.array([0.3, 0.0, 0.0]))
        moves.append(env.physics.bind(env.task.panda.tcp_site).xpos - start)
    np.testing.assert_allclose(moves[1], moves[0], atol=1e-9)
    np.testing.assert_allclose(moves[2], moves[0], atol=1e-9)


def test_a_colour_jitter_about_each_objects_colour_is_taken_within_its_range():
    """It was refused: the option probed it about white."""
    colour = np.array(franka_composer.load("push").task.prop.rgba[:3])
    env = _make(render_mode="rgb_array", randomization={"object_rgb": noises.Multiplicative(
        distributions.Uniform(0.9, 1.1))})
    drawn = np.array(env.reset(seed=0)[1]["randomization"]["object_rgb"][0])
    assert np.all((drawn >= 0.9 * colour - 1e-12) & (drawn <= 1.1 * colour + 1e-12))
    assert not np.allclose(drawn, colour)
    # About the colour, out of [0, 1] (its blue is 0.9): refused as the task is made.
    with pytest.raises(ValueError, match=re.escape(
            "randomization 'object_rgb' is a colour and must draw numbers in [0, 1]")):
        _make(render_mode="rgb_array", randomization={"object_rgb": noises.Multiplicative(
            distributions.Uniform(0.9, 1.5))})
    # Its range is known from the colour: one that leaves [0, 1] by 0.0005 (blue 0.9 x 1.1117)
    # is refused as well, though 64 probe draws miss it (a later reset met it).
    with pytest.raises(ValueError, match=re.escape(
            "draws in [0.05, 1.00053]: refused now, not at the first reset that draws outside")):
        _make(render_mode="rgb_array", randomization={"object_rgb": noises.Multiplicative(
            distributions.Uniform(0.5, 1.1117))})


@pytest.mark.parametrize("task, markers", [("stack", ("marker1", "marker2")),
                                           ("flip", ("marker",))])
def test_goal_markers_take_their_objects_drawn_colours(task, markers):
    """Stack's markers said which block goes where only by colour: under `object_rgb` they
    kept the nominal blue and green while the blocks took any colour (seed 1 drew block 1
    green, block 2's marker's colour), and a pixel policy could not tell the blocks apart."""
    env = franka_composer.load(task, seed=1, observation_mode="pixels",
                               randomization={"object_rgb": distributions.Uniform(0.05, 0.95)})
    physics = env.physics
    for _ in range(2):
        env.reset()
        drawn = np.float32(env.task.randomization["object_rgb"])
        sites = physics.named.model.site_rgba
        for colour, marker in zip(drawn, markers):
            np.testing.assert_array_equal(sites[f"goal/{marker}"], [*colour, np.float32(0.35)])
        np.testing.assert_array_equal(
            physics.bind([prop.geom for prop in env.task.props]).rgba[:, :3], drawn)


def test_a_light_direction_offset_that_cancels_a_light_is_refused_by_name():
    env = _make(render_mode="rgb_array", randomization={"light_direction": (0.0, 0.0, 1.0)})
    with pytest.raises(ValueError, match=re.escape(
            "randomization 'light_direction' drew [0.0, 0.0, 1.0], which cancels a light's "
            "direction [0.0, 0.0, -1.0]: offsets must leave every direction some length")):
        env.reset(seed=0)


@pytest.mark.parametrize("interface", ["dm_env", "gym"])
def test_a_reset_whose_draw_is_refused_is_not_drawn_again_by_the_next(interface):
    """A draw is refused at the reset that makes it (a light offset that can cancel a light,
    drawn 0 or 1 per axis). The draws were keyed by the episode's random state, which the
    refused reset left where it was: every reset after it drew the same and failed the
    same, forever (a vector env's worker could not go on). Now it moves on."""
    light = {"light_direction": distributions.UniformInteger(0, 2)}
    if interface == "dm_env":
        reset = franka_composer.load("push", seed=0, randomization=light).reset
    else:
        env = _make(render_mode="rgb_array", randomization=light)
        env.reset(seed=0)
        reset = env.reset  # Unseeded: each continues the stream.
    outcomes = []
    for _ in range(40):
        try:
            reset()
            outcomes.append(None)
        except ValueError as error:
            assert "randomization 'light_direction' drew" in str(error)
            outcomes.append(str(error))
    refused = [i for i, outcome in enumerate(outcomes) if outcome is not None]
    assert 0 < len(refused) < 20, outcomes
    assert [i for i in refused[:-1] if outcomes[i + 1] == outcomes[i]] == []


def test_a_mass_factor_too_small_for_mujoco_is_a_value_error_naming_it():
    """A factor of 1e-11 left the block's inertia below what MuJoCo simulates, and the reset
    raised dm_control's PhysicsError from inside the block's placer. The least mass is the one
    a body compiles with: the option refuses less (it was made that mass, 1e-5 kg, silently);
    a draw from a range not known to reach it (a wrapped distribution) is refused at its
    reset."""
    env = franka_composer.load("pick_and_place", seed=0, randomization={
        "object_mass": distributions.Uniform(1e-6, 2e-4) * distributions.LogNormal(0, 0.01)})
    with pytest.raises(ValueError, match=re.escape(
            "randomization 'object_mass' drew a factor of 9.03984e-05, which makes an object "
            "9.03984e-06 kg, lighter than any body compiles (1e-05 kg): bound the factor away "
            "from 0")):
        env.reset()
    with pytest.raises(ValueError, match=re.escape(
            "object_mass must be >= 1e-05, got 1e-12")):
        franka_composer.load("pick_and_place", object_mass=1e-12)
    franka_composer.load("pick_and_place", object_mass=1e-5).reset()  # The least, taken.
    # A range known to reach below it is refused as the env is made, not at some reset.
    with pytest.raises(ValueError, match=re.escape(
            "randomization 'object_mass' draws factors in [1e-06, 0.0002], which make a 0.1 kg "
            "object as light as 1e-07 kg, lighter than any body compiles (1e-05 kg): refused "
            "now")):
        franka_composer.load("pick_and_place", randomization={
            "object_mass": distributions.Uniform(1e-6, 2e-4)})


def test_action_noise_moves_the_target_by_the_noise():
    env = franka_composer.load("push", seed=0, randomization={
        "action_noise": distributions.Normal(0.0, 0.1)})
    env.reset()
    moves = []
    for _ in range(100):
        tcp = env.physics.bind(env.task.panda.tcp_site).xpos.copy()
        env.step(np.zeros(3))
        moves.append(env.physics.bind(env.task.controller.target).mocap_pos - tcp)
    moves = np.array(moves) / 0.05  # In units of a full action.
    assert moves.std() == pytest.approx(0.1, rel=0.15)
    assert abs(moves.mean()) < 0.03


def test_fast_and_stock_paths_agree_under_the_default_preset(monkeypatch):
    records = {}
    for path in ("fast", "stock"):
        monkeypatch.setenv(fast_path.ENV_VARIABLE, "1" if path == "fast" else "0")
        env = _make("pick_and_place", randomization="default")
        assert type(env.unwrapped.composer_env) is (fast_path.FastEnvironment if path == "fast"
                                                     else GoalEnvironment)
        records[path] = _rollout(env, 11, 120)
        assert batches_substeps(env.unwrapped.composer_env) == (path == "fast")
    for (a, reward_a, info_a), (b, reward_b, info_b) in zip(records["fast"], records["stock"]):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
        assert reward_a == reward_b and info_a == info_b


def test_her_relabelled_rewards_are_exact_under_randomisation():
    env = _make("push", randomization="default", terminate_on_success=False)
    achieved, desired, rewards = her_samples(env, 200)
    np.testing.assert_array_equal(
        rewards, env.unwrapped.compute_reward(achieved, desired, None).astype(np.float32))
    assert 0.1 < (rewards == 0).mean() < 1


@pytest.mark.parametrize("parameter, distribution, drawn", [
    # Rarely outside: 64 draws pass, and a reset hours into a run would be the first.
    ("object_mass", distributions.Normal(1.0, 0.1), "(-inf, inf)"),
    ("joint_damping", 1.0 + 0.1 * distributions.Normal(0.0, 1.0), "(-inf, inf)"),
    ("floor_friction", distributions.Exponential(1.0) + 0.0, "[0, inf)"),
    ("object_friction", distributions.Uniform(0.5, 1.5) - 0.5, "[0, 1]"),
    ("observation_delay", distributions.Poisson(0.01), "[0, inf)"),
    ("observation_delay", 60 * distributions.Bernoulli(1e-4), "[0, 60]"),
    # Through a divisor or a product that can be 0 or unbounded.
    ("object_mass", 1.0 / distributions.Normal(1.0, 0.3), "(-inf, inf)"),
    ("object_mass", distributions.Uniform(0.0, 1.0) * distributions.Normal(1.0, 0.3),
     "(-inf, inf)"),
    ("object_mass", distributions.Exponential(1.0) * distributions.Normal(1.0, 0.3),
     "(-inf, inf)"),
    ("object_mass", distributions.Uniform(0.5, 1.5) / distributions.Uniform(0.0, 1.0),
     "(-inf, inf)"),
    # 1 / a range below an open 0 (-0.0 or 0.0 alike) is below 0: here above -inf, to 1.
    ("gripper_gain", 1.0 + 1.0 / (0.0 - distributions.LogNormal(3.2, 1.0)), "(-inf, 1)"),
    ("object_mass", distributions.UniformChoice(1000) / 100, "[0, 9.99]"),  # 0 to 999.
])
def test_a_distribution_that_can_draw_outside_its_parameters_range_is_refused_at_once(
        parameter, distribution, drawn, monkeypatch):
    import franka_composer.suite

    monkeypatch.setattr(franka_composer.suite, "build_task",
                        lambda *args, **kwargs: pytest.fail("a task was built"))
    with pytest.raises(ValueError, match=re.escape(f"draws in {drawn}: refused now, not at "
                                                   "the first reset that draws outside")):
        _make(randomization={parameter: distribution})


@pytest.mark.parametrize("parameter, distribution", [
    ("object_mass", distributions.LogNormal(0.0, 0.2)),
    ("object_mass", noises.Multiplicative(distributions.Uniform(0.8, 1.2))),
    ("controller_gain", distributions.Uniform(0.5, 1.5) / distributions.Uniform(1.0, 2.0)),
    ("joint_damping", -distributions.Uniform(-1.5, -0.5)),
    ("observation_delay", distributions.UniformInteger(0, 51)),
    ("observation_delay", distributions.UniformInteger(51)),  # 0 to 50.
    # Above 0 however scaled: LogNormal's 0 is never drawn.
    ("object_mass", 0.5 * distributions.LogNormal(0.0, 0.1)),
    ("object_mass", distributions.LogNormal(0.0, 0.1) / 2),
    ("object_mass", 1.0 / distributions.LogNormal(0.0, 0.1)),
    ("object_mass", distributions.Uniform(0.5, 1.5) * distributions.LogNormal(0.0, 0.1)),
    ("object_mass", noises.Multiplicative(distributions.LogNormal(0.0, 0.1)) * 0.5),
    ("object_mass", distributions.LogNormal(0.0, 0.1) * distributions.LogNormal(0.0, 0.1)),
    ("object_mass", 0.5 / -(0.0 - distributions.LogNormal(0.0, 0.1))),
    ("observation_delay", distributions.UniformChoice(51)),  # 0 to 50.
])
def test_a_distribution_bounded_within_its_parameters_range_is_accepted(parameter,
                                                                       distribution):
    """Taken, and drawn at each reset within the range: a factor above 0, a delay a
    whole number of steps from 0 to 50."""
    env = _make(randomization={parameter: distribution})
    draws = np.concatenate([np.ravel(env.reset(seed=seed)[1]["randomization"][parameter])
                            for seed in range(20)])
    env.close()
    if PARAMETERS[parameter].kind == "steps":
        assert np.all((draws >= 0) & (draws <= MAX_DELAY) & (draws == np.round(draws)))
    else:
        assert np.all(draws > 0) and np.all(np.isfinite(draws))
    assert np.ptp(draws) > 0  # Drawn anew each episode, not one value.


@pytest.mark.parametrize("value, message", [
    ("defaults", "unknown randomization 'defaults'; valid randomizations: None or a mapping, "
                 "default"),
    ({"object_weight": 1.0}, "unknown randomization parameter(s) 'object_weight'; valid "
                             "randomization parameters: action_noise, angle_noise"),
    ({"object_mass": "heavy"}, "'object_mass' must be a composer.variation distribution"),
    ({"object_mass": distributions.Uniform(-1.0, 1.0)},
     "'object_mass' is a factor and must draw > 0"),
    ({"object_rgb": distributions.Uniform(0.0, 2.0)},
     "'object_rgb' is a colour and must draw numbers in [0, 1]"),
    ({"observation_delay": distributions.Uniform(0.0, 2.0)},
     "'observation_delay' must draw a whole number of control steps in [0, 50]"),
    ({"camera_position": 0.01}, "'camera_position' must draw 3 finite numbers"),
    ({"position_noise": float("nan")}, "'position_noise' is noise added to each reading"),
    # A fixed number of components: a finger width is one number, a quaternion four.
    ({"position_noise": [0.1, 0.2, 0.3]}, "'position_noise' is noise added to each reading, "
                                          "one finite number per component (a distribution "
                                          "without a size, or one number): added to a "
                                          "reading of 1 number(s), it makes 3"),
    ({"action_noise": [0.1] * 5}, "'action_noise' is noise added to each reading, one "
                                  "finite number per component"),

    # A distribution that cannot draw at all (numpy's own errors name no parameter).
    ({"position_noise": distributions.Normal(0.0, -1.0)},
     "randomization 'position_noise' cannot draw from Normal(args=(), kwargs={'loc': 0.0, "
     "'scale': -1.0}, single_sample=False): ValueError: scale < 0"),
    ({"controller_gain": distributions.Uniform(float("nan"), 1.0)},
     "randomization 'controller_gain' cannot draw from Uniform("),
    ({"light_direction": distributions.Uniform(0.0, float("inf"))},
     "randomization 'light_direction' cannot draw from Uniform("),
    ({"observation_delay": distributions.UniformInteger(3, 1)},
     "randomization 'observation_delay' cannot draw from UniformInteger("),
    (3, "randomization must be None, a preset (default) or a mapping"),
])
def test_bad_randomisations_are_refused_before_anything_is_built(value, message, monkeypatch):
    import franka_composer.suite

    monkeypatch.setattr(franka_composer.suite, "build_task",
                        lambda *args, **kwargs: pytest.fail("a task was built"))
    with pytest.raises(ValueError) as error:
        _make(randomization=value)
    assert message in str(error.value)


@pytest.mark.parametrize("task, options, message", [
    ("reach", dict(randomization={"object_mass": 2.0}),
     "randomization 'object_mass' does nothing here: reach has no object: leave it out"),
    ("reach", dict(randomization={"object_rgb": (1.0, 0.0, 0.0)}),
     "randomization 'object_rgb' does nothing here: reach has no object"),
    # It scales the objects' contacts with the floor (the hand's keep theirs).
    ("reach", dict(randomization={"floor_friction": 0.7}),
     "randomization 'floor_friction' does nothing here: reach has no object: leave it out"),
    ("push", dict(randomization={"camera_position": (0.01, 0.0, 0.0)}),
     "randomization 'camera_position' does nothing here: no camera's images are observed "
     "(observation_mode 'state'): leave it out"),
    ("push", dict(randomization={"camera_rotation": 0.05}),
     "randomization 'camera_rotation' does nothing here: no camera's images are observed"),
])
def test_a_custom_randomisation_of_what_the_env_does_not_have_is_refused(task, options,
                                                                        message):
    """It was taken and reported as drawn (reach's object_mass as ()), and did nothing. The
    same mapping where it applies is taken, and a preset gives what applies where it is
    used."""
    with pytest.raises(ValueError, match=re.escape(message)):
        franka_composer.load(task, **options)
    where = dict(observation_mode="pixels") if task == "push" else {}
    franka_composer.load("push" if task == "reach" else task, **options, **where).close()
    franka_composer.load(task, randomization="default").close()
    # A mapping built on the preset (the guide's first example) applies its entries where
    # it can, as the preset does; the ones the user gives are checked.
    from franka_composer.randomization import PRESETS

    franka_composer.load(task, randomization={**PRESETS["default"], "observation_delay": 2})
    with pytest.raises(ValueError, match=re.escape(message)):
        franka_composer.load(task, randomization={**PRESETS["default"], **options["randomization"]})


def test_reach_reports_no_draw_of_what_acts_on_objects_under_the_preset():
    """The floor's friction scales its contacts with the objects alone: reach has none."""
    env = franka_composer.load("reach", seed=0, randomization="default")
    env.reset()
    drawn = env.task.randomization
    assert "joint_damping" in drawn and not {"floor_friction", "object_friction",
                                             "object_mass", "object_rgb"} & set(drawn)


@pytest.mark.parametrize("name", ["object_rgb", "floor_tint", "robot_tint",
                                  "light_direction", "light_intensity"])
def test_visual_randomisation_where_no_image_shows_it_is_refused(name):
    """A Gymnasium env without render_mode observing the state alone draws no image: its
    colours and lights were drawn each episode, reported in info, and shown nowhere. Where
    frames or camera images show them, and in dm_env (whose physics renders), they are
    taken; a preset gives them where it is used."""
    visual = {name: distributions.Uniform(0.9, 1.0)}
    with pytest.raises(ValueError, match="^" + re.escape(
            f"randomization {name!r} does nothing here: it changes what images show, and "
            "render_mode=None with observation_mode='state' has none: give render_mode="
            "'rgb_array' or 'human', or observation_mode='pixels' or 'state+pixels', or "
            "leave it out") + "$"):
        _make(randomization={**PRESETS["default"], "object_mass": 2.0, **visual})
    for shown in (dict(render_mode="rgb_array"), dict(observation_mode="pixels")):
        _make(randomization=visual, **shown).close()
    franka_composer.load("push", randomization=visual).close()
    _make(randomization="default").close()
    _make(randomization={**PRESETS["default"], "object_mass": 2.0}).close()


@pytest.mark.parametrize("name", ["position_noise", "angle_noise", "velocity_noise"])
def test_sensing_noise_without_a_state_vector_is_refused(name):
    """observation_mode='pixels' observes no state vector, and the noise (added to its
    readings) was taken, reported nowhere and did nothing: the observations were those of
    an env without it, bit for bit. Where a state vector is observed it is taken; the
    preset leaves it out there."""
    noisy = {name: distributions.Normal(0.0, 0.01)}
    with pytest.raises(ValueError, match="^" + re.escape(
            f"randomization {name!r} does nothing here: no state vector is observed "
            "(observation_mode 'pixels'), and the noise is added to its readings, not to "
            "images: leave it out") + "$"):
        franka_composer.load("push", observation_mode="pixels", randomization=noisy)
    franka_composer.load("push", observation_mode="state+pixels", randomization=noisy).close()
    franka_composer.load("push", observation_mode="pixels", randomization="default").close()


def test_a_light_intensity_past_float32_is_a_value_error_naming_it():
    """MuJoCo keeps a light's colour in float32: a factor of 1e39 wrote inf there (numpy's
    overflow warning the only sign)."""
    env = _make(render_mode="rgb_array", randomization={"light_intensity": 1e39})
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Not numpy's overflow warning on the way.
        with pytest.raises(ValueError, match=re.escape(
                "randomization 'light_intensity' drew a factor of 1e+39, which makes a "
                "light's colour infinite in MuJoCo's float32: bound it")):
            env.reset(seed=0)
