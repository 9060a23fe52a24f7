"""Bad input gets one clear error naming what was wrong, before anything reaches MuJoCo:
task options, rendering arguments, actions, reset options, ids, closed environments."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from franka_composer.environment import EnvironmentClosedError
from franka_composer.tasks import PhysicsSettings

NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("option, value, message", [
    ("terminate_on_success", "no", "terminate_on_success must be True or False, got 'no'"),
    ("actuated_gripper", 1, "actuated_gripper must be True or False, got 1"),
    ("goal_centre", (0.6,), r"goal_centre must have 2 number\(s\), got 1"),
    ("object_centre", "0.6", "object_centre must be a sequence of 2 numbers"),
    ("max_tcp_step", -1, "max_tcp_step must be > 0, got -1"),
    ("max_tcp_step", INF, "max_tcp_step must be a finite number > 0, got inf"),
    ("max_finger_step", NAN, "max_finger_step must be a finite number > 0, got nan"),
    ("neutral_arm_qpos", (NAN,) * 7, r"neutral_arm_qpos\[0\] must be a finite number"),
    ("neutral_arm_qpos", (0.0,) * 6, r"neutral_arm_qpos must have 7 number\(s\)"),
    ("neutral_arm_qpos", (0, 3.0, 0, -1.85, 0, 2.26, 0.79),
     r"neutral_arm_qpos\[1\] = 3.0 is outside joint2's range \[-1.7628, 1.7628\] rad"),
    ("object_friction", -0.5, "object_friction must be >= 0, got -0.5"),
    ("floor_friction", -1, "floor_friction must be >= 0, got -1"),
    ("object_mass", 0, "object_mass must be > 0, got 0"),
    ("block_half_size", 0.0, "block_half_size must be > 0, got 0.0"),
    ("block_half_size", (0.02,), "block_half_size must be a finite number > 0, got"),
    ("puck_radius", 0.03, "puck_radius does not apply to push: its objects are blocks "
                          r"\(its object options: object_mass, object_friction, "
                          r"block_half_size\)"),
    ("object_range", (-0.1, 0.3), r"object_range\[0\] must be >= 0, got -0.1"),
    ("goal_max_height", -0.2, "goal_max_height must be >= 0"),
    ("goal_in_air_probability", 1.5, "goal_in_air_probability must be >= 0 and <= 1, got 1.5"),
    ("control_timestep", 0, "control_timestep must be > 0, got 0"),
    ("control_timestep", -0.05, "control_timestep must be > 0, got -0.05"),
    ("control_timestep", 0.051, "control_timestep must be a whole multiple of the physics "
                                r"timestep \(0.002 s\), got 0.051"),
    ("distance_threshold", "0.05", "distance_threshold must be a finite number > 0, got '0.05'"),
    ("distance_threshold", True, "distance_threshold must be a finite number > 0, got True"),
    ("reward_type", "shaped", "unknown reward_type 'shaped'; valid reward_types: sparse, dense"),
    ("physics", None, "physics must be a PhysicsSettings record, got None"),
])
def test_a_bad_task_option_names_itself_and_what_it_accepts(option, value, message):
    with pytest.raises(ValueError, match=message):
        franka_composer.load("push", **{option: value})
    if option != "reward_type":  # A Gymnasium id fixes its reward type.
        with pytest.raises(ValueError, match=message):
            gym.make("FrankaPushSparse-v0", **{option: value})


@pytest.mark.parametrize("field, value, message", [
    ("timestep", 0.0, "physics.timestep must be > 0"),
    ("integrator", "verlet", "unknown physics.integrator 'verlet'"),
    ("cone", "round", "unknown physics.cone 'round'"),
    ("iterations", 0, "physics.iterations must be >= 1"),
    ("noslip_iterations", 2.5, "physics.noslip_iterations must be a whole number"),
])
def test_bad_physics_settings_are_refused(field, value, message):
    with pytest.raises(ValueError, match=message):
        PhysicsSettings(**{field: value})


def test_good_options_are_normalised_to_floats_and_tuples():
    env = franka_composer.load("push", goal_centre=[0.5, 0.1], distance_threshold=1)
    assert env.task.workspace.goal_box.centre == (0.5, 0.1)
    assert env.task.distance_threshold == 1.0


@pytest.mark.parametrize("options, message", [
    (dict(task="slide", reward_type="dense"),
     "FrankaPushSparse-v0 is the sparse push task: its task and reward_type cannot be "
     "changed; use 'FrankaSlideDense-v0'"),
    (dict(reward_type="dense"), "use 'FrankaPushDense-v0'"),
    (dict(task="lift"), "its task and reward_type cannot be changed$"),
    (dict(camera="nope"), "unknown camera 'nope'; valid cameras: workspace, top"),
    (dict(width=True), r"width must be an int in \[1, 1024\], got True"),
    (dict(height=0), r"height must be an int in \[1, 1024\], got 0"),
    (dict(render_mode="video"), "unknown render_mode 'video'; valid render_modes: None, "
                                "human, rgb_array"),
])
def test_bad_make_arguments_are_refused_at_construction(options, message):
    with pytest.raises(ValueError, match=message):
        gym.make("FrankaPushSparse-v0", **options).unwrapped


def test_an_id_that_names_a_controller_keeps_it_and_a_plain_id_takes_any():
    with pytest.raises(ValueError, match="FrankaPushOscSparse-v0 is the sparse push task, "
                                         "under osc control: its task, reward_type and "
                                         "control cannot be changed; use "
                                         "'FrankaPushJointsSparse-v0'"):
        gym.make("FrankaPushOscSparse-v0", control="joints")
    with pytest.raises(ValueError, match="unknown control 'torque'; valid controls: mocap, "
                                         "osc, joints"):
        gym.make("FrankaPushSparse-v0", control="torque")
    assert gym.make("FrankaPushSparse-v0", control="osc").unwrapped.task.config.control.kind \
        == "osc"
    assert gym.make("FrankaPushOscSparse-v0", control="osc").unwrapped.task.config.control \
        .kind == "osc"


def test_human_rendering_without_a_display_raises_instead_of_aborting(monkeypatch):
    """GLFW aborts the whole process without a display; the env refuses first."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="render_mode='human' needs a display.*rgb_array"):
        gym.make("FrankaPushSparse-v0", render_mode="human")


@pytest.mark.parametrize("action, dtype", [
    (["0.1", "0.2", "0.3"], "<U3"),
    (np.array(["0.1", "0.2", "0.3"], dtype=object), "object"),
    (np.array([0.1, 0.2, 0.3], dtype=complex), "complex128"),
    ([True, False, True], "bool"),
])
def test_non_numeric_actions_are_refused(action, dtype):
    env = franka_composer.load("push", seed=0)
    env.reset()
    before = env.physics.data.time
    with pytest.raises(ValueError, match=f"action must be an array of real numbers .*got "
                                         f"dtype {dtype}"):
        env.step(action)
    assert env.physics.data.time == before
    env.step([0, 0, 1])  # Integers are real numbers.


def test_unknown_reset_options_are_refused_before_anything_changes():
    env = gym.make("FrankaPushSparse-v0")
    first = env.reset(seed=1)[0]
    with pytest.raises(ValueError, match="unknown reset option.*'goal'.*takes none"):
        env.reset(seed=5, options={"goal": [0.6, 0, 0.02]})
    np.testing.assert_array_equal(env.reset(seed=1)[0]["desired_goal"], first["desired_goal"])
    env.reset(options={})  # Empty options are no options.


def test_a_closed_gymnasium_env_says_so():
    env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array")
    env.reset(seed=0)
    env.close()
    env.close()  # Closing twice is harmless.
    for call in (env.reset, lambda: env.step(np.zeros(3, np.float32)), env.render):
        with pytest.raises(gym.error.ClosedEnvironmentError, match="closed: make a new one"):
            call()


def test_a_closed_dm_env_says_so():
    env = franka_composer.load("slide", seed=0)
    env.reset()
    env.close()
    env.close()
    for call in (env.reset, lambda: env.step(np.zeros(3)), lambda: env.physics):
        with pytest.raises(EnvironmentClosedError, match="closed"):
            call()


def test_a_pickled_or_copied_env_is_a_fresh_env_with_the_same_options():
    """What README promises: the options travel, the simulation state does not."""
    env = gym.make("FrankaPushSparse-v0", distance_threshold=0.03)
    env.reset(seed=4)
    for _ in range(5):
        env.step(np.ones(3, np.float32))
    for clone in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        assert clone.unwrapped.task.distance_threshold == 0.03
        with pytest.raises(gym.error.ResetNeeded):
            clone.unwrapped.step(np.zeros(3, np.float32))  # No episode came along.
        np.testing.assert_array_equal(clone.reset(seed=4)[0]["observation"],
                                      env.reset(seed=4)[0]["observation"])


def test_object_options_do_not_apply_to_reach():
    with pytest.raises(ValueError, match="object_mass does not apply to reach: it has no "
                                         r"object \(its object options: none\)"):
        franka_composer.load("reach", object_mass=1.0)


def test_an_object_option_sets_every_object():
    config = franka_composer.load("stack", object_mass=0.2).task.config
    assert [spec.mass for spec in config.objects] == [0.2, 0.2]
