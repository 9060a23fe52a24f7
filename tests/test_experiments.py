"""The investigation scripts still in use (experiments/): two setups compared over seeds, the
still baseline is what an untrained run scores, the paper's curves are read back from
figures drawn as the paper's are, and the goal bands split pick-and-place's episodes as
`evaluate` plays them."""

from __future__ import annotations

import json
import os
import pathlib
import pickle
import re
import shutil
import shlex
import subprocess
import sys

import numpy as np
import pytest

from conftest import load_script
from franka_composer.cli import main

EXPERIMENTS = pathlib.Path(__file__).resolve().parents[1] / "experiments"
RESULTS = EXPERIMENTS.parent / "results"



@pytest.mark.slow
def test_the_still_baseline_is_what_an_untrained_run_scores(tmp_path):
    """An untrained policy scores exactly the episodes that start solved: the zero-action
    replay of a run's evaluations gives the rates of the run's own first evaluations
    (learning starts after them)."""
    module = load_script(EXPERIMENTS / "still_baseline.py")
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
    module = load_script(EXPERIMENTS / "still_baseline.py")
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
def test_a_run_is_set_beside_its_own_floor_evaluation_by_evaluation(tmp_path):
    """`still_baseline.py --run`: the still policy on the run's own episodes (its task,
    options, seed and cadence), per window and over all, counting the evaluations above,
    at and below it."""
    module = load_script(EXPERIMENTS / "still_baseline.py")
    from franka_composer.training.hyperparams import hyperparameters
    from franka_composer.training.runs import RunConfig, RunDir

    still = module.still_rates("push", "osc", seed=3, evaluations=4, episodes=15)
    assert still == [0.0, 1 / 15, 1 / 15, 1 / 15]  # Seed 3's (seed 0's: 0, 1/15, 2/15, ...).
    run = RunDir(tmp_path / "run")
    run.write_config(RunConfig("push", "sac", 3, hyperparameters("push", "sac"),
                               control="osc"))
    rates = [still[0], still[1] + 0.2, still[2], 0.0]
    run.eval_csv.write_text("steps,wall_time_s,success_rate,mean_reward\n" + "".join(
        f"{2000 * i},{i + 1},{rate},-1\n" for i, rate in enumerate(rates)))
    assert module.run_beside_floor(run.root, window=4000).splitlines()[2:] == [
        "| 0–4,000 | 2 | 16.7 % | 6.7 % | 1 / 1 / 0 | 0.5 |",
        "| 4,000–6,000 | 1 | 0.0 % | 6.7 % | 0 / 0 / 1 | 1 |",
        "| 0–6,000 | 4 | 8.3 % | 5.0 % | 1 / 2 / 1 | 0.75 |"]
    run.eval_csv.write_text("steps,wall_time_s,success_rate,mean_reward\n0,1,0.0,-1\n"
                            "4000,2,0.0,-1\n")
    with pytest.raises(SystemExit, match="evaluations are not every 2000 steps from 0"):
        module.run_beside_floor(run.root)
    with pytest.raises(SystemExit, match="is not a training run"):
        module.run_beside_floor(tmp_path)
    altered = RESULTS / "damped-block" / "pick_and_place-tqc-seed0"
    with pytest.raises(SystemExit, match=f"^{altered}: the run trained in .* through the "
                                         "experiments/ script that trained it$"):
        module.run_beside_floor(altered)


def test_the_sign_test_is_the_binomial_tail_of_the_evaluations_above_the_floor():
    module = load_script(EXPERIMENTS / "still_baseline.py")
    assert module.sign_test(0, 0) is None  # All equal: nothing to test.
    assert module.sign_test(11, 0) == 2.0 ** -11
    assert module.sign_test(0, 3) == 1.0
    assert module.sign_test(2, 1) == (3 + 1) / 8  # P(X >= 2), X ~ Binomial(3, 1/2).


def test_the_trailing_mean_averages_each_evaluation_with_those_before_it():
    module = load_script(EXPERIMENTS / "still_baseline.py")
    values = np.array([0.0, 0.2, 0.4, 0.0, 1.0])
    np.testing.assert_allclose(module.trailing_mean(values, 3), [0.0, 0.1, 0.2, 0.2, 14 / 30])
    np.testing.assert_array_equal(module.trailing_mean(values, 1), values)


@pytest.mark.slow
def test_runs_are_drawn_beside_their_floors_one_panel_each(tmp_path, capsys):
    """`--run A B --plot PNG`: each run's table under its name, then one figure with a
    panel per run; --plot without runs, or to a file of no image type, is refused first."""
    from PIL import Image

    module = load_script(EXPERIMENTS / "still_baseline.py")
    from franka_composer.training.hyperparams import hyperparameters
    from franka_composer.training.runs import RunConfig, RunDir

    for name, seed in (("a", 3), ("b", 0)):
        run = RunDir(tmp_path / name)
        run.write_config(RunConfig("push", "sac", seed, hyperparameters("push", "sac")))
        run.eval_csv.write_text("steps,wall_time_s,success_rate,mean_reward\n" + "".join(
            f"{2000 * i},{i + 1},0.5,-1\n" for i in range(4)))
    png = tmp_path / "floors.png"
    assert module.main(["--run", str(tmp_path / "a"), str(tmp_path / "b"),
                        "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert f"{tmp_path / 'a'} (push sac seed 3)" in out and f"{tmp_path / 'b'} (push sac " \
        "seed 0)" in out
    assert "| 0–6,000 | 4 | 50.0 % | 5.0 % | 4 / 0 / 0 | 0.062 |" in out  # Seed 0: 0, 1, 2, 0 of 15.
    assert out.rstrip().endswith(f"wrote {png}")
    # --final-test: the still policy on evaluate's episodes: those that start solved (push's
    # 20 from seed 2024: the block within 5 cm of the goal at reset in 2).
    from franka_composer.training.models import make_env

    env = make_env("push")
    starts = [env.reset(seed=2024 if episode == 0 else None)[0] for episode in range(20)]
    env.close()
    solved = [np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]) < 0.05
              for obs in starts]
    assert sum(solved) == 2
    assert module.main(["--run", str(tmp_path / "b"), "--final-test", "20", "2024"]) == 0
    assert "still policy on evaluate's 20 episodes from seed 2024: 10.0 %" in \
        capsys.readouterr().out
    assert Image.open(png).size == (1100, 400)  # Two 5.5 x 4 in panels at 100 dpi.
    for args, message in ((["--plot", str(png)], "--plot draws runs: give them with --run"),
                          (["--run", "x", "--plot", "floors.txt"],
                           "--plot: a .png, .pdf or .svg file, not floors.txt"),
                          (["--final-test", "20", "2024"],
                           "--final-test reads runs: give them with --run"),
                          (["--run", "x", "--final-test", "0", "2024"],
                           "--final-test EPISODES: must be a positive integer, got '0'"),
                          (["--run", "x", "--final-test", "20", "-1"],
                           "--final-test SEED: must be an integer >= 0, got '-1'")):
        with pytest.raises(SystemExit):
            module.main(args)
        assert message in capsys.readouterr().err


@pytest.mark.slow
def test_the_edge_flick_the_physics_page_records_happens_at_both_timings():
    """docs/guide/physics.md's limit of the guard, as `edge_flick.py` measures it: a finger
    resting on the block's top edge, a full sideways command off it; the block's speed and
    height are read after every physics step (the reference timing's step ends miss a
    flight), and the hand's top speed in free space beside them."""
    import gymnasium as gym

    module = load_script(EXPERIMENTS / "edge_flick.py")
    cases = {"default": [(0, (-0.025, -0.03), 0.0, (1, -1, 1)),
                         (0, (-0.035, 0.0), 0.0, (1, 0, -1))],
             "reference": [(1, (-0.035, 0.03), 0.0, (1, 0, -1))]}
    hand, outcomes = {}, {}
    for timing, trials in cases.items():
        env = gym.make("FrankaPickAndPlaceSparse-v0", max_episode_steps=400, timing=timing,
                       terminate_on_success=False)
        hand[timing] = module.hand_top_speed(env)
        outcomes[timing] = [module.trial(env, *case) for case in trials]
        env.close()
    assert hand == {"default": pytest.approx(2.73, abs=0.01),
                    "reference": pytest.approx(1.33, abs=0.01)}
    (speed, rise), (push_speed, push_rise) = outcomes["default"]
    assert speed == pytest.approx(4.57, abs=0.01) and rise == pytest.approx(0.256, abs=0.001)
    assert push_speed == pytest.approx(1.86, abs=0.01) and push_rise < 0.002  # Shoved, flat.
    [(speed, rise)] = outcomes["reference"]
    assert speed == pytest.approx(4.08, abs=0.01) and rise == pytest.approx(0.151, abs=0.001)
    # --stiff-hand-contacts: the block's weight takes its contacts with the hand, over resets.
    env = gym.make("FrankaPickAndPlaceSparse-v0", terminate_on_success=False)
    module.stiffen_hand_contacts(env)
    env.reset(seed=3)
    model = env.unwrapped._env.physics.model
    assert model.geom_solmix[model.name2id("block/geom", "geom")] == 1e6
    env.close()


@pytest.mark.slow
def test_the_controller_press_the_controllers_page_records():
    """docs/guide/controllers.md's table, as `controller_press.py` measures it on
    pick-and-place seed 0: every controller holds the specification's bounds (object
    within 2 mm of its height, under 0.3 m/s, the force within the arm's push)."""
    module = load_script(EXPERIMENTS / "controller_press.py")
    readings = {control: module.press("pick_and_place", control, 0, 80, "default")
                for control in ("mocap", "osc", "joints")}
    for reading in readings.values():
        assert reading["sank_mm"] < 2 and reading["rose_mm"] < 2
        assert reading["fastest_m_s"] < 0.3 and reading["moved_mm"] < 1
        assert reading["peak_force_n"] < 136 and reading["into_floor_mm"] < 2
    joints = readings["joints"]
    assert joints["fastest_m_s"] == pytest.approx(0.004, abs=0.001)
    assert joints["peak_force_n"] == pytest.approx(115, abs=1)


@pytest.mark.slow
def test_osc_tracking_the_controllers_page_records():
    """docs/guide/controllers.md's osc cell, as `osc_tracking.py` measures it: mid-square a
    full +x is tracked as from the neutral pose; at x 0.75 the arm, at its torque limits,
    turns the hand back."""
    import franka_composer

    module = load_script(EXPERIMENTS / "osc_tracking.py")
    env = franka_composer.load("reach", seed=0, control="osc", terminate_on_success=False,
                               time_limit=None)
    middle, _ = module.shares(env, (0.6, 0.2), 0, 1)
    edge, end = module.shares(env, (0.75, 0.2), 0, 1)
    assert np.round(middle) == pytest.approx([76, 95, 90], abs=0.5)
    assert np.round(edge) == pytest.approx([69, 39, -42], abs=0.5)
    assert end[0] == pytest.approx(0.783, abs=0.001)


def test_joint_tracking_the_controllers_page_records():
    """docs/guide/controllers.md's joints cell, as `joint_tracking.py` measures it: joint 2
    covers 83 % of a full command from rest, then 115-124 % held, until in the fifth step
    the hand nears the floor and the surface guard brakes it (99 %); joint 6, 97 then
    98-99."""
    import franka_composer

    module = load_script(EXPERIMENTS / "joint_tracking.py")
    env = franka_composer.load("push", seed=0, control="joints", terminate_on_success=False,
                               time_limit=None)
    shoulder = module.shares(env, [1], 1, 5)[:, 0]
    wrist = module.shares(env, [5], 1, 5)[:, 0]
    assert round(shoulder[0]) == 83 and (round(shoulder[1:4].min()), round(
        shoulder[1:4].max())) == (115, 124) and round(shoulder[4]) == 99
    assert round(wrist[0]) == 97 and (round(wrist[1:].min()), round(wrist[1:].max())) == (98, 99)


@pytest.mark.parametrize("args, message", [
    (["--move-z", "2"], "--move-z must be an action in [-1, 1], got 2"),
    (["--seeds", "-1"], "argument --seeds: must be an integer >= 0, got '-1'"),
    (["--weld-time-constant", "0"], "argument --weld-time-constant:"),
])
def test_edge_flick_names_a_bad_option_before_any_trial(args, message, capsys, monkeypatch):
    module = load_script(EXPERIMENTS / "edge_flick.py")
    monkeypatch.setattr(module, "trial", lambda *args, **kwargs: pytest.fail("a trial ran"))
    import gymnasium

    monkeypatch.setattr(gymnasium, "make", lambda *args, **kwargs: pytest.fail("env made"))
    with pytest.raises(SystemExit) as exit_info:
        module.main(args)
    assert exit_info.value.code == 2 and message in capsys.readouterr().err


def test_training_episodes_reads_what_each_flip_learner_episode_reached():
    """`training_episodes.py` on flip: which face is up from the quaternion, a tip, and
    success over the goals that need a tip and those that need none; a table per window."""
    import types

    module = load_script(EXPERIMENTS / "training_episodes.py")
    upright, turned = [1.0, 0.0, 0.0, 0.0], [np.cos(0.1), 0.0, 0.0, np.sin(0.1)]
    on_y, upside_down = [np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]
    assert module.face_up(np.array([upright, turned, on_y, upside_down])).tolist() == [2, 2, 1, 5]
    # Two episodes: steps 0-2 tip the cube onto its +y face, the goal, and succeed; steps 3-4
    # leave it upright, short of a goal turned about z.
    before = [upright, upright, on_y, upright, upright]
    after = [upright, on_y, on_y, upright, upright]
    goals = [on_y] * 3 + [turned] * 2

    def stored(achieved):
        return {"observation": np.zeros((5, 1, 20)), "achieved_goal": np.array(achieved)[:, None],
                "desired_goal": np.array(goals)[:, None]}

    buffer = types.SimpleNamespace(
        n_envs=1, full=False, pos=5, observations=stored(before),
        next_observations=stored(after), actions=np.zeros((5, 1, 4)),
        ep_start=np.array([0, 0, 0, 3, 3])[:, None],
        rewards=np.array([-1.0, 0.0, 0.0, -1.0, -1.0])[:, None])
    steps = module.Steps(buffer)
    measures = module.flip_measures(steps)
    assert [(title, holds.tolist(), None if among is None else among.tolist())
            for title, holds, among in measures] == [
        ("cube tipped onto another face", [True, False], None),
        ("succeeded", [True, False], None),
        ("succeeded, goals that need a tip", [True, False], [True, False]),
        ("succeeded, goals that need none", [True, False], [False, True])]
    assert module.table(steps.first_step, measures, window=3) == [
        "| training steps | episodes | cube tipped onto another face | succeeded | succeeded, "
        "goals that need a tip | succeeded, goals that need none |",
        "|---|---|---|---|---|---|",
        "| 0–3 | 1 | 100.0 % | 100.0 % | 100.0 % of 1 | – of 0 |",
        "| 3–6 | 1 | 0.0 % | 0.0 % | – of 0 | 0.0 % of 1 |"]


def test_training_episodes_tells_a_stacked_block_from_a_flung_one():
    """stack: a block resting on the other is 4 cm above it and within 2 cm across; a block
    5 cm up and above the hand was flung, not carried."""
    import types

    module = load_script(EXPERIMENTS / "training_episodes.py")
    floor = [0.6, 0.0, 0.02, 0.7, 0.0, 0.02]
    stacked = [0.6, 0.0, 0.02, 0.61, 0.0, 0.06]
    carried, flung = [0.6, 0.0, 0.02, 0.7, 0.0, 0.09], [0.6, 0.0, 0.02, 0.9, 0.0, 0.12]
    after = [stacked, carried, flung]
    tcp = [0.61, 0.7, 0.7]  # The hand's x; its height 0.08 m, with the carried block.
    observation = np.zeros((3, 1, 31))
    observation[:, 0, 0], observation[:, 0, 2] = tcp, 0.08

    def stored(achieved):
        return {"observation": observation, "achieved_goal": np.array(achieved)[:, None],
                "desired_goal": np.array([[0.6, 0.0, 0.02, 0.6, 0.0, 0.06]] * 3)[:, None]}

    buffer = types.SimpleNamespace(
        n_envs=1, full=False, pos=3, observations=stored([floor] * 3),
        next_observations=stored(after), actions=np.zeros((3, 1, 4)),
        ep_start=np.array([0, 1, 2])[:, None], rewards=np.array([0.0, -1.0, -1.0])[:, None])
    measures = {title: holds.tolist()
                for title, holds, _ in module.stack_measures(module.Steps(buffer))}
    assert measures == {"a block pushed > 2 cm": [True, False, True],
                        "a block lifted > 2 cm": [True, True, True],
                        "block 1 within 5 cm of its goal": [True, True, True],
                        "a block resting on the other": [True, False, False],
                        "succeeded": [True, False, False],
                        "a block flung > 5 cm up": [False, False, True]}


def test_flip_goals_group_each_goal_by_the_tips_it_needs():
    module = load_script(EXPERIMENTS / "flip_goals.py")
    # face_up's numbering: +x, +y, +z, -x, -y, -z; upright is +z (2).
    assert [module.tips_between(2, face) for face in range(6)] == [1, 1, 0, 1, 1, 2]
    assert [module.tips_between(face, (face + 3) % 6) for face in range(6)] == [2] * 6
    # (tips needed, tipped, success) per episode.
    rows = np.array([[0, 0, 1], [0, 0, 0], [1, 1, 1], [1, 1, 0], [1, 0, 0], [2, 1, 0]])
    groups = module.group_rows(rows)
    assert [group[:2] for group in groups] == [("no tip", 2), ("one tip", 3), ("two tips", 1),
                                               ("all", 6)]
    assert [group[2:] for group in groups] == [(50.0, 0.0), pytest.approx((100 / 3, 200 / 3)),
                                               (0.0, 100.0), pytest.approx((100 / 3, 50.0))]
    assert [group[0] for group in module.group_rows(rows[:2])] == ["no tip", "all"]


@pytest.mark.slow
def test_flip_goals_record_what_each_played_episode_needed_and_did():
    """Played still (zero actions), the cube never tips, and an episode succeeds only where
    it starts solved: one needing no tip, turned less than 0.2 rad; the tips are those from
    the start's face up to the goal's. The expert tips it where, and only where, needed."""
    module = load_script(EXPERIMENTS / "flip_goals.py")
    from franka_composer.training.models import make_env

    env = module.FlipGoals(make_env("flip", terminate_on_success=True))
    needed = []
    for seed in range(12):
        obs, _ = env.reset(seed=seed)
        needed.append(module.tips_between(int(module.face_up(obs["achieved_goal"])),
                                          int(module.face_up(obs["desired_goal"]))))
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(np.zeros(4, np.float32))
            done = terminated or truncated
    rows = np.array(env.rows)
    assert rows[:, 0].tolist() == needed and set(needed) == {0, 1, 2}
    assert not rows[:, 1].any()
    assert set(np.flatnonzero(rows[:, 2])) <= set(np.flatnonzero(rows[:, 0] == 0))
    # The scripted expert tips the cube exactly where a goal needs it.
    from franka_composer.policies import make_expert

    env.rows.clear()
    expert = make_expert(env)
    for seed in range(12):
        obs, _ = env.reset(seed=seed)
        expert.reset()
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(expert(obs))
            done = terminated or truncated
    env.close()
    played = np.array(env.rows)
    assert played[:, 0].tolist() == needed
    assert played[:, 1].tolist() == [tips > 0 for tips in needed]
    assert np.flatnonzero(played[:, 2] == 0).tolist() == [6]  # 11 of 12 (>= 90 % over 100).


def test_flip_goals_refuse_a_run_of_another_task():
    module = load_script(EXPERIMENTS / "flip_goals.py")
    with pytest.raises(SystemExit, match="a pick_and_place run; this reads flip runs"):
        module.episodes_of(RESULTS / "table2" / "pick_and_place-tqc-seed1", 1, seed=0)


def test_the_paper_curves_are_read_back_from_a_figure_drawn_as_its_are(tmp_path):
    """A figure drawn as the paper's are (seaborn's grey axes, white grid, deep colours,
    shaded spreads, the legend top left, a later line over an earlier one, saved as JPEG)
    from known curves gives those curves back, and their steps to 80 % and 90 %."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from franka_composer.training.learning_report import first_reaching, smoothed

    curves_module = load_script(EXPERIMENTS / "paper_curves.py")
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
    curves_module = load_script(EXPERIMENTS / "paper_curves.py")
    grey = np.full((300, 400, 3), curves_module.AXES_GREY, dtype=np.uint8)
    grey[:, 100:104] = 255  # One vertical grid line: no scale can be read off it.
    with pytest.raises(ValueError, match="x grid lines not found evenly spaced"):
        curves_module.digitise(grey, curves_module.FIGURES["push"])


def test_the_goal_bands_split_each_episode_by_its_goal_height():
    module = load_script(EXPERIMENTS / "pick_and_place_goals.py")
    # (goal height above rest, lifted, success) per episode; 5 cm is still pushable.
    rows = np.array([[0.0, 0, 1], [0.03, 1, 0], [0.05, 1, 1], [0.12, 1, 1], [0.2, 0, 0]])
    assert module.band_rows(rows) == [("on the floor", 1, 100.0, 0.0),
                                      ("0-5 cm up", 2, 50.0, 100.0),
                                      ("5-20 cm up", 2, 50.0, 50.0),
                                      ("all", 5, 60.0, 60.0)]
    assert [band[0] for band in module.band_rows(rows[1:2])] == ["0-5 cm up", "all"]


@pytest.mark.slow  # sbx's policies build a JAX model.
def test_the_goal_bands_play_the_episodes_evaluate_plays(capsys, monkeypatch):
    """Its "all" row is `franka-composer evaluate`'s success on the same episodes, and the
    bands share those episodes out among them; --object-damping plays them on a block
    damped so."""
    module = load_script(EXPERIMENTS / "pick_and_place_goals.py")
    run = RESULTS / "table2" / "pick_and_place-tqc-seed1"
    steps, rows = module.episodes_of(run, 12, seed=100)
    bands = module.band_rows(rows)
    assert sum(band[1] for band in bands[:-1]) == bands[-1][1] == 12
    assert main(["evaluate", str(run), "--episodes", "12", "--seed", "100",
                 "--device", "cpu"]) == 0
    assert (f"{steps} steps: success {bands[-1][2]:.1f} % over 12 episodes"
            in capsys.readouterr().out)
    # --object-damping: the same episodes, on a block damped so.
    seen = []

    class Watched(module.GoalBands):
        def reset(self, **kwargs):
            result = super().reset(**kwargs)
            seen.append(self.env.unwrapped.composer_env.physics.model.dof_damping[-6:].copy())
            return result

    monkeypatch.setattr(module, "GoalBands", Watched)
    _, damped = module.episodes_of(run, 2, seed=100, object_damping=0.01)
    _, undamped = module.episodes_of(run, 2, seed=100)
    assert [list(damping) for damping in seen] == [[0.01] * 6] * 2 + [[0.0] * 6] * 2
    np.testing.assert_array_equal(undamped[:, 0], rows[:2, 0])  # The same goals.
    np.testing.assert_array_equal(damped[:, 0], rows[:2, 0])


def test_the_goal_bands_refuse_a_run_of_another_task():
    module = load_script(EXPERIMENTS / "pick_and_place_goals.py")
    with pytest.raises(SystemExit, match="a push run; this reads pick_and_place runs"):
        module.episodes_of(RESULTS / "table2" / "push-tqc-seed0", 1, 0)
    # A run in an env only its own script builds (experiments/altered_runs.py) is named,
    # with the script to use, not a traceback.
    altered = RESULTS / "damped-block" / "pick_and_place-tqc-seed0"
    with pytest.raises(SystemExit, match=f"^{altered}: the run trained in .* through the "
                                         "experiments/ script that trained it$"):
        module.episodes_of(altered, 1, 0)


@pytest.mark.parametrize("args, message", [
    (["--episodes", "0"], "argument --episodes: must be a positive integer, got '0'"),
    (["--seed", "-1"], "argument --seed: must be an integer >= 0, got '-1'"),
    (["--object-damping", "-1"], "error: object_damping must be >= 0, got -1.0"),
])
def test_the_goal_bands_name_a_bad_option(args, message):
    completed = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "pick_and_place_goals.py"), "some-run", *args],
        capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert message in completed.stderr


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
        [sys.executable, str(EXPERIMENTS / "compare_arms.py"), "--arm", "a", str(tmp_path / "a/*"),
         "--arm", "b", str(tmp_path / "b/*"), "--marks", "10000", "30000",
         "--window", "20000", "30000"], capture_output=True, text=True, check=True)
    assert completed.stdout.splitlines() == [
        "| arm | 10k | 30k | mean 20k–30k |",
        "|---|---|---|---|",
        "| a | 30 ± 10 % (n=2) | 80 ± 20 % (n=2) | 70 ± 20 % (n=2) |",
        "| b | 20 ± 10 % (n=2) | 50 ± 0 % (n=1) | 40 ± 0 % (n=1) |",
    ]


def test_compare_arms_sets_the_papers_curve_beside_the_arms(tmp_path):
    """The paper's row reads the digitised curve's point at each mark and its mean over the
    window, from the committed curves.csv; a mark the figure has no point at reads "–"."""
    _write_runs(tmp_path / "a", {"seed0": {200_000: 0.2, 400_000: 0.4}})
    completed = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "compare_arms.py"), "--arm", "a", str(tmp_path / "a/*"),
         "--marks", "200000", "400000", "400001", "--window", "440000", "444000",
         "--paper", "pick_and_place", "tqc"], capture_output=True, text=True, check=True)
    module = load_script(EXPERIMENTS / "compare_arms.py")
    curve = module.read_paper_curves(module.PAPER_CURVES)["pick_and_place", "tqc"]
    window = np.mean([curve[440_000], curve[442_000], curve[444_000]])
    assert completed.stdout.splitlines()[-1] == (
        f"| the paper's pick_and_place tqc | {100 * curve[200_000]:.0f} % | "
        f"{100 * curve[400_000]:.0f} % | – | {100 * window:.0f} % |")
    assert completed.stdout.splitlines()[-1] == (
        "| the paper's pick_and_place tqc | 26 % | 75 % | – | 99 % |")


def test_compare_arms_windows_are_half_open_averaged_per_run_then_over_runs(tmp_path):
    """A window (A, B] holds the evaluation at B, not the one at A; each run's mean comes
    first, then the arm's mean over the runs that evaluated there; a run that stopped inside
    a window says where."""
    _write_runs(tmp_path / "a", {"seed0": {0: 0.9, 50_000: 0.1, 100_000: 0.3, 150_000: 0.5},
                                 "seed1": {50_000: 0.3, 60_000: 0.6, 80_000: 0.9}})
    (tmp_path / "a" / "final-test.md").write_text("not a run")
    completed = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "compare_arms.py"), "--arm", "a", str(tmp_path / "a/*"),
         "--marks", "50000", "--windows", "50000"], capture_output=True, text=True, check=True)
    # 0–50k: seed0 0.1 (step 0 is outside), seed1 0.3 -> 20.0 ± 10.0; 50–100k: seed0 0.3,
    # seed1 (0.6 + 0.9) / 2 = 0.75, stopped at 80k -> 52.5 ± 22.5; 100–150k: seed0 alone.
    assert completed.stdout.splitlines()[-3:] == [
        "| mean success (%) per window | 0–50k | 50–100k | 100–150k |",
        "|---|---|---|---|",
        "| a | 20.0 ± 10.0 | 52.5 ± 22.5 (to 80k) | 50.0 ± 0.0 (n=1) |",
    ]


def test_compare_arms_windows_refuse_runs_without_an_evaluation(tmp_path):
    _write_runs(tmp_path / "a", {"seed0": {}})
    completed = subprocess.run(
        [sys.executable, str(EXPERIMENTS / "compare_arms.py"), "--arm", "a", str(tmp_path / "a/*"),
         "--windows", "50000"], capture_output=True, text=True, check=False)
    assert completed.returncode != 0
    assert "--windows: no arm has an evaluation after step 0" in completed.stderr


def _results_window_tables() -> list[tuple[list[list[str]], str]]:
    """RESULTS.md's per-5e4-step tables: each one's rows' cells (name left out) and the
    compare_arms command in the note below it."""
    text = (EXPERIMENTS.parent / "RESULTS.md").read_text()
    tables = []
    for block in text.split("| mean success of the evaluations per 5e4 steps")[1:]:
        lines = block.split("\n\n")[0].splitlines()[2:]
        note = " ".join(block.split("\n\n")[1].split())
        command = next(part for part in note.split("`") if "compare_arms.py" in part)
        tables.append(([[cell.strip() for cell in line.split("|")[2:-1]] for line in lines],
                       command))
    return tables


def test_results_has_its_five_window_tables():
    """The tables the next test checks are found (a reworded heading would leave it none)."""
    assert len(_results_window_tables()) == 5


@pytest.mark.parametrize("rows, command", _results_window_tables())
def test_results_window_tables_are_the_output_of_the_command_beside_them(rows, command):
    """Every cell of RESULTS.md's per-5e4-step tables, from the committed runs' eval.csv
    and the paper's curve, by the command printed beside the table."""
    assert command.startswith("python experiments/compare_arms.py ")
    completed = subprocess.run([sys.executable, *shlex.split(command)[1:]],
                               cwd=EXPERIMENTS.parent, capture_output=True, text=True,
                               check=True)
    printed = completed.stdout.split("\n\n")[1].splitlines()[2:]
    assert [[cell.strip() for cell in line.split("|")[2:-1]] for line in printed] == rows


@pytest.mark.parametrize("args, message", [
    (["--arm", "a", "/nowhere/*"],
     "arm 'a': no run directory (one with an eval.csv) matches '/nowhere/*'"),
    (["--arm", "a", "/nowhere/*", "--window", "5", "1"], "--window: start 5 is after end 1"),
    (["--arm", "a", "/nowhere/*", "--windows", "0"], "--windows: the step must be positive, not 0"),
    (["--arm", "a", str(EXPERIMENTS.parent / "results/table2/*"), "--paper", "pick_and_place",
      "ppo"],
     "has no curve for pick_and_place ppo (it has pick_and_place ddpg,"),
])
def test_compare_arms_names_what_was_wrong(args, message):
    completed = subprocess.run([sys.executable, str(EXPERIMENTS / "compare_arms.py"), *args],
                               capture_output=True, text=True, check=False)
    assert completed.returncode != 0
    assert message in completed.stderr



def test_random_exploration_plays_the_same_actions_and_reads_the_block_from_the_goal():
    """Every suite plays episode i's same actions from reset(seed=SEED + i); the rows are
    the same on a second play, the block starts still, and the closed-hand variant starts
    with the fingers at width 0 where this suite's open to 0.08 m."""
    module = load_script(EXPERIMENTS / "random_exploration.py")
    assert not np.array_equal(module.episode_actions(0, 3, 4), module.episode_actions(0, 4, 4))
    ours = module.make_env("ours", "pick_and_place")
    played, step = [], ours.step
    ours.step = lambda action: played.append(action) or step(action)
    row = module.play(ours, seed=5, episode=2)
    # What any suite is given: a function of the seed and the episode alone, as float32.
    expected = np.random.default_rng([5, 2]).uniform(-1.0, 1.0, (50, 4))[:row["steps"]]
    np.testing.assert_array_equal(np.array(played), expected.astype(np.float32))
    del ours.step
    closed = module.make_env("closed", "pick_and_place")
    assert ours.reset(seed=0)[0]["observation"][6] == pytest.approx(0.08)
    assert closed.reset(seed=0)[0]["observation"][6] == pytest.approx(0.0, abs=1e-12)
    rows = [module.play(ours, seed=0, episode=episode) for episode in range(3)]
    assert rows == [module.play(ours, seed=0, episode=episode) for episode in range(3)]
    assert all(1 <= row["steps"] <= 50 and row["away"] >= row["highest"] for row in rows)
    summary = module.summary([{"away": 0.06, "highest": 0.0, "far_steps": 5, "steps": 50},
                              {"away": 0.0, "highest": 0.0, "far_steps": 0, "steps": 30}])
    assert summary["moved 5 cm"] == 0.5 and summary["steps 5 cm away"] == 5 / 80
    ours.close()
    closed.close()


def assert_same_reference_physics(model, undone) -> None:
    """`model` has what env_differences.py undoes on `undone`: contacts, damping, solver."""
    for field in ("geom_friction", "geom_condim", "geom_solref", "geom_solimp", "pair_dim",
                  "pair_friction", "pair_solref", "pair_solimp", "dof_damping"):
        np.testing.assert_array_equal(getattr(model, field), getattr(undone, field))
    for field in ("integrator", "cone", "noslip_iterations"):
        assert getattr(model.opt, field) == getattr(undone.opt, field)


def test_random_exploration_plays_the_reference_physics_as_the_training_check_does(
        monkeypatch):
    from franka_composer.surface_guard import BoundSurfaceGuard

    monkeypatch.setattr(BoundSurfaceGuard, "guard", BoundSurfaceGuard.guard)
    module = load_script(EXPERIMENTS / "random_exploration.py")
    differences = load_script(EXPERIMENTS / "env_differences.py")
    env = module.make_env("reference_physics", "pick_and_place")
    expected = differences.make_undone(set(differences.DIFFERENCES))
    try:
        model, undone = (each.unwrapped.composer_env.physics.model for each in (env, expected))
        assert_same_reference_physics(model, undone)
        assert model.opt.noslip_iterations == 3 and model.dof_damping[-1] == 0.01
        assert env.reset(seed=0)[0]["observation"][6] == pytest.approx(0.0, abs=1e-12)
        assert BoundSurfaceGuard.guard(None, None, np.array([0.1, 0.0, -0.3]), 1.0) == 0.0
    finally:
        env.close()
        expected.close()


def test_goal_sampling_draws_each_reset_from_its_seed_and_compares_alike_draws():
    module = load_script(EXPERIMENTS / "goal_sampling.py")
    env = load_script(EXPERIMENTS / "random_exploration.py").make_env("ours", "pick_and_place")
    blocks, goals = module.draw(env, seed=3, episodes=40)
    again = module.draw(env, seed=4, episodes=2)
    env.close()
    np.testing.assert_array_equal(again[0], blocks[1:3])  # Reset i is reset(seed=SEED + i).
    np.testing.assert_array_equal(again[1], goals[1:3])
    described = module.describe(blocks, goals)
    floor = np.mean(np.abs(goals[:, 2] - blocks[:, 2]) < module.FLOOR)
    assert described["goals on the floor"] == f"{100 * floor:.1f} %" and 0 < floor < 1
    # The statistic is the largest gap between the two distribution functions.
    assert module.ks_statistic(np.array([0.0, 1.0]), np.array([0.0, 1.0])) == 0.0
    assert module.ks_statistic(np.array([0.0, 1.0]), np.array([2.0, 3.0])) == 1.0
    assert module.ks_statistic(np.array([0.0, 2.0]), np.array([1.0, 3.0])) == 0.5
    assert module.ks_critical(10000, 10000) == pytest.approx(0.0230, abs=1e-4)
    table = module.tables({"ours": {"blocks": blocks.tolist(), "goals": goals.tolist()},
                           "reference": {"blocks": blocks.tolist(), "goals": goals.tolist()}})
    assert "| block x | 0.0000 | " in table  # One draw against itself.


@pytest.mark.parametrize("script", ["random_exploration.py", "grasp_margin.py",
                                    "grasp_reach.py", "push_tip.py", "goal_sampling.py"])
@pytest.mark.parametrize("args, message", [
    (["--episodes", "0"], "--episodes 0: give at least 1"),
    (["--reference-path", "{tmp}"], "{tmp}: no panda_mujoco_gym/__init__.py there; give the "
                                    "folder of a checkout")])
def test_the_reference_experiments_name_a_bad_argument(script, args, message, tmp_path):
    args = [arg.format(tmp=tmp_path) for arg in args]
    completed = subprocess.run([sys.executable, str(EXPERIMENTS / script), *args],
                               capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert message.format(tmp=tmp_path) in completed.stderr


class _ScriptedSuccesses:
    """An env whose episodes succeed at the steps each script lists, and end at success
    (`terminate`) or after 4 steps."""

    def __init__(self, scripts, terminate):
        self.scripts, self.terminate, self.seeds = list(scripts), terminate, []

    def reset(self, seed=None):
        self.seeds.append(seed)
        self.succeeds, self.t = self.scripts.pop(0), 0
        return {"observation": np.zeros(1)}, {}

    def step(self, action):
        self.t += 1
        success = self.t in self.succeeds
        return ({"observation": np.zeros(1)}, 0.0, success and self.terminate, self.t == 4,
                {"is_success": float(success)})


def test_cross_play_counts_a_success_at_any_step_and_at_the_last():
    module = load_script(EXPERIMENTS / "cross_play.py")
    resets = []

    class Policy:
        def reset(self):
            resets.append(True)

        def predict(self, obs, deterministic=True):
            assert deterministic
            return np.zeros(4), None

    # Succeeding at step 2 only, at steps 2 and 4, never, at step 4.
    scripts = [{2}, {2, 4}, set(), {4}]
    env = _ScriptedSuccesses(scripts, terminate=False)
    assert module.play(Policy(), env, 4, seed=7) == (0.75, 0.5)
    assert env.seeds == [7, None, None, None] and len(resets) == 4
    # Ending on success, the episode's last step is its success: the two agree.
    assert module.play(Policy(), _ScriptedSuccesses(scripts, terminate=True), 4,
                       seed=7) == (0.75, 0.75)


def cross_play_on_a_stand_in(monkeypatch):
    """cross_play.py with this suite's pick-and-place (0.05 s per step) standing in for the
    reference code's."""
    import gymnasium as gym

    module = load_script(EXPERIMENTS / "cross_play.py")
    monkeypatch.setattr(module.reference_env_runs, "reference_specs",
                        lambda path: {"pick_and_place": gym.spec("FrankaPickAndPlaceSparse-v0")})
    monkeypatch.setattr(module.reference_env_runs.peer_worker, "reference_path_error",
                        lambda path: None)
    return module


def test_cross_play_prints_a_row_per_policy(monkeypatch, capsys):
    module = cross_play_on_a_stand_in(monkeypatch)
    run = RESULTS / "reference-timing" / "pick_and_place-tqc-seed0"
    assert module.main(["--reference-path", "unused", str(run), "--expert",
                        "--episodes", "2", "--seed", "3"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert rows[0].startswith("| run | trained in | steps | this suite, reference timing |")
    assert rows[1].startswith("| pick_and_place-tqc-seed0 | this suite, 0.5 s per step | "
                              "500,000 | ")
    assert rows[2] == ("| scripted expert | – | – | 100.0 ± 0.0 | 100.0 ± 0.0 | +0.0 | "
                       "100.0 ± 0.0 | 100.0 ± 0.0 |")
    assert len(rows) == 3


def test_cross_play_splits_each_env_by_the_goals_height(monkeypatch, capsys):
    # The scripted expert lifts the block to every goal above the floor.
    module = cross_play_on_a_stand_in(monkeypatch)
    assert module.main(["--reference-path", "unused", "--expert", "--episodes", "6",
                        "--seed", "3", "--goal-bands"]) == 0
    out = capsys.readouterr().out
    bands = [line for line in out.split("\n\n")[-1].splitlines() if line.startswith("| ")]
    assert bands[0] == "| run | steps | env | goal | episodes | success | block rose > 1 cm |"
    cells = [line.strip("| ").split(" | ") for line in bands[1:]]
    assert [row[2] for row in cells if row[3] == "all"] == [
        "this suite, reference timing", "reference code's env"]
    assert all(row[:2] == ["scripted expert", "–"] and row[5] == "100.0 %" for row in cells)
    assert [row[4] for row in cells if row[3] == "all"] == ["6", "6"]
    high = [row for row in cells if row[3] == "5-20 cm up"]
    assert high and all(row[6] == "100.0 %" for row in high)
    assert sum(int(row[4]) for row in cells if row[3] != "all") == 12


def test_env_differences_undo_what_they_name_and_nothing_else():
    import mujoco

    module = load_script(EXPERIMENTS / "env_differences.py")
    plain = module.make_undone(set())
    undone = module.make_undone(set(module.DIFFERENCES))
    try:
        before = plain.unwrapped.composer_env.physics.model
        after = undone.unwrapped.composer_env.physics.model
        fingers = module.contact_geoms(after, module.FINGERS)
        block, floor = after.geom("block/geom").id, after.geom("floor").id
        assert len(fingers) == 12
        np.testing.assert_array_equal(after.geom_friction[fingers], 0.8)
        assert set(after.geom_condim[fingers]) == {3} and after.geom_condim[block] == 6
        np.testing.assert_array_equal(before.geom_friction[fingers], [[2.0, 0.005, 1e-4]] * 12)
        for geom in (block, floor):
            np.testing.assert_array_equal(after.geom_solref[geom], [0.02, 1.0])
            np.testing.assert_array_equal(after.geom_solimp[geom], [0.9, 0.95, 0.001, 0.5, 2])
            np.testing.assert_array_equal(before.geom_solref[geom], [0.004, 1.0])
        # The block's contact with the floor, a contact pair (`contacts.add_surface_pair`).
        on_floor = after.pair("block_floor").id
        assert (before.pair_dim[on_floor], after.pair_dim[on_floor]) == (4, 6)
        np.testing.assert_array_equal(after.pair_solref[on_floor], [0.02, 1.0])
        np.testing.assert_array_equal(after.pair_solimp[on_floor], [0.9, 0.95, 0.001, 0.5, 2])
        np.testing.assert_array_equal(before.pair_solref[on_floor], [0.004, 1.0])
        assert (after.opt.integrator, after.opt.cone, after.opt.noslip_iterations) == (
            mujoco.mjtIntegrator.mjINT_EULER, mujoco.mjtCone.mjCONE_PYRAMIDAL, 3)
        assert (before.opt.integrator, before.opt.cone, before.opt.noslip_iterations) == (
            mujoco.mjtIntegrator.mjINT_IMPLICITFAST, mujoco.mjtCone.mjCONE_ELLIPTIC, 0)
        np.testing.assert_array_equal(after.dof_damping[-6:], 0.01)
        np.testing.assert_array_equal(before.dof_damping[-6:], 0.0)
        # The fingers start closed, and the model's changes hold through resets.
        width = {name: env.reset(seed=1)[0]["observation"][6] for name, env in
                 (("plain", plain), ("undone", undone))}
        assert width["plain"] == pytest.approx(0.08, abs=1e-3)
        assert width["undone"] == pytest.approx(0.0, abs=1e-3)
        assert undone.unwrapped.composer_env.physics.model.geom_condim[block] == 6
    finally:
        plain.close()
        undone.close()


def test_env_differences_let_the_guard_go_for_their_row_only():
    from franka_composer.surface_guard import BoundSurfaceGuard

    module = load_script(EXPERIMENTS / "env_differences.py")
    guard = BoundSurfaceGuard.guard
    with module.guard_let_go({"closed_fingers"}):
        assert BoundSurfaceGuard.guard is guard
    with pytest.raises(KeyError):
        with module.guard_let_go({"unguarded"}):
            assert BoundSurfaceGuard.guard(None, None, np.array([0.1, 0.0, -0.3]), 1.0) == 0.0
            raise KeyError("played")
    assert BoundSurfaceGuard.guard is guard


def test_env_differences_row_of_nothing_undone_is_what_evaluate_measures(capsys):
    from franka_composer.tasks.options import TIMINGS
    from franka_composer.training.evaluation import measure_success
    from franka_composer.training.models import make_env
    from franka_composer.training.policy_file import load_trained
    from franka_composer.training.runs import RunDir

    module = load_script(EXPERIMENTS / "env_differences.py")
    run = RESULTS / "reference-timing" / "pick_and_place-tqc-seed0"
    assert module.main([str(run), "--only", "closed_fingers", "--episodes", "10",
                        "--seed", "100"]) == 0
    rows = [line.strip("| ").split(" | ") for line in capsys.readouterr().out.splitlines()
            if line.startswith("| ")]
    assert rows[0] == ["undone", "steps", "success", "on the floor", "0-5 cm up", "5-20 cm up",
                       "block rose > 1 cm"]
    assert [row[0] for row in rows[1:]] == ["none (this suite)", "closed_fingers"]
    env = make_env("pick_and_place", **TIMINGS["reference"])
    try:
        success = measure_success(load_trained(RunDir(run), env, device="cpu"), env, 10,
                                  seed=100).success_rate
    finally:
        env.close()
    assert rows[1][1] == "500,000" and rows[1][2] == f"{100 * success:.1f} % of 10"
    assert module.main([str(run), "--only", "closed_fingers", "solver", "--leave-one-out",
                        "--episodes", "1"]) == 0
    assert [line.split(" | ")[0] for line in capsys.readouterr().out.splitlines()
            if line.startswith("| ")][1:] == [
        "| none (this suite)", "| all of them", "| all but closed_fingers", "| all but solver"]


@pytest.mark.parametrize("args, message", [
    (["{tmp}/none"], "{tmp}/none does not exist"),
    ([str(RESULTS / "table2" / "push-tqc-seed0")],
     f"{RESULTS / 'table2' / 'push-tqc-seed0'} trained push; this plays pick_and_place"),
    ([str(RESULTS / "reference-timing" / "pick_and_place-tqc-seed0"), "--only", "friction"],
     "argument --only: invalid choice: 'friction'"),
    ([str(RESULTS / "reference-timing" / "pick_and_place-tqc-seed0"), "--only", "solver",
      "--leave-one-out"], "--leave-one-out needs two differences or more")])
def test_env_differences_name_a_bad_argument_before_they_play(args, message, tmp_path, capsys):
    module = load_script(EXPERIMENTS / "env_differences.py")
    with pytest.raises(SystemExit) as exit_:
        module.main([arg.format(tmp=tmp_path) for arg in args])
    assert exit_.value.code == 2
    assert message.format(tmp=tmp_path) in capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("args, message", [
    (["--episodes", "0"], "argument --episodes: must be a positive integer, got '0'"),
    ([], "give a RUN_DIR, --expert or both"),
    (["{tmp}/none"], "{tmp}/none does not exist"),
    ([str(RESULTS / "table2" / "push-tqc-seed0")],
     f"{RESULTS / 'table2' / 'push-tqc-seed0'} trained push; this compares pick_and_place"),
    ([str(RESULTS / "reference-timing" / "pick_and_place-tqc-seed0"), "--object-damping", "-1"],
     "object_damping must be >= 0, got -1.0"),
    (["--expert"], "--reference-path {tmp}/none: no panda_mujoco_gym/__init__.py there; give "
                   "the folder of a checkout of the reference code's repository")])
def test_cross_play_names_a_bad_argument_before_it_plays(args, message, tmp_path):
    checkout = tmp_path / "reference"  # Holds a checkout's marker, so the rest is read.
    (checkout / "panda_mujoco_gym").mkdir(parents=True)
    (checkout / "panda_mujoco_gym" / "__init__.py").write_text("")
    reference = tmp_path / "none" if "--expert" in args else checkout
    args = [arg.format(tmp=tmp_path) for arg in args]
    completed = subprocess.run([sys.executable, str(EXPERIMENTS / "cross_play.py"),
                                "--reference-path", str(reference), *args],
                               capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert completed.stderr.strip().splitlines()[-1].endswith(message.format(tmp=tmp_path))


def test_grasp_margin_keeps_the_block_where_the_reference_timing_does_and_not_elsewhere():
    """The scripted grasp holds the block at -1 in every suite of this package, drops it at
    -0.1 with 0.5 s steps and the stiff weld, and the hand's motion within a step is read
    back as the weld sets it (0.05 s into a 5 cm move: 94-95 % with 0.01 s, 70-71 % with
    0.02 s); a grasp 15 mm off-centre holds, one 20 mm off along the closing axis does not."""
    module = load_script(EXPERIMENTS / "grasp_margin.py")
    for suite, weak_held, share in (("ours_reference_timing", True, (0.68, 0.73)),
                                    ("stiff_weld", False, (0.93, 0.96))):
        env = module.make_env(suite, None)
        script = module.Script(env)
        assert module.attempt(script, seed=2, squeeze=-1.0)["held"]
        assert module.attempt(script, seed=2, squeeze=-0.1)["held"] == weak_held
        motion = module.hand_motion(env, suite, seed=2, axis=2)
        assert share[0] < motion["at_0.05"] < share[1]
        assert motion["at_0.5"] == pytest.approx(1.0, abs=1e-3)
        # Off the block's centre along the fingers' closing axis (y), an open finger lands
        # on the block's top from 20 mm on: the hand stops there and grasps nothing.
        grasp = module.attempt(script, seed=2, squeeze=-1.0, off_centre=(0.0, 0.015))
        assert grasp["held"] and grasp["stopped_above_mm"] < 3
        grasp = module.attempt(script, seed=2, squeeze=-1.0, off_centre=(0.0, 0.02))
        assert not grasp["held"] and grasp["stopped_above_mm"] > 20
        env.close()


def test_grasp_reach_finds_the_guard_holding_a_finger_on_the_block_top(monkeypatch):
    """25 mm off the block's centre along the closing axis, an open finger comes down on the
    block's top edge: the guard stops the hand on it, pressing nothing; let go, the finger
    sinks into the block by about the overlap (5 mm) under tens of newtons, the block is
    shoved aside and the grasp holds. The changes stay in the one env (and the guard's class
    is restored after the test)."""
    from franka_composer.surface_guard import BoundSurfaceGuard

    module = load_script(EXPERIMENTS / "grasp_reach.py")
    monkeypatch.setattr(BoundSurfaceGuard, "guard", BoundSurfaceGuard.guard)

    def reach(*changes):
        env = module.grasp_margin.make_env("ours_reference_timing", None)
        env.reset(seed=0)
        for change in changes:
            change(env)
        script, watcher = module.grasp_margin.Script(env), module.watch(env)
        descent = {}
        row = module.grasp_margin.attempt(
            script, 2, -1.0, (0.0, 0.025),
            descended=lambda: descent.update(press=watcher.press, depth=watcher.depth))
        env.close()
        return {**row, **descent}

    guarded = reach()
    assert not guarded["held"] and guarded["stopped_above_mm"] > 20
    assert guarded["press"] < 1.0 and guarded["depth"] < 1e-3 and guarded["shoved_mm"] < 1
    softer = reach(module.reference_block)  # The block's own contacts change nothing here.
    assert not softer["held"] and softer["stopped_above_mm"] > 20
    let_go = reach(module.let_guard_go)
    assert let_go["held"] and let_go["stopped_above_mm"] < 1
    assert let_go["press"] > 20 and 0.004 < let_go["depth"] < 0.007
    assert 3 < let_go["shoved_mm"] < 7


def test_hand_on_top_counts_a_hand_stopped_on_the_block_and_not_one_beside_it():
    import gymnasium as gym

    module = load_script(EXPERIMENTS / "hand_on_top.py")
    on_top = np.array([0.005, 0.025, 0.027])  # A finger's tip on the top, 25 mm off.
    assert module.held_on_top(on_top, width=0.08, action_z=-1.0, came_down=0.0)
    assert not module.held_on_top(on_top, width=0.08, action_z=-0.2, came_down=0.0)  # Not down.
    assert not module.held_on_top(on_top, width=0.08, action_z=-1.0, came_down=0.01)  # Moving.
    assert not module.held_on_top(on_top, width=0.03, action_z=-1.0, came_down=0.0)  # Closed.
    assert not module.held_on_top(on_top + [0.0, 0.0, 0.01], 0.08, -1.0, 0.0)  # Above it.
    assert not module.held_on_top(on_top + [0.0, 0.04, 0.0], 0.08, -1.0, 0.0)  # Beside it.
    assert module.at_block_height(np.array([0.0, 0.02, 0.0]))
    assert not module.at_block_height(np.array([0.0, 0.02, 0.027]))
    # Through the wrapper: down onto the top, then held there twice, the episode ending.
    steps = iter([(on_top, 0.08)] * 3)

    class Env(gym.Env):
        observation_space, action_space = None, None

        def reset(self, **kwargs):
            return self._obs(np.array([0.0, 0.0, 0.1]), 0.08), {}

        def step(self, action):
            offset, width = next(steps)
            done = action[0] > 0
            return self._obs(offset, width), 0.0, False, done, {}

        @staticmethod
        def _obs(offset, width):
            observation = np.zeros(19)
            observation[:3], observation[6] = offset + [0.6, 0.0, 0.02], width
            return {"observation": observation, "achieved_goal": np.array([0.6, 0.0, 0.02])}

    wrapped = module.HandOnTop(Env())
    wrapped.reset()
    wrapped.step(np.array([0.0, 0.0, -1.0, 1.0]))  # Came down 7 cm onto the top.
    wrapped.step(np.array([0.0, 0.0, -1.0, 1.0]))  # Held there.
    wrapped.step(np.array([1.0, 0.0, -1.0, 1.0]))  # Held there; the episode ends.
    assert wrapped.rows == [(2, 0, False, False)]
    # A block tipped onto an edge about x (its centre 8 mm up, not lifted) reads tipped.
    assert module.tipped(np.array([np.pi / 4, 0.0])) and module.tipped(np.array([0.0, -0.5]))
    assert not module.tipped(np.array([0.1, -0.1]))


@pytest.mark.slow
def test_render_backends_saves_the_scene_the_committed_frames_show(tmp_path, capsys):
    module = load_script(EXPERIMENTS / "render_backends.py")
    committed = RESULTS / "render-backends"
    module.compare(committed / "nvidia-h100.npz", committed / "llvmpipe.npz")
    report = json.loads(capsys.readouterr().out)
    assert report == json.loads((committed / "comparison.json").read_text())
    assert report["observations"]["max"] == 3 and report["renders"]["pixels_over_8"] == 2
    module.save(str(tmp_path / "here.npz"))
    assert "renderer" in json.loads(capsys.readouterr().out)
    module.compare(tmp_path / "here.npz", committed / "llvmpipe.npz")
    here = json.loads(capsys.readouterr().out)
    # This machine's GL draws the committed episode: within it, frames one step apart (the
    # arm a few centimetres further) differ by a mean of 3.7 levels.
    assert here["observations"]["shape"] == [21, 84, 84, 3]
    assert here["observations"]["mean"] < 0.5 and here["renders"]["mean"] < 0.5
    module.compare(tmp_path / "here.npz", committed / "nvidia-h100.npz")
    assert json.loads(capsys.readouterr().out)["observations"]["max"] <= 8


#: A run of a few hundred steps that trains, evaluates and checkpoints in seconds.
TINY_TRAINING = ["--net-arch", "16,16", "--batch-size", "32", "--learning-starts", "100",
                 "--eval-every", "100", "--eval-episodes", "2", "--threads", "1",
                 "--no-progress", "--device", "cpu", "--seed", "1"]


def train_in_another_env(monkeypatch, script: str):
    """The experiments/ `script` that registers another environment, loaded with what it
    installs (`models.ENVIRONMENTS`, `train`'s run_config) put back after the test."""
    from franka_composer.cli import train as train_cli
    from franka_composer.training import models

    module = load_script(EXPERIMENTS / script)
    monkeypatch.setattr(models, "ENVIRONMENTS", {})
    monkeypatch.setattr(train_cli, "run_config", train_cli.run_config)
    return module


def assert_refused_without_the_script(out: pathlib.Path, environment: str) -> None:
    """Neither resumed nor evaluated by a process that cannot build its `environment`."""
    message = (f"the run trained in {environment} environment, which this process does not "
               "build: train, evaluate or play it through the experiments/ script that "
               "trained it")
    with pytest.raises(ValueError, match=re.escape(message)):
        main(["train", "--resume", "--out", str(out), "--total-steps", "300"])
    with pytest.raises(ValueError, match=re.escape(message)):
        main(["evaluate", str(out), "--episodes", "1"])


@pytest.mark.slow
def test_a_run_in_another_suites_env_is_trained_there_and_refused_elsewhere(tmp_path,
                                                                           monkeypatch):
    # This suite's push spec stands in for the reference code's (not on PyPI, not in CI).
    import gymnasium as gym

    from franka_composer.training import exact_resume
    from franka_composer.training.runs import RunDir, read_eval_rows

    module = train_in_another_env(monkeypatch, "reference_env_runs.py")
    for name in ("save", "restore"):
        monkeypatch.setattr(exact_resume, name, getattr(exact_resume, name))
    # This suite's env keeps its MjData inside dm_control's physics.
    monkeypatch.setattr(module, "training_physics",
                        lambda model: model.get_env().envs[0].unwrapped._env.physics.data)
    module.install({"push": gym.spec("FrankaPushSparse-v0")})
    out = tmp_path / "run"
    assert main(["train", "--task", "push", "--algo", "sac", "--out", str(out),
                 "--total-steps", "200", *TINY_TRAINING]) == 0
    config = RunDir(out).read_config()
    assert config.environment == "panda_mujoco_gym"
    assert config.variant == "net_arch 16,16, batch_size 32, panda_mujoco_gym's env"
    assert json.loads((out / "config.json").read_text())["environment"] == "panda_mujoco_gym"
    assert [row["steps"] for row in read_eval_rows(RunDir(out).eval_csv)] == [0, 100, 200]
    kept = pickle.loads(RunDir(out).checkpoint_generators.read_bytes())
    assert {"stream", "torch", "numpy"} <= kept.keys()
    assert list(kept["panda_mujoco_gym"]) == ["qacc_warmstart"]
    assert kept["panda_mujoco_gym"]["qacc_warmstart"].shape == (15,)  # arm 7, fingers 2, box 6
    for options, named in ((["--control", "osc"], "--control osc"),
                           (["--timing", "reference"], "--timing or --control-timestep"),
                           (["--object-damping", "0.01"], "--object-damping 0.01"),
                           (["--no-terminate-on-success"], "--no-terminate-on-success"),
                           (["--task", "reach"], "--task reach (the reference code has push)")):
        refused = tmp_path / "refused"
        arguments = ["train", "--algo", "sac", "--out", str(refused), *TINY_TRAINING, *options]
        if "--task" not in options:
            arguments += ["--task", "push"]
        with pytest.raises(ValueError, match=re.escape(f"{named} cannot be given with it")):
            main(arguments)
        assert not refused.exists()
    monkeypatch.undo()  # A process without the script: the run's env cannot be made.
    assert_refused_without_the_script(out, "panda_mujoco_gym's push")
    with pytest.raises(ValueError, match=re.escape(
            f"{out} trained in panda_mujoco_gym's push environment, not this suite's")):
        main(["rollout", "--task", "push", "--policy", str(out), "--episodes", "1",
              "--out", str(tmp_path / "played.npz")])
    assert not (tmp_path / "played.npz").exists()
    assert RunDir(out).read_state()["steps"] == 200


@pytest.mark.slow
def test_an_unguarded_run_trains_with_the_guard_let_go_and_is_refused_elsewhere(tmp_path,
                                                                              monkeypatch):
    from franka_composer.surface_guard import BoundSurfaceGuard
    from franka_composer.training import models
    from franka_composer.training.runs import RunDir, read_eval_rows

    module = train_in_another_env(monkeypatch, "altered_runs.py")
    name = module.ALTERATIONS["unguarded"][0]
    monkeypatch.setattr(BoundSurfaceGuard, "guard", BoundSurfaceGuard.guard)
    out = tmp_path / "run"
    assert module.main(["unguarded", "train", "--task", "pick_and_place", "--algo", "sac",
                        "--timing", "reference", "--out", str(out), "--total-steps", "200",
                        *TINY_TRAINING]) == 0
    config = RunDir(out).read_config()
    assert json.loads((out / "config.json").read_text())["environment"] == name
    assert config.variant == ("net_arch 16,16, batch_size 32, unguarded franka_composer's "
                              "env, reference timing")
    assert [row["steps"] for row in read_eval_rows(RunDir(out).eval_csv)] == [0, 100, 200]
    # Its envs send the hand's target as deep as the action says, down to z = 0: full
    # downward steps from the start reach 5 cm below the hand where the floor stops the
    # guarded hand's target 7.2 mm above it (the fingertips on the floor).
    env = models.make_env("pick_and_place", environment=name)
    env.reset(seed=0)
    law = env.unwrapped.task.controller.law
    for _ in range(5):
        tcp = env.unwrapped.task.controller.law._tcp_pos[2]
        env.step(np.array([0.5, 0.0, -1.0, 0.0], dtype=np.float32))
    assert law._target[2] == pytest.approx(max(0.0, tcp - 0.05), abs=1e-9)
    assert law._target[2] < 0.002
    env.close()
    monkeypatch.undo()  # A process without the script: the guard is back, the run refused.
    assert_refused_without_the_script(out, "unguarded franka_composer's pick_and_place")
    env = models.make_env("pick_and_place")
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.array([0.5, 0.0, -1.0, 0.0], dtype=np.float32))
    assert env.unwrapped.task.controller.law._target[2] == pytest.approx(0.0072, abs=5e-4)
    env.close()


@pytest.mark.slow
def test_a_reference_physics_run_trains_with_every_difference_undone(tmp_path, monkeypatch):
    from franka_composer.surface_guard import BoundSurfaceGuard
    from franka_composer.training import models
    from franka_composer.training.runs import RunDir

    module = train_in_another_env(monkeypatch, "altered_runs.py")
    differences = load_script(EXPERIMENTS / "env_differences.py")
    name = module.ALTERATIONS["reference_physics"][0]
    monkeypatch.setattr(BoundSurfaceGuard, "guard", BoundSurfaceGuard.guard)
    out = tmp_path / "run"
    assert module.main(["reference_physics", "train", "--task", "pick_and_place", "--algo",
                        "sac", "--timing", "reference", "--out", str(out), "--total-steps",
                        "200", *TINY_TRAINING]) == 0
    assert RunDir(out).read_config().environment == name
    env = models.make_env("pick_and_place", environment=name)
    expected = differences.make_undone(set(differences.DIFFERENCES))
    try:
        model, undone = (each.unwrapped.composer_env.physics.model for each in (env, expected))
        assert_same_reference_physics(model, undone)
        assert model.opt.noslip_iterations == 3
        assert env.reset(seed=0)[0]["observation"][6] == pytest.approx(0.0, abs=1e-3)
        law = env.unwrapped.task.controller.law
        for _ in range(5):  # The target as deep as the action sends it (the unguarded test).
            env.step(np.array([0.5, 0.0, -1.0, 0.0], dtype=np.float32))
        assert law._target[2] < 0.002
    finally:
        env.close()
        expected.close()


def test_a_damped_block_run_damps_the_block_in_every_env_it_builds(monkeypatch):
    """The block's free joint damped as the reference code's in the envs the script builds
    (as push_tip.py damps the compiled model), and a push that tips the undamped block over
    slides the damped one."""
    module = train_in_another_env(monkeypatch, "altered_runs.py")
    push_tip = load_script(EXPERIMENTS / "push_tip.py")
    from franka_composer.training import models

    name = module.ALTERATIONS["damped_block"][0]
    module.install("damped_block")
    pushed = {}
    for environment in (None, name):
        env = models.make_env("pick_and_place", environment=environment,
                              terminate_on_success=False, control_timestep=0.5,
                              velocity_timestep=0.05, weld_time_constant=0.02)
        env.reset(seed=0)
        physics = env.unwrapped.composer_env.physics
        damping = physics.model.dof_damping.copy()
        assert list(damping[-6:]) == ([0.0] * 6 if environment is None else [0.01] * 6)
        if environment is None:  # The block's free joint comes last.
            push_tip.reference_block_damping(env)
            np.testing.assert_array_equal(physics.model.dof_damping, np.r_[damping[:-6],
                                                                           [0.01] * 6])
            physics.model.dof_damping[:] = damping
        script = push_tip.grasp_margin.Script(env)
        watcher = push_tip.grasp_reach.watch(env.unwrapped)
        pushed[environment] = push_tip.push(script, watcher, 1, 0.0)
        env.close()
    assert pushed[None]["tipped"] and not pushed[name]["tipped"]
    assert pushed[name]["slide_mm"] > 100


def test_the_damped_block_check_trains_as_train_object_damping_does(tmp_path, monkeypatch):
    """The damped-block cell began (frozen tree 42d36b4) with the damping set in the compiled
    model after each reset, as push_tip.py still sets it; `train --object-damping 0.01`
    builds it into the model: a run stores the same transitions both ways, bit for bit."""
    import gymnasium as gym
    from stable_baselines3.common.save_util import load_from_pkl

    from franka_composer.training import models
    from franka_composer.training.runs import RunDir

    module = train_in_another_env(monkeypatch, "altered_runs.py")
    push_tip = load_script(EXPERIMENTS / "push_tip.py")

    class DampedAfterReset(gym.Wrapper):
        def reset(self, **kwargs):
            result = self.env.reset(**kwargs)
            push_tip.reference_block_damping(self.env)
            return result

    name = module.ALTERATIONS["damped_block"][0]
    monkeypatch.setitem(module.ALTERATIONS, "damped_block", (name, lambda task, **options: (
        DampedAfterReset(models.make_env(task, **options)))))
    common = ["--task", "pick_and_place", "--algo", "sac", "--timing", "reference",
              "--total-steps", "300", "--checkpoint-every", "100", *TINY_TRAINING]
    assert module.main(["damped_block", "train", "--out", str(tmp_path / "wrapped"),
                        *common]) == 0
    assert main(["train", "--out", str(tmp_path / "option"), "--object-damping", "0.01",
                 *common]) == 0
    wrapped, option = (load_from_pkl(RunDir(tmp_path / run).checkpoint_buffer)
                       for run in ("wrapped", "option"))
    assert wrapped.pos == option.pos == 300
    for key in wrapped.observations:
        np.testing.assert_array_equal(wrapped.observations[key], option.observations[key])
    np.testing.assert_array_equal(wrapped.actions, option.actions)


def test_a_reference_env_checkpoint_keeps_the_warm_start_its_reset_leaves(tmp_path):
    # The reference env's reset keeps MuJoCo's solver warm start from the episode before;
    # a resume rebuilds the env by resets alone, so the checkpoint must give it back.
    import types

    import mujoco

    module = load_script(EXPERIMENTS / "reference_env_runs.py")
    data = mujoco.MjData(mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody></mujoco>"))
    env = types.SimpleNamespace(unwrapped=types.SimpleNamespace(data=data))
    model = types.SimpleNamespace(get_env=lambda: types.SimpleNamespace(envs=[env]))
    path = tmp_path / "generators.pkl"

    def save(model, stream, path):
        path.write_bytes(pickle.dumps({"stream": stream}))

    data.qacc_warmstart[:] = np.arange(1.0, 7.0)
    module.saving_carried_state(save)(model, {"seed": 3}, path)
    assert pickle.loads(path.read_bytes())["stream"] == {"seed": 3}
    data.qacc_warmstart[:] = 0.0
    assert module.restoring_carried_state(lambda model, path: "stream")(model, path) == "stream"
    np.testing.assert_array_equal(data.qacc_warmstart, np.arange(1.0, 7.0))
    data.qacc_warmstart[:] = 0.0  # A restore that found the env changed keeps it as it is.
    assert module.restoring_carried_state(lambda model, path: None)(model, path) is None
    np.testing.assert_array_equal(data.qacc_warmstart, np.zeros(6))


def test_the_pick_and_place_checks_script_says_where_a_check_stands(tmp_path):
    """Not started, or stopped with its checkpoint's step and its last evaluation; nothing
    made."""
    def status():
        completed = subprocess.run(
            ["bash", str(EXPERIMENTS / "pick_and_place_checks.sh"), "status", "unguarded"],
            capture_output=True, text=True, check=True,
            env={**os.environ, "RUNS": str(tmp_path)})
        return completed.stdout.strip()

    out = tmp_path / "unguarded" / "pick_and_place-tqc-seed0"
    assert status() == f"unguarded: not started ({out})"
    assert list(tmp_path.iterdir()) == []
    (out / "checkpoint-2004-abc").mkdir(parents=True)
    (out / "checkpoint-2004-abc" / "state.json").write_text(
        json.dumps({"steps": 2004, "wall_time_s": 1.5, "exact": True}))
    (out / "checkpoint").symlink_to("checkpoint-2004-abc")
    (out / "eval.csv").write_text("steps,wall_time_s,success_rate,mean_reward\n"
                                  "0,1.0,0.0,-50.0\n2000,9.5,0.2,-40.0\n")
    assert status() == ("unguarded: stopped; checkpoint at step 2004; last evaluation "
                        "(step,success): 2000,0.2")
    # SEED picks the run: seed 1 of the SB3 check lies in a folder of its own.
    completed = subprocess.run(
        ["bash", str(EXPERIMENTS / "pick_and_place_checks.sh"), "status", "reference_env_sb3"],
        capture_output=True, text=True, check=True,
        env={**os.environ, "RUNS": str(tmp_path), "SEED": "1"})
    assert completed.stdout.strip() == ("reference_env_sb3: not started "
                                        f"({tmp_path}/reference-env-sb3/pick_and_place-tqc-seed1)")
    # Each check in a folder of its own: those with 1e5 random steps first too.
    for check, folder in [("reference_env_learning_starts", "reference-env-learning-starts"),
                          ("reference_physics_learning_starts",
                           "reference-physics-learning-starts"),
                          ("damped_block_learning_starts", "damped-block-learning-starts")]:
        completed = subprocess.run(
            ["bash", str(EXPERIMENTS / "pick_and_place_checks.sh"), "status", check],
            capture_output=True, text=True, check=True,
            env={**os.environ, "RUNS": str(tmp_path), "RESULTS": str(tmp_path / "kept")})
        assert completed.stdout.strip() == (
            f"{check}: not started ({tmp_path}/{folder}/pick_and_place-tqc-seed0)")
    # Evaluations kept (RESULTS) beyond the run's: lost with its machine, to be retraced.
    kept = tmp_path / "kept" / "unguarded" / "pick_and_place-tqc-seed0"
    kept.mkdir(parents=True)
    (kept / "eval.csv").write_text("steps,wall_time_s,success_rate,mean_reward\n"
                                   "0,1.0,0.0,-50.0\n2000,9.5,0.2,-40.0\n4000,19.0,0.1,-45.0\n")
    completed = subprocess.run(
        ["bash", str(EXPERIMENTS / "pick_and_place_checks.sh"), "status", "unguarded"],
        capture_output=True, text=True, check=True,
        env={**os.environ, "RUNS": str(tmp_path), "RESULTS": str(tmp_path / "kept")})
    assert completed.stdout.splitlines()[1] == (
        f"pick_and_place-tqc-seed0: evaluations kept to step 4,000 in {kept.parent}; its run "
        "here has retraced them to step 2,000 (a run begun again from zero retraces them, "
        "and is kept once it has passed them)")


@pytest.mark.parametrize("args, seed, message", [
    ([], "0", "experiments/pick_and_place_checks.sh run CHECK"),
    (["run"], "0", "experiments/pick_and_place_checks.sh run CHECK"),
    (["start", "damped_block"], "0", "experiments/pick_and_place_checks.sh run CHECK"),
    (["run", "damped"], "0", "CHECK must be damped_block, unguarded, reference_physics, "
                             "reference_env, reference_env_sb3, learning_starts, "
                             "reference_env_learning_starts, "
                             "reference_physics_learning_starts or "
                             "damped_block_learning_starts, not damped"),
    (["run", "reference_env"], "one", "SEED must be a whole number, not one"),
])
def test_the_pick_and_place_checks_script_names_a_bad_command(tmp_path, args, seed, message):
    """Its usage, the checks it knows, or a seed that is not one, before anything is made
    or started."""
    completed = subprocess.run(
        ["bash", str(EXPERIMENTS / "pick_and_place_checks.sh"), *args],
        capture_output=True, text=True, check=False,
        env={**os.environ, "RUNS": str(tmp_path), "SEED": seed})
    assert completed.returncode == 2
    assert message in completed.stdout + completed.stderr
    assert list(tmp_path.iterdir()) == []


def test_actor_saturation_reads_the_gaussian_each_backend_acts_on(tmp_path):
    """tanh of the pre-tanh mean it reads is the deterministic action, on SB3 and on sbx, for
    a full model and for a policy file; the coefficient is the learnt one, None in a policy
    file; the two corrections agree where they should and part by the figures its docstring
    gives."""
    module = load_script(EXPERIMENTS / "actor_saturation.py")
    from franka_composer.training.models import make_env
    from franka_composer.training.policy_file import load_trained
    from franka_composer.training.runs import RunDir

    for backend in ("sb3", "sbx"):
        out = tmp_path / backend
        assert main(["train", "--task", "push", "--algo", "tqc", "--backend", backend,
                     "--out", str(out), "--total-steps", "150", *TINY_TRAINING]) == 0
        env = make_env("push")
        observation, _ = env.reset(seed=3)
        model = load_trained(RunDir(out), env, device="cpu")
        mean, std = module.gaussian_parameters(model, observation)
        action, _ = model.predict(observation, deterministic=True)
        assert mean.shape == std.shape == env.action_space.shape and np.all(std > 0)
        np.testing.assert_allclose(np.tanh(mean), action, rtol=0, atol=1e-6)
        assert 0 < module.entropy_coefficient(model) < 1  # From 1.0, after 50 updates.
        # The run as committed: its policy file alone, no model.zip, no checkpoint.
        (out / "model.zip").unlink()
        for checkpoint in sorted(out.glob("checkpoint*"), key=pathlib.Path.is_symlink,
                                 reverse=True):
            if checkpoint.is_symlink():
                checkpoint.unlink()
            else:
                shutil.rmtree(checkpoint)
        policy_only = load_trained(RunDir(out), env, device="cpu")
        np.testing.assert_allclose(module.gaussian_parameters(policy_only, observation)[0],
                                   mean, rtol=0, atol=1e-5)
        assert module.entropy_coefficient(policy_only) is None
        env.close()
    u = np.array([2.0, 3.0, 6.0, 10.0])
    np.testing.assert_allclose(module.exact_correction(u[:1]), np.log(1 - np.tanh(2.0) ** 2),
                               rtol=1e-12)
    gap = module.sb3_correction(u) - module.exact_correction(u)
    assert gap[1] < 1e-3 and gap[2] < 0.04 and gap[3] == pytest.approx(4.8, abs=0.01)


@pytest.mark.parametrize("change, message", [
    ({}, "trained in the reference code's env: give --reference-path"),
    ({"algo": "ddpg"}, "trained ddpg; only SAC and TQC squash a Gaussian"),
])
def test_actor_saturation_names_what_it_cannot_play(tmp_path, change, message):
    config = json.loads((EXPERIMENTS.parent / "results/reference-env/pick_and_place-tqc-seed0"
                         / "config.json").read_text())
    (tmp_path / "config.json").write_text(json.dumps({**config, **change}))
    completed = subprocess.run([sys.executable, str(EXPERIMENTS / "actor_saturation.py"),
                                str(tmp_path)], capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert message in completed.stderr


@pytest.mark.parametrize("threshold", ["0", "-1", "nan", "inf", "six"])
def test_actor_saturation_refuses_a_threshold_that_is_not_a_positive_number(tmp_path, threshold):
    completed = subprocess.run([sys.executable, str(EXPERIMENTS / "actor_saturation.py"),
                                str(tmp_path), "--threshold", threshold],
                               capture_output=True, text=True, check=False)
    assert completed.returncode == 2
    assert f"argument --threshold: must be a number > 0, got '{threshold}'" in completed.stderr


def test_held_rays_counts_what_docs_give_for_the_experts():
    """docs/guide/physics.md's count, as `held_rays.py --expert stack pick_and_place`
    measures it: over 30 episodes of stack's expert, 166 of the guard's 383 probes from the
    hand meet the block it holds, in each the nearest surface found (29 episodes succeed);
    with held bodies left out of the rays, 47 of 261 meet it and 30 succeed. Pick-and-place's expert
    meets none. The guard's own ray cast is back once the script is done."""
    from franka_composer.surface_guard import BoundSurfaceGuard

    module = load_script(EXPERIMENTS / "held_rays.py")
    original = BoundSurfaceGuard._lowest_hit
    probes = module.Probes()
    with module.watching_rays(probes, exclude_held=False):
        stack = module.expert_rows("stack", 30, 0, probes)
        pick = module.expert_rows("pick_and_place", 30, 0, probes)
    with module.watching_rays(probes, exclude_held=True):
        excluded = module.expert_rows("stack", 30, 0, probes)
    assert BoundSurfaceGuard._lowest_hit is original
    assert stack.sum(axis=0).tolist() == [383, 166, 166, 29]
    assert pick.sum(axis=0).tolist() == [102, 0, 0, 30]
    assert excluded.sum(axis=0).tolist() == [261, 47, 47, 30]


@pytest.mark.parametrize("tasks, message", [
    (["push", "push"], "argument --tasks: names push more than once: each task is run once"),
    (["stack"], "--tasks: stack not pressed here; tasks pressed: push, slide, pick_and_place"),
])
def test_the_controller_press_refuses_tasks_it_does_not_press_once(tasks, message, capsys):
    """Its `--tasks` is every command's (a task named twice refused), and a task whose block
    does not lie on the floor is refused before anything is pressed."""
    module = load_script(EXPERIMENTS / "controller_press.py")
    with pytest.raises(SystemExit) as exit_:
        module.main(["--tasks", *tasks])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


def test_light_angles_measures_the_turn_the_default_randomisation_gives_each_light():
    """The preset's reason quotes it ("within ~30 degrees ..., half the draws within 13")."""
    import math

    module = load_script(EXPERIMENTS / "light_angles.py")
    names, angles = module.light_angles("push", episodes=40, seed=3)
    assert names == ["key", "fill", "panda/top"] and angles.shape == (40, 3)
    # An offset in [-0.3, 0.3]^3 turns a unit vector by at most asin(0.3 * sqrt(3)).
    assert 0 < angles.min() and angles.max() <= math.degrees(math.asin(0.3 * math.sqrt(3)))
    assert 8 < float(np.median(angles)) < 18
    assert (module.light_angles("push", episodes=40, seed=3)[1] == angles).all()
    assert module.table(names, angles).splitlines()[2].startswith("| key | ")
