"""The benchmark tooling reports every figure, and its bare-MuJoCo baseline simulates exactly
what the env simulates. Nothing here is timed."""

from __future__ import annotations

import importlib.util
import json
import pathlib
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

from franka_composer.cli import main

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
_RUN_FIGURES = ("steps_per_s_resets_included", "steps_per_s_resets_excluded",
                "floor_steps_per_s", "overhead_ratio")


def _load_benchmark(name: str):
    """benchmarks/<name>.py as a module (the scripts are not a package)."""
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # Its dataclasses look their module up there.
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_the_full_benchmark_writes_every_figure(tmp_path):
    out = tmp_path / "results.json"
    completed = subprocess.run(
        [sys.executable, str(BENCHMARKS / "bench.py"), "--tasks", "push", "--steps", "60",
         "--reset-samples", "3", "--render-frames", "2", "--cold-start-samples", "1",
         "--vector-workers", "1", "--memory-envs", "2", "--out", str(out)],
        capture_output=True, text=True, timeout=600, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    results = json.loads(out.read_text())
    assert {"python", "mujoco", "dm-control", "gymnasium"} <= set(results["versions"])
    assert results["machine"]["nproc"] >= 1
    push = results["tasks"]["push"]
    assert push["env_id"] == "FrankaPushSparse-v0"
    for run in ("random", "expert"):
        assert push[run]["steps"] == 60
        for figure in _RUN_FIGURES:
            assert push[run][figure] > 0, (run, figure)
        # The baseline replays the same episodes with the same MuJoCo calls.
        assert push[run]["floor_mean_contacts"] == push[run]["mean_contacts"]
    for figure in ("reset_ms_median", "compute_reward_1024_us", "peak_rss_mb"):
        assert push[figure] > 0, figure
    assert push["render"]["ms_per_frame"] > 0
    assert push["cold_start"]["median_s"] > 0 and push["cold_start"]["uncached_s"] > 0
    assert push["vector_steps_per_s"]["1"] > 0
    lean, full = push["memory"]["none"], push["memory"]["rgb_array"]
    assert lean["envs"] == full["envs"] == 3
    # Measured 20 and 71 MB: the visual meshes are most of an env.
    assert 0 < lean["per_additional_env_mb"] < full["per_additional_env_mb"]
    assert "| push |" in completed.stdout and str(out) in completed.stdout


def test_the_quick_bench_command_times_each_task(capsys):
    assert main(["bench", "--tasks", "push", "slide", "--steps", "50"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert [row.split("|")[1].strip() for row in rows[1:]] == ["push", "slide"]
    assert all(float(row.split("|")[2]) > 0 and float(row.split("|")[3]) > 0
               for row in rows[1:])


def test_bench_rejects_an_unknown_task_naming_the_valid_ones(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--tasks", "lift"])
    assert "pick_and_place" in capsys.readouterr().err


@pytest.mark.parametrize("control", ["mocap", "osc", "joints"])
def test_the_baseline_follows_the_env_trajectory_bit_for_bit(control):
    """Same model, start state, actions, action law and MuJoCo calls: the baseline ends
    exactly where the env ends (one code path, one machine)."""
    measure = _load_benchmark("measure")
    env = gym.make("FrankaPickAndPlaceSparse-v0", control=control)
    env.reset(seed=1)
    physics = env.unwrapped.composer_env.physics
    episode = measure.Episode(measure._snapshot(physics.model.ptr, physics.data.ptr))
    rng = np.random.default_rng(0)
    for _ in range(20):
        action = rng.uniform(-1, 1, env.action_space.shape)
        env.step(action.astype(np.float32))
        episode.actions.append(action.astype(np.float32).astype(np.float64))
    baseline = measure.BareMujocoBaseline(env)
    seconds, contacts = baseline.replay(episode)
    assert seconds > 0 and contacts > 0
    np.testing.assert_array_equal(baseline.data.qpos, physics.data.qpos)
    np.testing.assert_array_equal(baseline.data.qvel, physics.data.qvel)


@pytest.mark.slow
def test_the_still_baseline_is_what_an_untrained_run_scores(tmp_path):
    """An untrained policy scores exactly the episodes that start solved: the zero-action
    replay of a run's evaluations gives the rates of the run's own first evaluations
    (learning starts after them)."""
    module = _load_benchmark("still_baseline")
    from franka_composer.training.runs import RunDir, read_eval_rows

    out = tmp_path / "run"
    assert main(["train", "--task", "push", "--algo", "sac", "--seed", "0", "--out", str(out),
                 "--total-steps", "400", "--learning-starts", "400", "--eval-every", "100",
                 "--net-arch", "8", "--threads", "1", "--no-progress", "--device", "cpu"]) == 0
    run = [row["success_rate"] for row in read_eval_rows(RunDir(out).eval_csv)]
    still = module.still_rates("push", "mocap", seed=0, evaluations=len(run))
    assert still == run
    assert still[:3] == [0.0, 1 / 15, 2 / 15]  # Seed 0: 0, 1 and 2 episodes start solved.


@pytest.mark.slow
def test_a_resumed_run_evaluates_the_episodes_an_uninterrupted_run_would(tmp_path):
    """Learning starts after the budget, so the policy is the same untrained network in
    both runs and only the episodes decide the evaluations: a run stopped at 300 steps and
    resumed to 600 logs what an uninterrupted 600-step run logs, not its first
    evaluations' episodes again (which would score differently: the still baseline)."""
    module = _load_benchmark("still_baseline")
    from franka_composer.training.runs import RunDir, read_eval_rows

    def train(out, *args):
        assert main(["train", "--out", str(out), "--threads", "1", "--no-progress",
                     "--device", "cpu", *args]) == 0

    start = ["--task", "push", "--algo", "sac", "--seed", "0", "--learning-starts", "1000",
             "--eval-every", "100", "--checkpoint-every", "100", "--net-arch", "8"]
    train(tmp_path / "whole", *start, "--total-steps", "600")
    train(tmp_path / "resumed", *start, "--total-steps", "300")
    train(tmp_path / "resumed", "--resume", "--total-steps", "600")
    whole, resumed = (read_eval_rows(RunDir(tmp_path / name).eval_csv)
                      for name in ("whole", "resumed"))
    assert [row["steps"] for row in resumed] == [0, 100, 200, 300, 400, 500, 600]
    for key in ("success_rate", "mean_reward"):
        assert [row[key] for row in resumed] == [row[key] for row in whole]
    still = module.still_rates("push", "mocap", seed=0, evaluations=7)
    assert still[4:] != still[1:4]  # Evaluating the first episodes again would show.


@pytest.mark.slow
def test_probing_the_critic_leaves_the_run_as_train_makes_it():
    """`critic_probe.py` samples actions on the probed states from a fork of torch's
    generator: a run probed every 50 steps ends with the weights, bit for bit, of the same
    run unprobed; and the probe reports one saturation and log-std per action dimension."""
    torch = pytest.importorskip("torch")
    from stable_baselines3.common.callbacks import BaseCallback

    from franka_composer.training import hyperparameters
    from franka_composer.training.models import build_model, make_env

    module = _load_benchmark("critic_probe")
    hp = hyperparameters("push", "sac").replace(net_arch=(16, 16), batch_size=32,
                                                buffer_size=1000, learning_starts=100)
    env = make_env("push")
    states = {key: np.stack([value] * 5) for key, value in
              env.observation_space.sample().items()}
    env.close()
    reports = []

    class Probe(BaseCallback):
        def _on_step(self):
            if self.num_timesteps % 50 == 0:
                reports.append(module.critic_report(self.model, states))
            return True

    weights = []
    for callback in (Probe(), None):
        env = make_env("push")
        model = build_model("push", "sac", hp, env, seed=3, device="cpu")
        model.learn(300, callback=callback)
        weights.append(torch.cat([p.detach().flatten() for p in model.policy.parameters()]))
        env.close()
    assert len(reports) == 6 and torch.equal(weights[0], weights[1])
    assert all(r["saturated"].shape == r["log_std"].shape == (3,) and r["alpha"] > 0
               for r in reports)


def _write_runs(root: pathlib.Path, curves: dict[str, dict[int, float]]) -> None:
    from franka_composer.training.runs import write_eval_rows
    for name, curve in curves.items():
        (root / name).mkdir(parents=True)
        write_eval_rows(root / name / "eval.csv", [
            {"steps": steps, "wall_time_s": 1.0, "success_rate": rate, "mean_reward": -1.0}
            for steps, rate in curve.items()])


def test_compare_arms_gives_mean_and_std_over_seeds_at_each_mark_and_over_a_window(tmp_path):
    _write_runs(tmp_path / "a", {"seed0": {10_000: 0.2, 20_000: 0.4, 30_000: 0.6},
                                 "seed1": {10_000: 0.4, 20_000: 0.8, 30_000: 1.0}})
    # A run short of the window's end counts at the marks it reached, not in the window.
    _write_runs(tmp_path / "b", {"seed0": {10_000: 0.1, 20_000: 0.3, 30_000: 0.5},
                                 "seed1": {10_000: 0.3}})
    completed = subprocess.run(
        [sys.executable, str(BENCHMARKS / "compare_arms.py"), "--arm", "a", str(tmp_path / "a/*"),
         "--arm", "b", str(tmp_path / "b/*"), "--marks", "10000", "30000",
         "--window", "20000", "30000"], capture_output=True, text=True, check=True)
    assert completed.stdout.splitlines() == [
        "| arm | 10k | 30k | mean 20k–30k |",
        "|---|---|---|---|",
        "| a | 30 ± 10 % (n=2) | 80 ± 20 % (n=2) | 70 ± 20 % (n=2) |",
        "| b | 20 ± 10 % (n=2) | 50 ± 0 % (n=1) | 40 ± 0 % (n=1) |",
    ]


@pytest.mark.parametrize("args, message", [
    (["--arm", "a", "/nowhere/*"], "arm 'a': no run directory matches '/nowhere/*'"),
    (["--arm", "a", "/nowhere/*", "--window", "5", "1"], "--window: start 5 is after end 1"),
])
def test_compare_arms_names_what_was_wrong(args, message):
    completed = subprocess.run([sys.executable, str(BENCHMARKS / "compare_arms.py"), *args],
                               capture_output=True, text=True, check=False)
    assert completed.returncode != 0
    assert message in completed.stderr


def test_precision_fidelity_compares_one_gradient_step_on_the_same_batch_and_noise():
    """fp32 against itself is exact (the same batch, noise and starting state each time:
    nothing of the step is kept); bf16 departs from it, and the model is left unchanged."""
    import torch

    from franka_composer.training import hyperparameters
    from franka_composer.training.models import build_model, make_env

    fidelity = _load_benchmark("precision_fidelity")
    env = make_env("push")
    model = build_model("push", "tqc", hyperparameters("push", "tqc").replace(
        net_arch=(16, 16), batch_size=32, buffer_size=2000), env, seed=0, device="cpu")
    fidelity.fill(model, 200)
    assert model.replay_buffer.size() == 200 and model.gradient_steps == 1
    before = {name: tensor.clone() for name, tensor in model.policy.state_dict().items()}
    same = fidelity.compare(model, 3, against="fp32")
    assert set(same) == {"critic", "actor"}
    for values in same.values():
        np.testing.assert_allclose(values[:, 1], 0.0, atol=0)
        np.testing.assert_allclose(values[:, 0], 1.0, rtol=1e-6)
    bf16 = fidelity.compare(model, 3)
    assert all(0.0 < values[:, 1].min() and values[:, 0].max() < 1.0 for values in bf16.values())
    after = model.policy.state_dict()
    assert all(torch.equal(before[name], after[name]) for name in before)
    assert type(model.critic.optimizer).step is model.critic.optimizer.step.__func__
    env.close()


def test_the_paper_curves_are_read_back_from_a_figure_drawn_as_its_are(tmp_path):
    """A figure drawn as the paper's are (seaborn's grey axes, white grid, deep colours,
    shaded spreads, the legend top left, a later line over an earlier one, saved as JPEG)
    from known curves gives those curves back, and their steps to 80 % and 90 %."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from franka_composer.training.learning_report import first_reaching, smoothed

    curves_module = _load_benchmark("paper_curves")
    steps = np.arange(2000, 500_001, 2000)
    wiggle = 0.03 * np.sin(steps / 7000)
    truth = {"ddpg": 0.07 + wiggle,
             "sac": 0.05 + 0.93 / (1 + np.exp(-(steps - 160_000) / 18_000)) + wiggle,
             "tqc": 0.05 + 0.95 / (1 + np.exp(-(steps - 145_000) / 15_000)) - wiggle}
    fig, ax = plt.subplots(figsize=(6.5, 5))
    ax.set_facecolor("#eaeaf2")
    ax.grid(color="white", linewidth=1.25)
    ax.set_axisbelow(True)
    for spine in ax.spines.values():
        spine.set_visible(False)
    for algo, values in truth.items():
        colour = np.array(curves_module.LINE_COLOURS[algo]) / 255
        ax.plot(steps / 1e6, values, color=colour, linewidth=1.5, label=algo.upper())
        ax.fill_between(steps / 1e6, values - 0.03, values + 0.03, color=colour, alpha=0.2,
                        linewidth=0)
    ax.set_xticks(np.arange(0, 0.51, 0.1))
    ax.set_yticks(np.arange(0, 1.01, 0.2))
    ax.set_ylim(-0.05, 1.05)
    ax.legend(loc="upper left")
    fig.savefig(tmp_path / "figure.jpg", dpi=600)
    plt.close(fig)

    figure = curves_module.Figure("figure.jpg", (0.0, 1e5), (0.0, 0.2))
    read = curves_module.digitise(np.asarray(Image.open(tmp_path / "figure.jpg")), figure)
    assert set(read) == set(truth)
    for algo, values in truth.items():
        true_curve = dict(zip(steps.tolist(), values.tolist()))
        # Where a later line covers it, a line is read from its visible neighbours.
        common = sorted(set(read[algo]) & set(true_curve))
        assert len(common) > 0.75 * len(steps)
        errors = [abs(read[algo][s] - true_curve[s]) for s in common]
        assert np.median(errors) < 0.002 and max(errors) < 0.015, algo
        for threshold in (0.8, 0.9):
            expected = first_reaching(smoothed(true_curve), threshold)
            got = first_reaching(smoothed(read[algo]), threshold)
            assert (expected is None) == (got is None), algo
            if expected is not None:
                assert abs(got - expected) <= 2000, (algo, threshold, got, expected)


def test_the_paper_curves_refuse_a_figure_without_its_grid(tmp_path):
    curves_module = _load_benchmark("paper_curves")
    grey = np.full((300, 400, 3), curves_module.AXES_GREY, dtype=np.uint8)
    grey[:, 100:104] = 255  # One vertical grid line: no scale can be read off it.
    with pytest.raises(ValueError, match="x grid lines not found evenly spaced"):
        curves_module.digitise(grey, curves_module.FIGURES["push"])


def test_the_goal_bands_split_each_episode_by_its_goal_height():
    module = _load_benchmark("pick_and_place_goals")
    # (goal height above rest, lifted, success) per episode; 5 cm is still pushable.
    rows = np.array([[0.0, 0, 1], [0.03, 1, 0], [0.05, 1, 1], [0.12, 1, 1], [0.2, 0, 0]])
    assert module.band_rows(rows) == [("on the floor", 1, 100.0, 0.0),
                                      ("0-5 cm up", 2, 50.0, 100.0),
                                      ("5-20 cm up", 2, 50.0, 50.0),
                                      ("all", 5, 60.0, 60.0)]
    assert [band[0] for band in module.band_rows(rows[1:2])] == ["0-5 cm up", "all"]


@pytest.mark.slow  # sbx's policies build a JAX model.
def test_the_goal_bands_play_the_episodes_evaluate_plays(capsys):
    """Its "all" row is `franka-composer evaluate`'s success on the same episodes, and the
    bands share those episodes out among them."""
    module = _load_benchmark("pick_and_place_goals")
    run = BENCHMARKS.parent / "results" / "table2" / "pick_and_place-tqc-seed1"
    steps, rows = module.episodes_of(run, 12, seed=100)
    bands = module.band_rows(rows)
    assert sum(band[1] for band in bands[:-1]) == bands[-1][1] == 12
    assert main(["evaluate", str(run), "--episodes", "12", "--seed", "100",
                 "--device", "cpu"]) == 0
    assert (f"{steps} steps: success {bands[-1][2]:.1f} % over 12 episodes"
            in capsys.readouterr().out)


def test_the_goal_bands_refuse_a_run_of_another_task():
    module = _load_benchmark("pick_and_place_goals")
    with pytest.raises(SystemExit, match="a push run; this splits pick_and_place's goals"):
        module.episodes_of(BENCHMARKS.parent / "results" / "table2" / "push-tqc-seed0", 1, 0)


@pytest.mark.parametrize("args, message", [
    (["--episodes", "0"], "argument --episodes: must be a positive integer, got '0'"),
    (["--seed", "-1"], "argument --seed: must be an integer >= 0, got '-1'"),
])
def test_the_goal_bands_name_a_bad_option(args, message):
    completed = subprocess.run(
        [sys.executable, str(BENCHMARKS / "pick_and_place_goals.py"), "some-run", *args],
        capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert message in completed.stderr


def test_the_timestep_study_writes_its_table_against_the_finest_step(tmp_path):
    study = _load_benchmark("timestep_study")
    assert study.main(["--episodes", "1", "--tasks", "reach", "--out", str(tmp_path)]) == 0
    import csv

    with open(tmp_path / "timestep-study.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["policy"], float(r["timestep_ms"]), int(r["substeps"])) for r in rows] == [
        (policy, ms, substeps) for policy in ("expert", "random")
        for ms, substeps in ((2.0, 25), (1.0, 50), (0.5, 100))]
    finest = [r for r in rows if float(r["timestep_ms"]) == 0.5]
    assert all(float(r["final_position_diff_max_mm"]) == 0.0 for r in finest)
    # The same random actions at 2 ms end the hand elsewhere, by millimetres, not metres.
    coarse = next(r for r in rows if r["policy"] == "random" and r["substeps"] == "25")
    assert 0.0 < float(coarse["final_position_diff_max_mm"]) < 50.0
    assert (tmp_path / "timestep-study.md").read_text().count("| reach |") == 6


def test_the_timestep_study_reads_a_resting_blocks_weight_on_the_floor():
    """A 1 kg block resting on the floor: four corner contacts share its 9.81 N, and the
    stiff contacts (contacts.py) leave it tens of microns deep (0.04 mm measured)."""
    study = _load_benchmark("timestep_study")
    env = gym.make("FrankaPushSparse-v0")
    peaks = study.ContactPeaks(env.unwrapped.composer_env)
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(3, np.float32))
    assert 9.81 / 4 * 0.9 < peaks.force < 9.81
    assert peaks.force_pair == "world/block/"
    assert 0.0 < peaks.penetration < 1e-4


def test_the_timestep_study_refuses_an_unknown_task(capsys):
    study = _load_benchmark("timestep_study")
    with pytest.raises(SystemExit):
        study.main(["--tasks", "push,fly"])
    assert "unknown --tasks fly; valid: push, slide" in capsys.readouterr().err
