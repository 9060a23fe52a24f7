"""Demonstration datasets (franka_composer/datasets/): Minari and RLDS load with the
ecosystem's own readers and round-trip, an episode replayed from its seed and actions giving
back the stored observations exactly."""

from __future__ import annotations

import pathlib
import re

import minari
import numpy as np
import pytest

import franka_composer
from franka_composer import seeding
from franka_composer.cli import main
from franka_composer.datasets import minari_format, record, rlds_format
from franka_composer.policies import Trajectories, make_expert


def _replay_goal_env(env, seed, actions):
    """The observations, rewards and flags of `actions` from `env.reset(seed=seed)`."""
    obs, _ = env.reset(seed=seed)
    observations, rewards, terminated, truncated = [obs], [], [], []
    for action in actions:
        obs, reward, term, trunc, _ = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        terminated.append(term)
        truncated.append(trunc)
    return observations, rewards, terminated, truncated


@pytest.mark.parametrize("control, options", [("mocap", {}),
                                              ("osc", {"terminate_on_success": False})])
def test_a_minari_dataset_loads_recovers_its_env_and_replays_exactly(tmp_path, control, options):
    summary = record("push", 3, tmp_path, format="minari", seed=20, control=control, **options)
    dataset_id = "franka_composer/push/expert-v0" if control == "mocap" else \
        "franka_composer/push-osc/expert-v0"
    assert summary["dataset_id"] == dataset_id and summary["episodes"] == 3
    with minari_format.datasets_root(tmp_path):
        dataset = minari.load_dataset(dataset_id)  # Minari's own reader.
    assert dataset.total_episodes == 3 and minari_format.episode_seeds(dataset) == [20, 21, 22]
    env = dataset.recover_environment()
    assert env.unwrapped.task.config.control.kind == control
    assert env.unwrapped.task.terminate_on_success is options.get("terminate_on_success", True)
    for seed, episode in zip(minari_format.episode_seeds(dataset), dataset.iterate_episodes()):
        assert set(episode.observations) == {"observation", "achieved_goal", "desired_goal"}
        assert episode.actions.shape == (len(episode.rewards), 3)
        observations, rewards, terminated, truncated = _replay_goal_env(env, seed,
                                                                        episode.actions)
        for key, stored in episode.observations.items():
            np.testing.assert_array_equal(np.array([o[key] for o in observations]), stored)
        np.testing.assert_array_equal(rewards, episode.rewards)
        np.testing.assert_array_equal(terminated, episode.terminations)
        np.testing.assert_array_equal(truncated, episode.truncations)
        assert episode.infos["is_success"][-1] == (episode.rewards[-1] == 0.0)
    if control == "osc":  # Fetch semantics: every episode runs to the time limit.
        assert all(len(e.rewards) == 50 and e.truncations[-1]
                   for e in dataset.iterate_episodes())


def test_an_rlds_dataset_reads_with_envlogger_and_replays_exactly(tmp_path):
    summary = record("pick_and_place", 3, tmp_path / "rlds", format="rlds", seed=5,
                     action_noise=0.2, terminate_on_success=False)
    assert summary["steps"] == 150  # Three episodes cut at the time limit.
    envlogger = rlds_format.import_envlogger()
    with envlogger.Reader(data_directory=str(tmp_path / "rlds")) as reader:  # Its own reader.
        assert reader.metadata()["task"] == "pick_and_place"
        assert len(reader.episodes) == 3
    dataset = rlds_format.read(tmp_path / "rlds")
    assert dataset["metadata"]["action_noise"] == 0.2
    assert dataset["metadata"]["options"] == {"terminate_on_success": False}
    env = franka_composer.load("pick_and_place", terminate_on_success=False)
    for index, episode in enumerate(dataset["episodes"]):
        # The time-out's LAST (discount 1): not a termination.
        assert episode["seed"] == 5 + index and not episode["terminated"]
        seeding.reseed(env.random_state, episode["seed"])
        replayed = [env.reset().observation]
        rewards = []
        for action in episode["actions"]:
            timestep = env.step(action)
            replayed.append(timestep.observation)
            rewards.append(timestep.reward)
        assert len(replayed) == len(episode["observations"]) == 51
        for stored, again in zip(episode["observations"], replayed):
            assert set(stored) == set(again) >= {"achieved_goal", "goal", "block/position"}
            for key in stored:
                np.testing.assert_array_equal(stored[key], again[key])
        np.testing.assert_array_equal(episode["rewards"], rewards)
    # The actions are the expert's plus N(0, 0.2) noise (drawn per episode from the seed),
    # not the expert's own: the expert, replayed on the stored observations, planned others.
    expert = make_expert(env)
    expert.reset()
    episode = dataset["episodes"][0]
    planned = np.array([expert(observation) for observation in episode["observations"][:-1]])
    taken = np.array(episode["actions"])
    free = (np.abs(taken) < 1) & (np.abs(planned) < 1)  # Neither clipped to [-1, 1].
    noise = (taken - planned)[free]
    assert noise.size > 50 and 0.15 < noise.std() < 0.25 and abs(noise.mean()) < 0.06


def test_every_rlds_episode_ends_with_a_last_step(tmp_path, capsys):
    # The noisy osc expert fails some episodes: those end at the time limit, discount 1.
    assert main(["rollout", "--task", "push", "--control", "osc", "--action-noise", "0.2",
                 "--format", "rlds", "--episodes", "3", "--out", str(tmp_path / "rlds")]) == 0
    envlogger = rlds_format.import_envlogger()
    with envlogger.Reader(data_directory=str(tmp_path / "rlds")) as reader:
        ends = [(len(steps) - 1, steps[-1].timestep) for steps in map(list, reader.episodes)]
    assert len(ends) == 3 and all(last.last() for _, last in ends)
    for length, last in ends:  # A time-out at 50 steps, discount 1; a success, 0.
        assert (length, last.discount) == (50, 1.0) if last.reward == -1.0 else (
            1 <= length <= 50 and last.discount == 0.0)
    assert any(last.reward == -1.0 for _, last in ends)  # The failure the noise brings.
    assert "push: 3 episodes" in capsys.readouterr().out


@pytest.mark.parametrize("format", ["npz", "minari", "rlds"])
def test_record_works_in_the_pixel_modes(tmp_path, format):
    """Every format keeps the images as they were observed, pixel for pixel (Minari's
    default JPEG changed almost all of them)."""
    out = tmp_path / ("pixels.npz" if format == "npz" else "pixels")
    options = dict(seed=2, observation_mode="pixels", pixel_width=48, pixel_height=32)
    summary = record("push", 1, out, format=format, **options)
    assert summary["success_rate"] == 1.0
    if format == "npz":
        episode = Trajectories.load(out).episodes[0]
        assert "observation" not in episode
        assert episode["workspace_pixels"].shape == (summary["steps"] + 1, 32, 48, 3)
        return
    record("push", 1, tmp_path / "as-observed.npz", **options)
    observed = Trajectories.load(tmp_path / "as-observed.npz").episodes[0]["workspace_pixels"]
    if format == "minari":
        with minari_format.datasets_root(out):
            episode = next(minari.load_dataset(summary["dataset_id"]).iterate_episodes())
        assert set(episode.observations) == {"achieved_goal", "desired_goal",
                                             "workspace_pixels"}
        stored = episode.observations["workspace_pixels"]
    else:
        stored = np.stack([observation["workspace_pixels"] for observation in
                           rlds_format.read(out)["episodes"][0]["observations"]])
    assert stored.shape == (summary["steps"] + 1, 32, 48, 3)
    np.testing.assert_array_equal(stored, observed)


@pytest.mark.parametrize("format", ["npz", "minari", "rlds"])
def test_every_format_records_episodes_of_the_length_max_episode_steps_asks(tmp_path, format):
    # gym.make takes max_episode_steps for its TimeLimit; RLDS logs the dm_env beneath it.
    out = tmp_path / ("short.npz" if format == "npz" else "short")
    summary = record("push", 2, out, format=format, seed=0, max_episode_steps=7,
                     terminate_on_success=False)
    assert summary["steps"] == 14
    if format == "rlds":
        assert [len(e["actions"]) for e in rlds_format.read(out)["episodes"]] == [7, 7]
    # Episodes that end only on success could run forever: refused before anything is made.
    endless = tmp_path / ("endless.npz" if format == "npz" else "endless")
    with pytest.raises(ValueError, match=r"episodes of this env end only on success \(no "
                                         r"max_episode_steps and time_limit=None\)"):
        record("push", 1, endless, format=format, max_episode_steps=-1, time_limit=None)
    assert not endless.exists()


def test_action_noise_is_a_function_of_the_seed_and_the_command_line_records(tmp_path, capsys):
    def actions(name, seed, noise):
        assert main(["rollout", "--task", "push", "--episodes", "2", "--seed", str(seed),
                     "--action-noise", str(noise), "--format", "npz",
                     "--out", str(tmp_path / f"{name}.npz")]) == 0
        with np.load(tmp_path / f"{name}.npz") as data:
            return data["action"][:20]  # The first episode's first steps: equal lengths.

    noisy = actions("a", 3, 0.3)
    assert "push: 2 episodes" in capsys.readouterr().out
    np.testing.assert_array_equal(actions("b", 3, 0.3), noisy)
    assert np.abs(noisy).max() <= 1.0
    expert = actions("quiet", 3, 0)
    # The first step sees the same reset: the expert's action plus episode 0's first draw.
    draw = 0.3 * np.random.default_rng([3, 0]).normal(size=3)
    np.testing.assert_allclose(noisy[0], np.clip(expert[0] + draw, -1, 1), rtol=0, atol=1e-6)
    assert not np.array_equal(actions("other", 4, 0.3), noisy)


def test_rollout_records_at_the_control_timestep_it_is_given(tmp_path):
    assert main(["rollout", "--task", "push", "--episodes", "1", "--control-timestep", "0.5",
                 "--format", "rlds", "--out", str(tmp_path / "slow")]) == 0
    assert rlds_format.read(tmp_path / "slow")["metadata"]["options"] == {
        "control_timestep": 0.5}
    with pytest.raises(ValueError, match="^--control-timestep must be a whole multiple of the "
                                         "physics timestep \\(0.002 s\\), got 0.051"):
        main(["rollout", "--task", "push", "--control-timestep", "0.051",
              "--out", str(tmp_path / "x.npz")])
    assert not (tmp_path / "x.npz").exists()


def test_a_named_timing_is_recorded_as_the_values_it_sets(tmp_path):
    """`record(..., timing="reference")` keeps what the name stands for today, so that a
    later change to the name's meaning cannot make old data read as new."""
    from franka_composer.datasets import record
    from franka_composer.policies.rollout import Trajectories

    record("push", 1, tmp_path / "named.npz", timing="reference")
    assert Trajectories.load(tmp_path / "named.npz").metadata["options"] == {
        "control_timestep": 0.5, "velocity_timestep": 0.05, "weld_time_constant": 0.02}


def test_rollout_records_at_the_reference_timing(tmp_path):
    assert main(["rollout", "--task", "push", "--episodes", "1", "--timing", "reference",
                 "--format", "rlds", "--out", str(tmp_path / "reference")]) == 0
    assert rlds_format.read(tmp_path / "reference")["metadata"]["options"] == {
        "control_timestep": 0.5, "velocity_timestep": 0.05, "weld_time_constant": 0.02}
    with pytest.raises(ValueError, match="give --timing or --control-timestep, not both"):
        main(["rollout", "--task", "push", "--timing", "reference", "--control-timestep",
              "0.5", "--out", str(tmp_path / "x.npz")])
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("argv, message", [
    (["--format", "parquet"], "invalid choice: 'parquet'"),
    (["--action-noise", "-0.1"], "must be a standard deviation >= 0, got '-0.1'"),
    (["--seed", "-1"], "must be an integer >= 0, got '-1'"),
])
def test_bad_rollout_options_are_refused_before_anything_is_written(tmp_path, capsys, argv,
                                                                    message):
    with pytest.raises(SystemExit):
        main(["rollout", "--task", "push", "--out", str(tmp_path / "x"), *argv])
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("arguments, message", [
    ({"task": "nope"}, "unknown task 'nope'; valid tasks: push, slide"),
    ({"reward_type": "shaped"}, "unknown reward_type 'shaped'; valid reward_types: sparse, dense"),
    ({"control": "ik"}, "unknown control 'ik'; valid controls: mocap, osc, joints")])
def test_record_refuses_a_task_reward_or_controller_it_does_not_know(tmp_path, arguments,
                                                                      message):
    """By name, as every other argument of `record` (not a KeyError from the id's parts),
    before anything is written."""
    arguments = {"task": "push", **arguments}
    with pytest.raises(ValueError, match=re.escape(message)):
        record(arguments.pop("task"), 1, tmp_path / "x.npz", **arguments)
    assert list(tmp_path.iterdir()) == []


def test_a_dataset_is_not_written_over_another_or_onto_a_file(tmp_path):
    """Found out before any episode is recorded: envlogger would append to an RLDS
    dataset there, and Minari refuses an existing id only at the end."""
    record("push", 1, tmp_path / "minari", format="minari", seed=0)
    record("push", 1, tmp_path / "rlds", format="rlds", seed=0)
    (tmp_path / "file").write_text("kept")
    for out, format, message in (
            ("minari", "minari", "already holds the Minari dataset "
                                 "franka_composer/push/expert-v0: choose another --out or "
                                 "--dataset-id"),
            ("rlds", "rlds", "is not empty: an RLDS dataset takes a folder of its own"),
            ("file", "rlds", "a rlds dataset is a folder, and .*file is a file"),
            ("file", "minari", "a minari dataset is a folder, and .*file is a file")):
        with pytest.raises(ValueError, match=message):
            record("push", 1, tmp_path / out, format=format, seed=0)
    assert len(rlds_format.read(tmp_path / "rlds")["episodes"]) == 1
    assert (tmp_path / "file").read_text() == "kept"
    # Another id in the same root is a dataset of its own.
    assert record("push", 1, tmp_path / "minari", format="minari", seed=0,
                  dataset_id="franka_composer/push/expert-v1")["episodes"] == 1


def test_an_npz_dataset_path_must_end_in_npz(tmp_path):
    """numpy adds ".npz" to any other name: the file would not be where it was asked for."""
    with pytest.raises(ValueError, match="an npz dataset's path must end in .npz, got '.*x.txt'"):
        record("push", 1, tmp_path / "x.txt")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("format", ["minari", "rlds"])
def test_a_folder_dataset_is_not_named_as_an_npz_file(format, tmp_path):
    """A Minari or RLDS dataset is a folder: one named x.npz was made without a word, a name
    that says npz file to whoever reads it."""
    with pytest.raises(ValueError, match=re.escape(
            f"a {format} dataset is a folder, and {str(tmp_path / 'x.npz')!r} is named as an "
            "npz file: give a folder's name, or --format npz")):
        record("push", 1, tmp_path / "x.npz", format=format, seed=0)
    assert list(tmp_path.iterdir()) == []


def test_joint_control_needs_a_trained_policy(tmp_path):
    with pytest.raises(ValueError, match="the scripted experts act on dx, dy, dz"):
        record("push", 1, tmp_path / "x", format="minari", control="joints")
    assert not (tmp_path / "x").exists()


def test_a_trained_policy_records_pixels_acting_on_the_state_it_learned_from(tmp_path):
    """In the pixel modes a committed policy (state observations) acts on the state the task
    reads, as the experts do: the same actions as in the state mode, images beside them
    (it built its networks on the image space, and torch refused the 84 x 3 input)."""
    policy = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-sac-seed0"
    recorded = {}
    for mode in ("state", "pixels", "state+pixels"):
        pixels = {} if mode == "state" else dict(pixel_height=16, pixel_width=16)
        record("push", 2, tmp_path / f"{mode}.npz", seed=3, policy_dir=policy,
               observation_mode=mode, **pixels)
        recorded[mode] = Trajectories.load(tmp_path / f"{mode}.npz")
    state = recorded["state"]
    assert state.success_rate == 1.0 and all(state.lengths < 50)  # It solves them.
    for mode in ("pixels", "state+pixels"):
        for ours, theirs in zip(recorded[mode].episodes, state.episodes):
            np.testing.assert_array_equal(ours["action"], theirs["action"])
            assert ours["workspace_pixels"].shape == (len(ours["action"]) + 1, 16, 16, 3)
    np.testing.assert_array_equal(recorded["state+pixels"].episodes[0]["observation"],
                                  state.episodes[0]["observation"])


@pytest.mark.slow
def test_a_trained_policy_records_deterministically(tmp_path):
    assert main(["train", "--task", "push", "--algo", "sac", "--seed", "0", "--out",
                 str(tmp_path / "run"), "--total-steps", "100", "--net-arch", "16,16",
                 "--batch-size", "32", "--buffer-size", "2000", "--learning-starts", "50",
                 "--eval-every", "100", "--eval-episodes", "1", "--threads", "1",
                 "--no-progress", "--device", "cpu"]) == 0
    for name in ("a", "b"):
        summary = record("push", 2, tmp_path / name, format="rlds", seed=1,
                         policy_dir=tmp_path / "run")
        assert summary["episodes"] == 2
    first, second = rlds_format.read(tmp_path / "a"), rlds_format.read(tmp_path / "b")
    assert first["metadata"]["source"] == "policy"
    assert len(first["episodes"]) == len(second["episodes"]) == 2
    for a, b in zip(first["episodes"], second["episodes"]):
        np.testing.assert_array_equal(np.array(a["actions"]), np.array(b["actions"]))
    with pytest.raises(ValueError, match="trained push, not slide"):
        record("slide", 1, tmp_path / "c.npz", policy_dir=tmp_path / "run")
    with pytest.raises(ValueError, match="acts through mocap control, not osc"):
        record("push", 1, tmp_path / "d.npz", control="osc", policy_dir=tmp_path / "run")
    with pytest.raises(ValueError, match="acts every 0.05 s, not every 0.5 s"):
        record("push", 1, tmp_path / "d.npz", control_timestep=0.5,
               policy_dir=tmp_path / "run")
    assert not (tmp_path / "d.npz").exists()
