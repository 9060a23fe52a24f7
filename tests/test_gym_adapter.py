"""The Gymnasium adapter over every registered id: checkers, goal contract, seeding,
pickling, rendering, vector envs, Shimmy, bad input, and a short SAC + HER run."""

from __future__ import annotations

import copy
import pickle
import re

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from franka_composer.adapters.registration import env_id
from conftest import (SPEC, UNBOUNDED_OBSERVATIONS, check_reward_contract,
                      env_checker_findings, her_samples, near_goal_pairs, spec_distance)

ALL_IDS = tuple(franka_composer.ENV_IDS)


@pytest.fixture(params=ALL_IDS)
def env_name(request) -> str:
    return request.param


def _random_rollout(env, seed: int, steps: int):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    records = []
    for _ in range(steps):
        action = env.action_space.sample()
        next_obs, reward, terminated, truncated, info = env.step(action)
        records.append((next_obs, reward, terminated, truncated, info))
        if terminated or truncated:
            next_obs, _ = env.reset()
    return obs, records


def test_every_task_is_registered_under_every_controller_with_its_episode_length():
    tasks = {"Push": "push", "Slide": "slide", "PickAndPlace": "pick_and_place",
             "Reach": "reach", "Stack": "stack", "Flip": "flip"}
    # The Joints ids one version up: the surface guard acts under joints since 0.4.0.
    assert set(ALL_IDS) == {f"Franka{t}{c}{r}-v{SPEC[task].get('version', 0) + (c == 'Joints')}"
                            for t, task in tasks.items()
                            for c in ("", "Osc", "Joints") for r in ("Sparse", "Dense")}
    for id_, registered in franka_composer.ENV_IDS.items():
        assert gym.spec(id_).max_episode_steps == SPEC[registered.task]["steps"]
        env = gym.make(id_)
        assert env.unwrapped.task.config.control.kind == registered.control
    assert env_id("pick_and_place", "dense") == "FrankaPickAndPlaceDense-v0"
    assert env_id("stack", "sparse", "osc") == "FrankaStackOscSparse-v1"
    assert env_id("stack", "dense", "joints") == "FrankaStackJointsDense-v2"
    assert env_id("flip", "dense", "osc") == "FrankaFlipOscDense-v1"
    assert env_id("push", "sparse", "joints") == "FrankaPushJointsSparse-v1"
    assert env_id("flip", "sparse", "joints") == "FrankaFlipJointsSparse-v2"


def test_no_option_makes_another_ids_env_under_an_id():
    """The id was among the spec's kwargs, so an option could replace it: a stack env under
    push's id, with push's time limit. Specs recorded then (a Minari dataset's) still make
    their env."""
    with pytest.raises(ValueError, match=re.escape(
            "registered_id is not an option of the Gymnasium env: the id "
            "(FrankaPushSparse-v0) is")):
        gym.make("FrankaPushSparse-v0", registered_id="FrankaStackSparse-v1", task="stack")
    assert "registered_id" not in gym.spec("FrankaPushSparse-v0").kwargs
    recorded = copy.deepcopy(gym.spec("FrankaStackOscDense-v1"))  # As registered before.
    recorded.entry_point = "franka_composer.adapters.registration:make_registered"
    recorded.kwargs = {"registered_id": recorded.id, **recorded.kwargs}
    env = gym.make(recorded)
    assert (env.unwrapped.task_name, env.unwrapped.task.config.control.kind,
            env.spec.max_episode_steps) == ("stack", "osc", SPEC["stack"]["steps"])


@pytest.mark.parametrize("old, new", [
    ("FrankaFlipSparse-v0", "FrankaFlipSparse-v1"),  # Flip's goals changed in v1.
    ("FrankaPushJointsSparse-v0", "FrankaPushJointsSparse-v1"),  # The guard under joints.
    ("FrankaFlipJointsDense-v1", "FrankaFlipJointsDense-v2"),
    ("FrankaStackSparse-v0", "FrankaStackSparse-v1"),  # The guard and carried blocks.
    ("FrankaStackJointsSparse-v1", "FrankaStackJointsSparse-v2"),
])
def test_replaced_ids_point_to_their_successor(old, new):
    """Gymnasium names the new id for the old one."""
    with pytest.raises(gym.error.DeprecatedEnv, match=f"Please use `{new}`"):
        gym.make(old)


def test_spaces_match_the_spec(env_name):
    env = gym.make(env_name)
    registered = franka_composer.ENV_IDS[env_name]
    spec = SPEC[registered.task]
    # Joint control: 7 joint-angle deltas instead of dx, dy, dz, and the 7 angles observed.
    joints = 4 if registered.control == "joints" else 0
    assert env.observation_space["observation"].shape == (spec["observation"] + 7 * bool(joints),)
    assert env.observation_space["achieved_goal"].shape == (spec["goal"],)
    assert env.observation_space["desired_goal"].shape == (spec["goal"],)
    assert {s.dtype for s in env.observation_space.spaces.values()} == {np.dtype(np.float64)}
    assert env.action_space == gym.spaces.Box(-1, 1, (spec["action"] + joints,), np.float32)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert isinstance(info["is_success"], bool)


def test_gymnasium_and_sb3_env_checkers_pass(env_name):
    assert env_checker_findings(gym.make(env_name), sb3=True) == UNBOUNDED_OBSERVATIONS


def test_step_reward_equals_compute_reward_and_success_matches_distance(env_name):
    check_reward_contract(env_name)


def test_batched_compute_reward_equals_per_pair_values(env_name):
    task = franka_composer.ENV_IDS[env_name].task
    env = gym.make(env_name).unwrapped
    achieved, desired = near_goal_pairs(task, np.random.default_rng(0), 1000)
    size = SPEC[task]["goal"]
    batched = env.compute_reward(achieved, desired, [{}] * 1000)
    assert batched.shape == (1000,)
    singles = np.array([env.compute_reward(a, d, {}) for a, d in zip(achieved, desired)])
    np.testing.assert_array_equal(batched, singles)
    np.testing.assert_array_equal(env.compute_reward(achieved, desired, None), batched)
    np.testing.assert_array_equal(
        env.compute_reward(achieved.reshape(10, 100, size), desired.reshape(10, 100, size),
                           np.array([{}] * 1000).reshape(10, 100)),
        batched.reshape(10, 100))
    if "Sparse" in env_name:
        assert 0 < np.mean(batched == 0) < 1  # Both outcomes occur in the batch.
        np.testing.assert_array_equal(
            batched == 0, spec_distance(task, achieved, desired) < SPEC[task]["threshold"])


def test_task_options_pass_through_gym_make():
    env = gym.make("FrankaPushSparse-v0", terminate_on_success=False, distance_threshold=0.03)
    assert env.unwrapped.task.distance_threshold == 0.03
    assert not env.unwrapped.task.terminate_on_success
    achieved = np.zeros(3)
    assert env.unwrapped.compute_reward(achieved, achieved + [0.04, 0, 0], {}) == -1.0


def test_terminate_on_success_is_the_paper_default():
    env = gym.make("FrankaPushSparse-v0", distance_threshold=1.0)  # Solved from the start.
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step(np.zeros(3, np.float32))
    assert terminated and not truncated and info["is_success"] and reward == 0.0
    assert env.unwrapped.compute_terminated(np.zeros(3), np.zeros(3), {})


def test_same_seed_same_trajectory_and_reset_without_seed_continues(env_name):
    first_obs, first = _random_rollout(gym.make(env_name), seed=3, steps=30)
    second_obs, second = _random_rollout(gym.make(env_name), seed=3, steps=30)
    for key in first_obs:
        np.testing.assert_array_equal(first_obs[key], second_obs[key])
    for a, b in zip(first, second):
        for key in a[0]:
            np.testing.assert_array_equal(a[0][key], b[0][key])
        assert a[1:4] == b[1:4]
    env = gym.make(env_name)
    goals = [env.reset(seed=9)[0]["desired_goal"]] + [env.reset()[0]["desired_goal"]
                                                      for _ in range(3)]
    assert len({tuple(g) for g in goals}) == 4
    np.testing.assert_array_equal(env.reset(seed=9)[0]["desired_goal"], goals[0])


def test_pickled_env_rebuilds_into_an_equivalent_env(env_name):
    env = gym.make(env_name, terminate_on_success=False)
    clone = pickle.loads(pickle.dumps(env))
    a, b = env.reset(seed=5)[0], clone.reset(seed=5)[0]
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    action = env.action_space.sample()
    np.testing.assert_array_equal(env.step(action)[0]["observation"],
                                  clone.step(action)[0]["observation"])
    assert clone.unwrapped.task.terminate_on_success is False


def test_a_copy_keeps_its_spec_so_gym_make_rebuilds_it():
    """Gymnasium's pickling rebuilds from the constructor's arguments, which leaves the
    registry's spec (id, options, time limit) behind; a copy keeps it."""
    env = gym.make("FrankaSlideDense-v0", terminate_on_success=False, max_episode_steps=7)
    for clone in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        assert clone.spec == env.spec and clone.spec.id == "FrankaSlideDense-v0"
        remade = gym.make(clone.spec)
        remade.reset(seed=0)
        steps = 1
        while not remade.step(np.zeros(remade.action_space.shape))[3]:
            steps += 1
        assert steps == 7 and remade.unwrapped.task.terminate_on_success is False


def test_an_env_registered_with_a_lambda_still_pickles_without_its_spec():
    """Its spec's entry point does not pickle; the env, rebuilt from its arguments, does."""
    from franka_composer.adapters.goal_env import FrankaGoalEnv

    gym.register("TestLambdaReach-v0", max_episode_steps=5,
                 entry_point=lambda **kwargs: FrankaGoalEnv(task="reach", **kwargs))
    try:
        env = gym.make("TestLambdaReach-v0")
        clone = pickle.loads(pickle.dumps(env))
        assert clone.unwrapped.spec is None and clone.unwrapped.task_name == "reach"
        np.testing.assert_array_equal(clone.reset(seed=3)[0]["desired_goal"],
                                      env.reset(seed=3)[0]["desired_goal"])
    finally:
        gym.registry.pop("TestLambdaReach-v0")


@pytest.mark.parametrize("control", ["mocap", "osc", "joints"])
def test_rgb_array_frames_have_the_requested_size_and_show_the_goal(task_name, control):
    id_ = env_id(task_name, "sparse", control)
    env = gym.make(id_, render_mode="rgb_array", width=320, height=240)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # Not blank.
    physics = env.unwrapped.composer_env.physics
    for site in env.unwrapped.task.goal_marker.mjcf_model.find_all("site"):
        physics.bind(site).rgba = (0, 0, 0, 0)  # Hide the goal marker.
    hidden = env.render()
    changed = np.any(frame != hidden, axis=-1)
    assert changed.sum() > 20  # The goal marker is visible.
    env.close()
    env.close()  # Closing twice is harmless.


@pytest.mark.parametrize("control_timestep, fps", [(0.05, 20), (0.5, 2), (0.3, 1 / 0.3),
                                                   (2.0, 0.5)])
def test_render_fps_is_one_frame_per_step(control_timestep, fps):
    """Rounded to a whole number it read 0 at 2 s per step (videos of 0 frames/s)."""
    env = gym.make("FrankaPushSparse-v0", control_timestep=control_timestep)
    assert env.metadata["render_fps"] == fps and env.metadata["render_fps"] * env.unwrapped.dt \
        == pytest.approx(1.0, rel=1e-12)
    assert type(env.metadata["render_fps"]) is (int if fps == round(fps) else float)
    env.close()


def test_rgb_array_list_collects_the_frames_as_for_any_gymnasium_env():
    """gym.make wraps RenderCollection around an env whose entry point lists its render
    modes; the function entry point listed none, and the mode was refused."""
    from gymnasium.wrappers import RenderCollection

    env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array_list", width=48, height=32)
    assert isinstance(env, RenderCollection) and env.unwrapped.render_mode == "rgb_array"
    env.reset(seed=0)
    env.step(np.zeros(3, np.float32))
    env.step(np.zeros(3, np.float32))
    frames = env.render()
    assert [frame.shape for frame in frames] == [(32, 48, 3)] * 3  # The reset's, two steps'.
    env.close()


def test_bad_render_arguments_raise_clear_errors():
    with pytest.raises(ValueError, match="unknown render_mode 'video'"):
        gym.make("FrankaPushSparse-v0", render_mode="video").unwrapped
    with pytest.raises(ValueError, match="width must be >= 1 and <= 1024, got 4096"):
        gym.make("FrankaPushSparse-v0", render_mode="rgb_array", width=4096)


def test_bad_actions_and_options_raise_clear_errors():
    env = gym.make("FrankaPickAndPlaceSparse-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must have shape \(4,\)"):
        env.step(np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="action must be finite"):
        env.step(np.array([0, 0, np.nan, 0], np.float32))
    with pytest.raises(ValueError, match="unknown task option.*'threshold'"):
        gym.make("FrankaPushSparse-v0", threshold=0.1)


@pytest.mark.parametrize("typo", ["time_limt", "render_mod", "widht", "max_episode_step"])
def test_a_misspelt_argument_of_the_env_is_listed_among_its_own(typo):
    """`gym.make` takes its own arguments, the env's rendering arguments and `time_limit`
    beside the task options (not `load`'s seed or renderable, which the adapter sets): a
    misspelling lists them, and the env made from its class lists its own. What the id
    fixes (task, reward type, an Osc or Joints id's controller) is not listed."""
    with pytest.raises(ValueError, match=rf"unknown task option\(s\) '{typo}'; valid task "
                                         r"options: [^;]*; gym.make's own arguments: camera, "
                                         r"disable_env_checker, height, max_episode_steps, "
                                         r"render_mode, time_limit, width$"):
        gym.make("FrankaPushSparse-v0", **{typo: 1})
    for id_, fixed in [("FrankaPushSparse-v0", ("task", "reward_type")),
                       ("FrankaPushOscSparse-v0", ("task", "reward_type", "control"))]:
        with pytest.raises(ValueError) as error:
            gym.make(id_, **{typo: 1})
        listed = re.split(r"[:;,] ", str(error.value))
        assert [name for name in fixed if name in listed] == []
        assert ("control" in listed) == (id_ == "FrankaPushSparse-v0")
    from franka_composer.adapters.goal_env import FrankaGoalEnv

    with pytest.raises(ValueError, match=rf"unknown task option\(s\) '{typo}'; valid task "
                                         r"options: [^;]*; the env's own arguments: camera, "
                                         r"height, render_mode, task, time_limit, width$"):
        FrankaGoalEnv("push", **{typo: 1})


def test_step_before_reset_raises_gymnasiums_error():
    env = gym.make("FrankaPushSparse-v0")
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(3, np.float32))
    with pytest.raises(gym.error.ResetNeeded, match=r"^Cannot call env.step\(\) before calling "
                                                    r"env.reset\(\)$"):
        env.unwrapped.step(np.zeros(3, np.float32))


def test_a_step_after_a_reset_that_raised_is_refused_until_a_reset_succeeds():
    """A mass factor drawn too light is refused at its reset; the next step went on from
    what the failed reset left: the arm at the model's qpos0 (pointing up), the block
    inside the robot's base and rising, the last episode's goal and draws."""
    from dm_control.composer.variation import distributions

    env = gym.make("FrankaPushSparse-v0",
                   randomization={"object_mass": distributions.LogNormal(0, 5)})
    env.reset(seed=0)
    env.step(np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="lighter than any body compiles"):
        env.reset(seed=110)
    message = ("^" + re.escape("Cannot call env.step() before calling env.reset(): the last "
                               "reset() raised, and left no episode to step") + "$")
    for _ in range(2):
        with pytest.raises(gym.error.ResetNeeded, match=message):
            env.unwrapped.step(np.zeros(3, np.float32))
    first, _ = env.reset(seed=0)
    again = gym.make("FrankaPushSparse-v0",
                     randomization={"object_mass": distributions.LogNormal(0, 5)})
    np.testing.assert_equal(first, again.reset(seed=0)[0])  # Bit for bit.
    env.unwrapped.step(np.zeros(3, np.float32))
    # dm_env, mid-episode: its next step resets (as after a LAST step) and starts an
    # episode with the arm at its neutral pose; it stepped on from the failed reset's state.
    with pytest.raises(ValueError, match="lighter than any body compiles"):
        env.reset(seed=110)
    composer_env = env.unwrapped.composer_env
    timestep = composer_env.step(np.zeros(3))
    assert timestep.first()
    np.testing.assert_allclose(timestep.observation["panda/tcp_position"], first["observation"][:3],
                               atol=0.02)  # Any episode's start: the hand over the floor.


@pytest.mark.slow
@pytest.mark.parametrize("control, size", [("mocap", 18), ("osc", 18), ("joints", 25)])
def test_async_vector_env_with_two_workers_steps(control, size):
    envs = gym.vector.AsyncVectorEnv([lambda: gym.make(env_id("push", "sparse", control))] * 2)
    try:
        obs, _ = envs.reset(seed=[0, 1])
        assert obs["observation"].shape == (2, size)
        assert not np.array_equal(obs["desired_goal"][0], obs["desired_goal"][1])
        for _ in range(5):
            obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
        assert reward.shape == (2,) and obs["achieved_goal"].shape == (2, 3)
    finally:
        envs.close()


@pytest.mark.slow
def test_sb3_subproc_vec_env_with_two_workers_steps():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # Workers are fresh processes: the "module:id" form imports franka_composer there.
    venv = make_vec_env("franka_composer:FrankaSlideSparse-v0", n_envs=2, seed=0,
                        vec_env_cls=SubprocVecEnv)
    try:
        obs = venv.reset()
        assert obs["observation"].shape == (2, 18)
        obs, reward, done, info = venv.step(np.zeros((2, 3), np.float32))
        assert reward.shape == (2,) and len(info) == 2
        rewards = venv.env_method("compute_reward", obs["achieved_goal"], obs["desired_goal"],
                                  info, indices=[0])[0]
        np.testing.assert_array_equal(rewards, reward)
    finally:
        venv.close()


def test_shimmy_wraps_the_dm_env_suite_for_raw_dict_observations():
    from shimmy import DmControlCompatibilityV0

    env = DmControlCompatibilityV0(franka_composer.load("push", seed=0))
    obs, _ = env.reset(seed=0)
    assert set(obs) >= {"panda/tcp_position", "block/position", "goal"}
    obs, reward, terminated, truncated, _ = env.step(np.zeros(3, np.float32))
    assert obs["block/position"].shape == (3,) and reward in (0.0, -1.0)
    env.close()


@pytest.mark.slow
def test_short_sac_her_run_learns_without_error(task_name):
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make(env_id(task_name, "sparse"))
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
                learning_starts=100, batch_size=64, buffer_size=2000, seed=0,
                policy_kwargs=dict(net_arch=[32, 32]), device="cpu")
    model.learn(total_timesteps=250)
    assert model.num_timesteps == 250
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert env.action_space.contains(action)


def test_an_env_that_never_renders_simulates_what_a_rendering_env_does(task_name):
    """render_mode=None leaves the Panda's visual meshes out (~50 MB less per env); they have
    no mass and no contacts, so both envs give the same trajectories, bit for bit."""
    from franka_composer.policies import make_expert

    id_ = env_id(task_name, "sparse")
    lean = gym.make(id_, terminate_on_success=False)
    full = gym.make(id_, render_mode="rgb_array", terminate_on_success=False)
    lean_model = lean.unwrapped.composer_env.physics.model
    full_model = full.unwrapped.composer_env.physics.model
    assert (lean_model.geom_group == 2).sum() == 0 < (full_model.geom_group == 2).sum()
    expert = make_expert(lean)
    rng = np.random.default_rng(0)
    for episode in range(2):
        expert.reset()
        a, b = lean.reset(seed=episode)[0], full.reset(seed=episode)[0]
        for _ in range(50):
            action = expert(a) if episode == 0 else rng.uniform(-1, 1, lean.action_space.shape)
            a, reward_a, *_ = lean.step(np.asarray(action, np.float32))
            b, reward_b, *_ = full.step(np.asarray(action, np.float32))
            for key in a:
                np.testing.assert_array_equal(a[key], b[key])
            assert reward_a == reward_b


def test_rendering_from_another_thread_is_refused_clearly():
    import threading

    env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array", width=64, height=64)
    env.reset(seed=0)
    assert env.render().shape == (64, 64, 3)
    errors = []
    thread = threading.Thread(target=lambda: errors.append(_render_error(env)))
    thread.start()
    thread.join()
    assert errors[0].startswith("this environment renders on thread 'MainThread', which "
                                "rendered it first")
    assert env.render().shape == (64, 64, 3)  # The first thread still renders.
    env.close()


def _render_error(env) -> str:
    try:
        env.render()
    except RuntimeError as error:
        return str(error)
    return "no error"


def test_her_relabelled_rewards_are_exact(task_name):
    """SB3's HerReplayBuffer relabels with `compute_reward` (a quaternion goal for flip, six
    coordinates for stack): every sampled reward is the task's reward for its goals, and
    the relabelling does produce goals that the original episodes missed."""
    env = gym.make(env_id(task_name, "sparse"), terminate_on_success=False)
    achieved, desired, rewards = her_samples(env, 4 * SPEC[task_name]["steps"])
    np.testing.assert_array_equal(
        rewards, env.unwrapped.compute_reward(achieved, desired, None).astype(np.float32))
    successes = spec_distance(task_name, achieved, desired) < SPEC[task_name]["threshold"]
    np.testing.assert_array_equal(rewards == 0, successes)
    assert successes.mean() > 0.1  # Relabelled goals are reached (measured: 18-80 %).


def test_the_episode_stream_continues_after_an_episode_ends_on_success():
    """Which episode an unseeded reset starts depends on the seed and the number of resets,
    not on how the episodes before it ended (evaluations of a resumed training run rely on
    it): one env's episode ends on success, the other's is cut short before."""
    from franka_composer.policies import make_expert

    starts = []
    for finish in (True, False):
        env = gym.make("FrankaReachSparse-v0")
        obs, _ = env.reset(seed=5)
        expert = make_expert(env)
        if finish:
            terminated = False
            while not terminated:
                obs, _, terminated, _, info = env.step(expert(obs))
            assert info["is_success"]
        else:
            env.step(np.zeros(3, np.float32))
        starts.append([env.reset()[0]["desired_goal"] for _ in range(3)])
        env.close()
    np.testing.assert_array_equal(starts[0], starts[1])
