"""The benchmark harness reports every figure, and the speed levers change no behaviour.

Nothing here is timed: these tests check that figures exist and are positive, that the
bare-MuJoCo floor simulates what the env simulates, and that each speed lever gives the
same model, observations and episodes as plain Composer.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from dm_control import composer

import franka_composer
from franka_composer import benchmark, seeding
from franka_composer.cli import main
from franka_composer.cli.bench import TARGETS
from franka_composer.entities.props import quat_to_euler
from franka_composer.tasks import build_task, task_config

_RUN_FIGURES = ("steps_per_s_resets_included", "steps_per_s_resets_excluded",
                "floor_steps_per_s", "overhead_ratio")


def test_bench_command_writes_every_figure(tmp_path, capsys):
    out = tmp_path / "results.json"
    assert main(["bench", "--tasks", "push", "--steps", "60", "--reset-samples", "3",
                 "--render-frames", "2", "--cold-start-samples", "1",
                 "--vector-workers", "1", "--memory-envs", "2", "--out", str(out)]) == 0
    results = json.loads(out.read_text())
    assert {"python", "mujoco", "dm-control", "gymnasium"} <= set(results["versions"])
    assert results["machine"]["nproc"] >= 1
    push = results["tasks"]["push"]
    assert push["env_id"] == "FrankaPushSparse-v0"
    for run in ("random", "expert"):
        assert push[run]["steps"] == 60
        for figure in _RUN_FIGURES:
            assert push[run][figure] > 0, (run, figure)
        # The floor replays the same episodes: the same contacts to within a few.
        assert push[run]["floor_mean_contacts"] == pytest.approx(push[run]["mean_contacts"],
                                                                 rel=0.2)
    for figure in ("reset_ms_median", "compute_reward_1024_us", "peak_rss_mb"):
        assert push[figure] > 0, figure
    assert push["render"]["ms_per_frame"] > 0
    assert push["cold_start"]["median_s"] > 0 and push["cold_start"]["uncached_s"] > 0
    assert push["vector_steps_per_s"]["1"] > 0
    lean, full = push["memory"]["none"], push["memory"]["rgb_array"]
    assert lean["envs"] == full["envs"] == 3
    # Measured 20 and 71 MB: the visual meshes are most of an env.
    assert 0 < lean["per_additional_env_mb"] < full["per_additional_env_mb"]
    assert set(push["targets"]) == set(TARGETS)
    table = capsys.readouterr().out
    assert "| push |" in table and str(out) in table


def test_bench_rejects_an_unknown_task_naming_the_valid_ones(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--tasks", "stack"])
    assert "pick_and_place" in capsys.readouterr().err


def test_floor_follows_the_env_trajectory_bit_for_bit():
    """Same model, start state, actions, action law and MuJoCo calls: the floor ends exactly
    where the env ends (one code path, one machine)."""
    env = gym.make("FrankaPickAndPlaceSparse-v0")
    env.reset(seed=1)
    physics = env.unwrapped.composer_env.physics
    episode = benchmark.Episode(benchmark._snapshot(physics.model.ptr, physics.data.ptr))
    rng = np.random.default_rng(0)
    for _ in range(20):
        action = rng.uniform(-1, 1, 4)
        env.step(action.astype(np.float32))
        episode.actions.append(action.astype(np.float32).astype(np.float64))
    floor = benchmark.Floor(env)
    seconds, contacts = floor.replay(episode)
    assert seconds > 0 and contacts > 0
    np.testing.assert_array_equal(floor.data.qpos, physics.data.qpos)
    np.testing.assert_array_equal(floor.data.qvel, physics.data.qvel)


def test_fast_resets_and_steps_match_composer_over_episodes():
    """Our environment (direct observables, kept updater, one compile) against plain
    Composer: identical observations at every reset and step of several episodes."""
    ours = franka_composer.load("pick_and_place", seed=5, terminate_on_success=False)
    task = build_task(task_config("pick_and_place", terminate_on_success=False))
    reference = composer.Environment(task, random_state=seeding.random_state(5),
                                     time_limit=float("inf"), strip_singleton_obs_buffer_dim=True)
    rng = np.random.default_rng(0)
    for _ in range(3):
        pairs = [(ours.reset(), reference.reset())]
        for _ in range(8):
            action = rng.uniform(-1, 1, 4).astype(np.float32)
            pairs.append((ours.step(action), reference.step(action)))
        for a, b in pairs:
            assert a.reward == b.reward and a.step_type == b.step_type
            assert a.observation.keys() == b.observation.keys()
            for key, value in b.observation.items():
                np.testing.assert_array_equal(a.observation[key], value, err_msg=key)
                assert a.observation[key].dtype == value.dtype


def test_an_observable_enabled_between_episodes_appears_after_the_next_reset():
    env = franka_composer.load("push", seed=0)
    env.reset()
    env.step(np.zeros(3, np.float32))
    env.task.panda.observables.joints_pos.enabled = True
    assert "panda/joints_pos" in env.reset().observation
    assert env.step(np.zeros(3, np.float32)).observation["panda/joints_pos"].shape == (7,)


def test_quat_to_euler_matches_the_numpy_formula_to_a_few_ulp():
    """Two implementations of one formula (scalar `math` against vectorised NumPy): NumPy's
    vectorised arctan2 takes a different SIMD path on AVX-512 CPUs and may differ in the
    last bit, so equality is to a few units in the last place, not bit for bit."""
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(2000, 4))
    quats[::3] = [1, 0, 0, 0] + 1e-4 * quats[::3]  # Near identity: small angles.
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    w, x, y, z = quats.T
    expected = np.stack([np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                         np.arcsin(np.clip(2 * (w * y - z * x), -1, 1)),
                         np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))], axis=1)
    actual = np.array([quat_to_euler(q) for q in quats])
    np.testing.assert_array_max_ulp(actual, expected, maxulp=4)
