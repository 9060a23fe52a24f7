"""Camera observations (`observation_mode`): Composer camera observables beside state goals,
so rewards and HER relabelling are unchanged (tasks/records.py ObservationSettings,
tasks/goal_task.py, adapters/goal_env.py)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from conftest import UNBOUNDED_OBSERVATIONS, env_checker_findings, move_tcp_to
from franka_composer.adapters.registration import env_id

MODES = {"pixels": {"achieved_goal", "desired_goal", "workspace_pixels"},
         "state+pixels": {"observation", "achieved_goal", "desired_goal", "workspace_pixels"}}


@pytest.mark.parametrize("mode", list(MODES))
def test_pixel_modes_give_uint8_images_beside_state_goals(task_name, mode):
    env = gym.make(env_id(task_name, "sparse"), observation_mode=mode,
                   terminate_on_success=False)
    state = gym.make(env_id(task_name, "sparse"), terminate_on_success=False)
    space = env.observation_space
    assert set(space.spaces) == MODES[mode]
    image = space["workspace_pixels"]
    assert (image.shape, image.dtype, image.low.min(), image.high.max()) == (
        (84, 84, 3), np.uint8, 0, 255)
    for key in ("achieved_goal", "desired_goal"):
        assert space[key] == state.observation_space[key]
    obs, _ = env.reset(seed=3)
    reference, _ = state.reset(seed=3)
    assert space.contains(obs)
    assert obs["workspace_pixels"].std() > 10  # An image, not a blank buffer.
    for _ in range(3):  # Same seed, same actions: the same goals and rewards as "state".
        action = env.action_space.sample()
        obs, reward, *_ = env.step(action)
        reference, reference_reward, *_ = state.step(action)
        for key in ("achieved_goal", "desired_goal", *(("observation",) if "state" in mode
                                                       else ())):
            np.testing.assert_array_equal(obs[key], reference[key])
        assert reward == reference_reward == env.unwrapped.compute_reward(
            obs["achieved_goal"], obs["desired_goal"], {})
    assert env_checker_findings(env) == UNBOUNDED_OBSERVATIONS
    env.close()
    state.close()


def test_cameras_and_image_size_are_options_and_dm_env_names_the_observables():
    env = franka_composer.load("pick_and_place", seed=0, observation_mode="pixels",
                               cameras=("wrist", "workspace"), pixel_height=48, pixel_width=64)
    timestep = env.reset()
    assert env.task.pixel_keys == ("wrist_pixels", "workspace_pixels")
    for key in env.task.pixel_keys:
        assert timestep.observation[key].shape == (48, 64, 3)
        assert timestep.observation[key].dtype == np.uint8
    # Pixels only: the state vector's observables are off; the goals are the task's own.
    assert set(timestep.observation) == {"wrist_pixels", "workspace_pixels", "achieved_goal",
                                         "goal"}
    assert franka_composer.load("push", observation_mode="pixels", cameras="wrist").task \
        .config.observations.cameras == ("wrist",)


def test_the_same_seed_gives_the_same_pixels():
    """Equal frames, each a picture (not blank) of the scene after the steps (not the
    reset's)."""
    frames, starts = [], []
    for _ in range(2):
        env = gym.make("FrankaPushSparse-v0", observation_mode="pixels",
                       cameras=("workspace", "wrist"))
        obs, _ = env.reset(seed=7)
        starts.append(obs)
        for _ in range(4):
            obs, *_ = env.step(np.array([0.5, -0.3, -0.2], np.float32))
        frames.append(obs)
        env.close()
    for key in ("workspace_pixels", "wrist_pixels"):
        np.testing.assert_array_equal(frames[0][key], frames[1][key])
        assert frames[0][key].std() > 10  # Measured: 30 (workspace), 63 (wrist).
        # The hand moved: measured a mean change of 7 and 13 levels a pixel.
        assert np.abs(frames[0][key].astype(int) - starts[0][key]).mean() > 1


def test_the_goal_marker_can_be_hidden_without_changing_the_simulation():
    runs = {}
    for visible in (True, False):
        env = gym.make("FrankaPushSparse-v0", observation_mode="state+pixels",
                       goal_marker_visible=visible, terminate_on_success=False)
        obs, _ = env.reset(seed=1)
        rng = np.random.default_rng(0)
        states = []
        for _ in range(5):
            obs, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            states.append(obs["observation"])
        runs[visible] = (np.array(states), obs["workspace_pixels"].astype(int))
        env.close()
    np.testing.assert_array_equal(runs[True][0], runs[False][0])
    changed = np.abs(runs[True][1] - runs[False][1]).sum(axis=-1) > 30
    # The 2 cm sphere, ~3 pixels across at 84 x 84 from the workspace camera: measured 7.
    assert 3 <= changed.sum() <= 50
    red = runs[True][1][changed]
    assert (red[:, 0] > red[:, 1] + 40).all()  # It is the red marker that went.


def _block_pixels(image: np.ndarray) -> int:
    """Pixels of the pick-and-place block's blue (rgba (0.1, 0.45, 0.9)) in an image."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return int(((g > r + 60) & (b > r + 60)).sum())


def test_the_wrist_camera_sees_the_block_between_the_fingers_when_over_it():
    env = franka_composer.load("pick_and_place", seed=0, terminate_on_success=False,
                               observation_mode="state+pixels", cameras=("wrist",))
    timestep = env.reset()
    far = _block_pixels(timestep.observation["wrist_pixels"])
    block = timestep.observation["block/position"]
    timestep = move_tcp_to(env, timestep, block + [0, 0, 0.03], gripper=1.0)
    image = timestep.observation["wrist_pixels"]
    near = _block_pixels(image)
    centre = _block_pixels(image[20:64, 21:63])
    # Measured 592-600 of 7056 pixels over seeds 0-3, all of them in the centre; from the
    # starting pose, 28-149.
    assert near > 450 and centre == near
    assert near > 4 * far


def test_the_panda_is_drawn_from_its_hulls_or_its_visual_meshes():
    images = {}
    for meshes in ("hulls", "visual"):
        # renderable=None (what the Gymnasium adapter asks when it does not render): the
        # visual meshes only where the cameras draw them.
        env = franka_composer.load("push", seed=0, observation_mode="pixels",
                                   cameras=("workspace", "wrist"), camera_meshes=meshes,
                                   renderable=None)
        images[meshes] = {name: image.astype(int)
                          for name, image in env.reset().observation.items()
                          if name.endswith("_pixels")}
        # Hulls need no visual meshes in the model (a lean env); visual ones do.
        assert env.task.panda.has_visual_meshes == (meshes == "visual")
    differ = {camera: (np.abs(images["hulls"][camera] - images["visual"][camera]).sum(axis=-1)
                       > 30).mean() for camera in images["hulls"]}
    # The arm's outline and shading: measured 9.4 % of the workspace camera's pixels, 26.6 %
    # of the wrist camera's, where the hand fills much of the frame (docs/guide/pixels.md).
    assert 0.08 < differ["workspace_pixels"] < 0.11 and 0.24 < differ["wrist_pixels"] < 0.29
    with pytest.raises(ValueError, match="camera_meshes='visual' draws the Panda's visual "
                                         "meshes in the camera observations: "
                                         "renderable=False leaves them out"):
        franka_composer.load("push", observation_mode="pixels", camera_meshes="visual",
                             renderable=False)


@pytest.mark.parametrize("options, message", [
    (dict(observation_mode="rgb"), "unknown observation_mode 'rgb'; valid observation_modes: "
                                   "state, pixels, state\\+pixels"),
    (dict(cameras=("workspace", "eye")), "unknown camera 'eye'; valid cameras: workspace, "
                                          "wrist"),
    (dict(cameras=()), "cameras must be a camera name or a non-empty tuple or list"),
    (dict(cameras=("wrist", "wrist")), "cameras must be a camera name or a non-empty tuple or "
                                       "list of different ones"),
    # A sequence too, but not one it takes: "a sequence" said it was.
    (dict(cameras=np.array(["wrist"])), "cameras must be a camera name or a non-empty tuple "
                                        "or list of different ones from workspace, wrist, got "
                                        "array"),
    (dict(pixel_height=0), "pixel_height must be >= 1 and <= 1024, got 0"),
    (dict(pixel_width=84.0), "pixel_width must be a whole number"),
    (dict(pixel_width=2048), "pixel_width must be >= 1 and <= 1024, got 2048"),
    (dict(goal_marker_visible="yes"), "goal_marker_visible must be True or False"),
    (dict(camera_meshes="full"), "unknown camera_meshes 'full'; valid camera_meshes: hulls, "
                                 "visual$"),
    # Options of the images alone, in a mode without images: they did nothing.
    (dict(cameras="wrist"), "cameras set the camera observations, and observation_mode="
                            "'state' has none: give observation_mode='pixels' or "
                            "'state\\+pixels', or leave it out"),
    (dict(goal_marker_visible=False), "goal_marker_visible shows or hides the goal in "
                                      "rendered frames and camera observations, and "
                                      "render_mode=None with observation_mode='state' has "
                                      "neither: give render_mode='rgb_array' or 'human', or "
                                      "observation_mode='pixels' or 'state\\+pixels', or "
                                      "leave it out"),
    (dict(pixel_height=10, camera_meshes="visual"), "pixel_height, camera_meshes set the "
                                                    "camera observations, and observation_mode"
                                                    "='state' has none: .* leave them out"),
])
def test_bad_observation_options_are_refused_clearly(options, message):
    with pytest.raises(ValueError, match=message):
        gym.make("FrankaPushSparse-v0", **options)


def test_goal_marker_visible_is_taken_where_frames_or_images_show_the_goal():
    for options in (dict(render_mode="rgb_array"), dict(observation_mode="pixels")):
        env = gym.make("FrankaPushSparse-v0", goal_marker_visible=False, **options)
        assert env.unwrapped._task.config.observations.goal_marker_visible is False
        env.close()


@pytest.mark.slow
def test_sac_her_with_a_cnn_on_pixels_runs():
    """SB3's MultiInputPolicy puts a CNN on each image key and an MLP on the goals; HER
    relabels the state goals, exactly (compute_reward)."""
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make("FrankaPushSparse-v0", observation_mode="pixels",
                   terminate_on_success=False)
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
                learning_starts=100, batch_size=16, buffer_size=400, seed=0,
                policy_kwargs=dict(net_arch=[32]), device="cpu")
    extractor = model.actor.features_extractor
    assert type(extractor).__name__ == "CombinedExtractor"
    assert type(extractor.extractors["workspace_pixels"]).__name__ == "NatureCNN"
    model.learn(total_timesteps=150)
    assert model.num_timesteps == 150
    samples = model.replay_buffer.sample(64)
    assert samples.observations["workspace_pixels"].shape[1:] == (3, 84, 84)
    np.testing.assert_array_equal(
        samples.rewards.numpy().squeeze(-1),
        env.unwrapped.compute_reward(samples.next_observations["achieved_goal"].numpy(),
                                     samples.observations["desired_goal"].numpy(),
                                     None).astype(np.float32))
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert env.action_space.contains(action)
