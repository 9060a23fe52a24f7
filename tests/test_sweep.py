"""`franka-composer sweep`: the grid as data, resumable cells, the live table, and a tiny
two-cell sweep on a local Ray (training/sweep.py, cli/sweep.py)."""

from __future__ import annotations

import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

import pytest

from conftest import write_policy_file
from franka_composer import cli
from franka_composer.training import hyperparameters
from franka_composer.training.run_config import RunConfig
from franka_composer.training.runs import EVAL_COLUMNS, RunDir, read_eval_rows, write_eval_rows
from franka_composer.training.sweep import (GRIDS, Cell, cell_log, cell_status, grid,
                                            run_directories, run_sweep, status_table,
                                            train_command)

REPO = pathlib.Path(__file__).resolve().parents[1]
#: Small enough for seconds per cell (as tests/test_training.py's tiny runs).
TINY = ["--net-arch", "16,16", "--batch-size", "32", "--buffer-size", "2000",
        "--learning-starts", "100", "--eval-every", "100", "--eval-episodes", "2",
        "--threads", "1", "--device", "cpu"]


def test_the_table2_grid_is_issue_15s_budgets():
    cells = {(c.task, c.algo): [] for c in GRIDS["table2"]}
    for cell in GRIDS["table2"]:
        cells[(cell.task, cell.algo)].append((cell.seed, cell.steps, cell.options))
    # SAC in bf16, TQC on sbx, DDPG as the paper computed it (RESULTS.md says why).
    sac, tqc = ("--precision", "bf16"), ("--backend", "sbx")
    slide = ("--net-arch", "256,256,256", "--batch-size", "512")
    expected = {
        ("push", "sac"): (3, 250_000, sac), ("push", "tqc"): (3, 250_000, tqc),
        ("push", "ddpg"): (3, 150_000, ()),
        ("pick_and_place", "sac"): (3, 400_000, sac),
        ("pick_and_place", "tqc"): (3, 400_000, tqc),
        ("pick_and_place", "ddpg"): (1, 200_000, ()),
        ("slide", "sac"): (3, 200_000, slide + sac), ("slide", "tqc"): (3, 200_000, slide + tqc),
        ("slide", "ddpg"): (1, 200_000, slide),
    }
    assert set(cells) == set(expected)
    for key, (seeds, steps, options) in expected.items():
        assert cells[key] == [(seed, steps, options) for seed in range(seeds)], key
    assert len(GRIDS["table2"]) == 23


def test_a_grid_takes_one_budget_or_one_per_task():
    cells = grid(["push", "slide"], ["sac"], [0, 1], {"push": 10, "slide": 20})
    assert [(c.name, c.steps) for c in cells] == [
        ("push-sac-seed0", 10), ("push-sac-seed1", 10), ("slide-sac-seed0", 20),
        ("slide-sac-seed1", 20)]
    assert {c.steps for c in grid(["push"], ["sac", "tqc"], [0], 5)} == {5}


def test_a_cell_starts_with_its_options_and_resumes_with_what_still_applies(tmp_path):
    cell = Cell("slide", "tqc", 2, 1000, ("--net-arch", "8,8"))
    args = ("--threads", "1", "--update-schedule", "episode", "--device=cpu")
    start = train_command(cell, tmp_path, args)
    assert start[:4] == [sys.executable, "-m", "franka_composer", "train"]
    assert start[4:] == ["--out", str(tmp_path / "slide-tqc-seed2"), "--total-steps", "1000",
                         "--no-progress", "--task", "slide", "--algo", "tqc", "--seed", "2",
                         "--net-arch", "8,8", *args]
    resume = train_command(cell, tmp_path, args, resume=True)
    assert resume[4:] == ["--out", str(tmp_path / "slide-tqc-seed2"), "--total-steps", "1000",
                          "--no-progress", "--resume", "--threads", "1", "--device=cpu"]


@pytest.mark.skipif(sys.version_info < (3, 11), reason="PYTHONSAFEPATH is Python 3.11's")
def test_a_cell_trains_the_franka_composer_the_sweep_imported_not_one_in_its_directory(
        tmp_path, monkeypatch):
    import os

    import franka_composer
    from franka_composer.training.sweep import cell_environment, run_cell

    started_in = tmp_path / "elsewhere"  # Another checkout, where the sweep was started.
    (started_in / "franka_composer").mkdir(parents=True)
    (started_in / "franka_composer" / "__init__.py").write_text("")
    (started_in / "franka_composer" / "__main__.py").write_text(
        "print('the other checkout'); raise SystemExit(3)")
    cell = Cell("push", "sac", 0, 200)
    interpreter = train_command(cell, tmp_path, ())[:3]
    plain = subprocess.run(interpreter, cwd=started_in, capture_output=True, text=True)
    assert (plain.returncode, plain.stdout) == (3, "the other checkout\n")  # What -m does.
    imported = subprocess.run(
        [sys.executable, "-c", "import franka_composer; print(franka_composer.__file__)"],
        cwd=started_in, capture_output=True, text=True, env=cell_environment())
    assert imported.stdout == franka_composer.__file__ + "\n"
    monkeypatch.chdir(started_in)
    assert run_cell(cell, tmp_path / "runs", tuple(TINY)) == ("push-sac-seed0", 0)
    assert RunDir(tmp_path / "runs" / "push-sac-seed0").read_outcome()["steps"] == 200
    # PYTHONPATH as the caller set it stays, after the sweep's franka_composer.
    tree = os.path.dirname(os.path.dirname(franka_composer.__file__))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path / "mine"), tree]))
    assert cell_environment()["PYTHONPATH"].split(os.pathsep) == [tree, str(tmp_path / "mine")]


def _write_run(root, name, rows, outcome=None, seed=0, precision="fp32"):
    run = RunDir(root / name)
    run.write_config(RunConfig("push", "sac", seed, hyperparameters("push", "sac"),
                               precision=precision))
    run.eval_csv.write_text("steps,wall_time_s,success_rate,mean_reward\n" + "".join(
        f"{steps},{wall},{rate},-1\n" for steps, wall, rate in rows))
    if outcome:
        run.write_outcome(*outcome)
    return run


def test_the_status_of_each_cell_is_read_from_its_directory(tmp_path):
    cells = grid(["push"], ["sac"], [0, 1, 2, 3], 4000)
    _write_run(tmp_path, "push-sac-seed0", [(0, 1, 0.0), (2000, 101, 0.2), (4000, 201, 0.6)],
               (4000, False, 201))
    _write_run(tmp_path, "push-sac-seed1", [(0, 1, 0.0), (2000, 51, 1.0)], (2000, True, 51))
    _write_run(tmp_path, "push-sac-seed2", [(0, 1, 0.0), (2000, 41, 0.4)])
    statuses = [cell_status(cell, tmp_path) for cell in cells]
    assert [(s.state, s.steps, s.success_rate) for s in statuses] == [
        ("done", 4000, 0.6), ("stopped early", 2000, 1.0), ("unfinished", 2000, 0.4),
        ("waiting", 0, None)]
    assert statuses[0].steps_per_s == pytest.approx(20.0)  # 2000 steps in 100 s.
    assert statuses[2].steps_per_s == pytest.approx(50.0)
    assert cell_status(cells[2], tmp_path, running=True, queued=True).state == "running"
    assert cell_status(cells[2], tmp_path, queued=True).state == "queued"
    assert cell_status(cells[3], tmp_path, queued=True).state == "queued"
    assert cell_status(cells[2], tmp_path, failed=True).state == "failed"
    with RunDir(tmp_path / "push-sac-seed2").training_lock():  # `--status` from elsewhere.
        assert cell_status(cells[2], tmp_path).state == "running"
    table = status_table(statuses).splitlines()
    assert table[0] == "| cell | state | steps | budget | steps/s | latest success |"
    assert table[2] == "| push-sac-seed0 | done | 4,000 | 4,000 | 20.0 | 60 % |"
    assert table[5] == "| push-sac-seed3 | waiting | 0 | 4,000 | – | – |"
    # A run that went on with a fresh episode stream says where, finished or not.
    _write_run(tmp_path, "push-sac-seed0", [(0, 1, 0.0), (4000, 201, 0.6)],
               (4000, False, 201, 201, [2004]))
    assert cell_status(cells[0], tmp_path).state == "done (fresh episode stream from 2,004)"
    run = RunDir(tmp_path / "push-sac-seed2")
    run.checkpoint.mkdir()
    run.checkpoint_state.write_text(json.dumps({"steps": 2050, "fresh_streams": [1010, 2050]}))
    assert (cell_status(cells[2], tmp_path).state
            == "unfinished (fresh episode stream from 1,010, 2,050)")
    # And one that went on on another machine, from the step it began there.
    here = {"cpu": "AMD EPYC", "vector_isa": ["avx2"], "python": "3.11.7", "libraries": {}}
    machines = [{"from_steps": 0, **here}, {"from_steps": 1010, **here, "cpu": "Intel"}]
    run.checkpoint_state.write_text(json.dumps({"steps": 2050, "fresh_streams": [],
                                                "machines": machines}))
    assert cell_status(cells[2], tmp_path).state == "unfinished (another machine from 1,010)"
    _write_run(tmp_path, "push-sac-seed0", [(0, 1, 0.0), (4000, 201, 0.6)],
               (4000, False, 201, 201, [], machines[:1]))
    assert cell_status(cells[0], tmp_path).state == "done"


def test_the_evaluations_a_resume_keeps_end_at_the_checkpoint_until_the_run_ends(tmp_path):
    run = _write_run(tmp_path, "push-sac-seed0", [(0, 1, 0.0), (2000, 2, 0.2), (4000, 3, 0.4)])
    assert [r["steps"] for r in run.kept_evaluations()] == [0, 2000, 4000]  # No checkpoint.
    run.checkpoint.mkdir()
    run.checkpoint_state.write_text(json.dumps({"steps": 2000}))
    assert [r["steps"] for r in run.kept_evaluations()] == [0, 2000]
    run.write_outcome(4000, False, 3.0)
    assert [r["steps"] for r in run.kept_evaluations()] == [0, 2000, 4000]


def test_sync_keeps_what_each_cell_has_kept_and_its_policy_once_finished(tmp_path, capsys):
    runs, kept = tmp_path / "runs", tmp_path / "kept"
    done = _write_run(runs, "push-sac-seed0", [(0, 1, 0.0), (2000, 2, 0.6)], (2000, False, 2))
    write_policy_file(done.policy_file, 10)
    going = _write_run(runs, "push-sac-seed1", [(0, 1, 0.0), (2000, 2, 0.2), (4000, 3, 0.4)],
                       seed=1)
    going.checkpoint.mkdir()
    going.checkpoint_state.write_text(json.dumps({"steps": 2000}))
    going.policy_file.write_bytes(b"an older budget's")
    sweep = ["sweep", "--out", str(runs), "--tasks", "push", "--algos", "sac", "--seeds", "0",
             "1", "2", "--steps", "2000", "--sync", str(kept)]
    assert cli.main(sweep) == 0
    assert capsys.readouterr().out == f"{kept}: push-sac-seed0, push-sac-seed1\n"
    assert sorted(path.name for path in kept.iterdir()) == ["push-sac-seed0", "push-sac-seed1"]
    copy, unfinished = RunDir(kept / "push-sac-seed0"), RunDir(kept / "push-sac-seed1")
    assert copy.read_config() == done.read_config() and copy.read_outcome()["steps"] == 2000
    assert copy.policy_file.read_bytes() == done.policy_file.read_bytes()
    assert read_eval_rows(copy.eval_csv) == read_eval_rows(done.eval_csv)
    # Up to its checkpoint (the steps after it are redone on resume), no outcome or policy.
    assert [row["steps"] for row in read_eval_rows(unfinished.eval_csv)] == [0, 2000]
    assert not unfinished.outcome_path.exists() and not unfinished.policy_file.exists()
    # Taken on to a larger budget, a finished cell's outcome and policy leave the copy.
    assert cli.main([*sweep[:-3], "4000", "--sync", str(kept)]) == 0
    assert not copy.outcome_path.exists() and not copy.policy_file.exists()
    assert read_eval_rows(copy.eval_csv) == read_eval_rows(done.eval_csv)


def test_keep_copies_what_each_run_has_kept_and_its_policy_once_finished(tmp_path, capsys,
                                                                      monkeypatch):
    """`keep`, for runs outside a sweep (as `sync` for its cells): config and the evaluations
    a resume keeps always; outcome and policy once the run has reached its own budget.
    Runs whose copies would overwrite each other, or the runs themselves, are refused before
    anything is copied."""
    def write(root, name, seed, rows, outcome=None):
        run = RunDir(root / name)
        run.write_config(RunConfig("push", "sac", seed,
                                   hyperparameters("push", "sac").replace(total_steps=2000)))
        write_eval_rows(run.eval_csv, [dict(zip(EVAL_COLUMNS, (*row, -1.0))) for row in rows])
        if outcome:
            run.write_outcome(*outcome)
        return run

    runs, kept = tmp_path / "runs", tmp_path / "kept"
    done = write(runs, "push-seed0", 0, [(0, 1, 0.0), (2000, 2, 0.6)], (2000, False, 2))
    write_policy_file(done.policy_file, 10)
    going = write(runs, "push-seed1", 1, [(0, 1, 0.0), (1000, 2, 0.2), (1500, 3, 0.4)])
    going.checkpoint.mkdir()
    going.checkpoint_state.write_text(json.dumps({"steps": 1000}))
    going.policy_file.write_bytes(b"an older budget's")
    assert cli.main(["keep", str(runs), "--into", str(kept)]) == 0
    assert capsys.readouterr().out == f"{kept}: push-seed0, push-seed1\n"
    copy, unfinished = RunDir(kept / "push-seed0"), RunDir(kept / "push-seed1")
    assert copy.read_config() == done.read_config() and copy.read_outcome()["steps"] == 2000
    assert copy.policy_file.read_bytes() == done.policy_file.read_bytes()
    assert read_eval_rows(copy.eval_csv) == read_eval_rows(done.eval_csv)
    assert [row["steps"] for row in read_eval_rows(unfinished.eval_csv)] == [0, 1000]
    assert not unfinished.outcome_path.exists() and not unfinished.policy_file.exists()

    other = write(tmp_path / "elsewhere", "push-seed0", 2, [(0, 1, 0.0)])
    with pytest.raises(ValueError, match="two runs named push-seed0"):
        cli.main(["keep", str(runs), str(other.root), "--into", str(tmp_path / "new")])
    assert not (tmp_path / "new").exists()
    before = going.eval_csv.read_bytes()
    with pytest.raises(ValueError, match="is the run itself"):
        cli.main(["keep", str(runs / "push-seed1"), "--into", str(runs)])
    assert going.eval_csv.read_bytes() == before  # Not cut back to its checkpoint.
    # Given as `.`, a run is kept under its own name, not into DIR itself.
    monkeypatch.chdir(going.root)
    assert cli.main(["keep", ".", "--into", str(tmp_path / "dot")]) == 0
    assert sorted(path.name for path in (tmp_path / "dot").iterdir()) == ["push-seed1"]


def test_keep_and_sync_extend_what_is_kept_and_never_cut_it_back_or_replace_it(tmp_path):
    """A run begun again from zero (its machine lost it) retraces its kept evaluations: it is
    kept once it has passed them, and until then, or if it differs from them or is another
    run, keeping is refused naming why, with nothing copied (the other runs given with it
    neither)."""
    runs, kept = tmp_path / "runs", tmp_path / "kept"
    first = [(0, 1, 0.0), (2000, 2, 0.2), (4000, 3, 0.4)]
    _write_run(runs, "push-sac-seed0", first)
    assert cli.main(["keep", str(runs / "push-sac-seed0"), "--into", str(kept)]) == 0
    copy = RunDir(kept / "push-sac-seed0")
    before = copy.eval_csv.read_bytes()
    again = _write_run(tmp_path / "again", "push-sac-seed0", [(0, 5, 0.0), (2000, 9, 0.2)])
    other = _write_run(tmp_path / "again", "push-sac-seed1", [(0, 1, 0.0)], seed=1)
    with pytest.raises(ValueError, match=re.escape(
            f"{copy.eval_csv} holds evaluations from step 4,000 on, which {again.root} has "
            "not reached (its own end at step 2,000; begun again from zero?): keeping it now "
            f"would drop them. Keep it once it has passed them, or move {copy.root} away")):
        cli.main(["keep", str(other.root), str(again.root), "--into", str(kept)])
    cells = ["sweep", "--out", str(tmp_path / "again"), "--tasks", "push", "--algos", "sac",
             "--seeds", "0", "1", "--steps", "6000", "--sync", str(kept)]
    with pytest.raises(ValueError, match="has not reached \\(its own end at step 2,000"):
        cli.main(cells)
    empty = _write_run(tmp_path / "empty", "push-sac-seed0", [])
    with pytest.raises(ValueError, match=re.escape(
            f"from step 0 on, which {empty.root} has not reached (it has kept none;")):
        cli.main(["keep", str(empty.root), "--into", str(kept)])
    assert copy.eval_csv.read_bytes() == before
    assert sorted(path.name for path in kept.iterdir()) == ["push-sac-seed0"]
    # Past them, having retraced them (at its own pace), it is kept, and the other with it.
    again = _write_run(tmp_path / "again", "push-sac-seed0",
                       [(0, 5, 0.0), (2000, 9, 0.2), (4000, 12, 0.4), (6000, 15, 0.6)])
    assert cli.main(cells) == 0
    assert [(row["steps"], row["wall_time_s"]) for row in read_eval_rows(copy.eval_csv)] == [
        (0, 5), (2000, 9), (4000, 12), (6000, 15)]
    assert (kept / "push-sac-seed1" / "eval.csv").is_file()
    # Not the run kept there: other evaluations, or other settings.
    differs = _write_run(tmp_path / "differs", "push-sac-seed0",
                         [(0, 1, 0.0), (2000, 2, 0.1), (4000, 3, 0.4), (6000, 4, 0.6)])
    with pytest.raises(ValueError, match=re.escape(
            f"{copy.eval_csv} is not {differs.root}'s evaluations: at step 2,000 it holds "
            "success rate 0.2, mean reward -1, and the run success rate 0.1, mean reward -1. "
            f"Move {copy.root} away to keep this run there")):
        cli.main(["keep", str(differs.root), "--into", str(kept)])
    precision = _write_run(tmp_path / "bf16", "push-sac-seed0", first, precision="bf16")
    with pytest.raises(ValueError, match=re.escape(
            f"{copy.config_path} is another run's than {precision.root}'s (precision: bf16, "
            f"not fp32): move {copy.root} away to keep this run there")):
        cli.main(["keep", str(precision.root), "--into", str(kept)])
    assert [row["steps"] for row in read_eval_rows(copy.eval_csv)] == [0, 2000, 4000, 6000]


def test_evaluate_and_plot_read_a_sweep_directory(tmp_path):
    for seed in (1, 0):
        _write_run(tmp_path / "sweep", f"push-sac-seed{seed}", [(0, 1, 0.0)], seed=seed)
    single = _write_run(tmp_path, "alone", [(0, 1, 0.0)], seed=2).root
    assert run_directories([tmp_path / "sweep", single]) == [
        tmp_path / "sweep" / "push-sac-seed0", tmp_path / "sweep" / "push-sac-seed1", single]
    (tmp_path / "sweep" / "nothing").mkdir()
    with pytest.raises(ValueError, match=re.escape(
            f"{tmp_path / 'sweep' / 'nothing'} is neither a training run nor a sweep of runs "
            "(no config.json in it or in its subdirectories)")):
        run_directories([tmp_path / "sweep" / "nothing"])


def test_a_folder_of_sweeps_names_them_and_a_sweep_beside_runs_is_not_passed_over(tmp_path):
    """A folder of sweeps was said to hold no config.json in its subdirectories, and the
    sweeps beside a folder's runs (`results/`) were left out of a report without a word."""
    for sweep in ("a", "b", "c", "d"):
        _write_run(tmp_path / "all" / sweep, "push-sac-seed0", [(0, 1, 0.0)])
    with pytest.raises(ValueError, match=re.escape(
            f"{tmp_path / 'all'} is neither a training run nor a sweep of runs: it holds 4 "
            f"sweeps ({tmp_path / 'all' / 'a'}, {tmp_path / 'all' / 'b'}, "
            f"{tmp_path / 'all' / 'c'} and 1 more): give a sweep itself")):
        run_directories([tmp_path / "all"])
    _write_run(tmp_path / "one" / "a", "push-sac-seed0", [(0, 1, 0.0)])
    with pytest.raises(ValueError, match=re.escape(
            f"it holds 1 sweep ({tmp_path / 'one' / 'a'}): give a sweep itself")):
        run_directories([tmp_path / "one"])
    beside = _write_run(tmp_path / "all", "push-sac-seed1", [(0, 1, 0.0)], seed=1).root
    with pytest.warns(UserWarning, match=re.escape(
            f"{tmp_path / 'all'}: its runs alone are read, not those of the 4 sweeps in it")):
        assert run_directories([tmp_path / "all"]) == [beside]


def test_a_seed_given_twice_is_refused_before_it_counts_twice(tmp_path):
    for seed in (0, 1):
        _write_run(tmp_path / "sweep", f"push-sac-seed{seed}", [(0, 1, 0.0)], seed=seed)
    copy = _write_run(tmp_path / "kept", "push-sac-seed1", [(0, 1, 0.0)], seed=1).root
    message = (f"{tmp_path / 'sweep' / 'push-sac-seed1'} and {copy} are both seed 1 of push "
               "SAC: give each run once")
    with pytest.raises(ValueError, match=re.escape(message)):
        run_directories([tmp_path / "sweep", tmp_path / "kept"])
    with pytest.raises(ValueError, match="are both seed 0 of push SAC"):
        run_directories([tmp_path / "sweep", tmp_path / "sweep" / "push-sac-seed0"])
    # The same seed in another setup is another cell's.
    bf16 = _write_run(tmp_path, "bf16", [(0, 1, 0.0)], seed=1, precision="bf16").root
    assert run_directories([tmp_path / "sweep", bf16]) == [
        tmp_path / "sweep" / "push-sac-seed0", tmp_path / "sweep" / "push-sac-seed1", bf16]


@pytest.mark.parametrize("argv, message", [
    (["--grid", "table2", "--tasks", "push"], "--grid names a whole grid: give it alone"),
    (["--tasks", "push", "--algos", "sac"], "a sweep needs --grid, or all of --tasks, "
                                             "--algos, --seeds and --steps"),
    (["--tasks", "push", "slide", "--algos", "sac", "--seeds", "0", "--steps", "push=10"],
     "--steps has no budget for slide"),
    (["--grid", "table2", "--", "--seed", "3"], "--seed is set by the sweep for each cell"),
    (["--tasks", "push", "--algos", "sac", "--seeds", "0", "1", "0", "--steps", "10"],
     r"seed\(s\) 0 given more than once: each cell is one run directory"),
    (["--tasks", "push", "--algos", "sac", "tqc", "sac", "--seeds", "0", "--steps", "10",
      "--status"], r"algorithm\(s\) sac given more than once"),
])
def test_a_bad_sweep_is_refused_before_anything_runs(tmp_path, argv, message):
    with pytest.raises(ValueError, match=message):
        cli.main(["sweep", "--out", str(tmp_path / "sweep"), *argv])
    assert not (tmp_path / "sweep").exists()


def test_an_address_where_no_ray_cluster_answers_is_refused_at_once(tmp_path):
    """Ray retries an unreachable head for minutes; the sweep says so within seconds."""
    import socket

    with socket.socket() as probe:  # A port nothing listens on once closed.
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    argv = ["sweep", "--out", str(tmp_path / "sweep"), "--tasks", "push", "--algos", "sac",
            "--seeds", "0", "--steps", "100"]
    start = time.monotonic()
    for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}", f"[::1]:{port}"):
        with pytest.raises(ValueError, match=f"no Ray cluster answers at --address "
                                             f"{re.escape(address)} .*ray start --head"):
            cli.main([*argv, "--address", address])
    assert time.monotonic() - start < 30
    with pytest.raises(ValueError, match="--address 'head' is not HOST:PORT, "
                                         "ray://HOST:PORT, auto or local"):
        cli.main([*argv, "--address", "head"])
    assert not (tmp_path / "sweep").exists()


def test_a_cell_trained_as_another_run_is_refused_before_anything_runs(tmp_path):
    """Changing a grid's options (say, a backend) under a sweep that has trained would
    otherwise resume its cells with their old settings under the new grid's name."""
    from franka_composer.training import hyperparameters, loop
    from franka_composer.training.run_config import RunConfig

    out = tmp_path / "sweep"
    hp = hyperparameters("push", "sac").replace(stop_success_rate=0.95)
    trained = loop.start(out / "push-sac-seed0", RunConfig("push", "sac", 0, hp))
    trained.checkpoint.mkdir()
    trained.checkpoint_state.write_text(json.dumps({"steps": 2000}))
    untrained = loop.start(out / "push-sac-seed1", RunConfig("push", "sac", 1, hp))
    before = {path: path.stat().st_mtime_ns for path in out.rglob("*")}
    sweep = ["sweep", "--out", str(out), "--tasks", "push", "--algos", "sac", "--seeds", "0",
             "1", "--steps", "5000", "--", "--stop-at-success", "0.95"]
    with pytest.raises(ValueError) as error:
        cli.main([*sweep, "--precision", "bf16", "--batch-size", "64"])
    assert str(error.value) == (
        f"{trained.root} holds a run other than the one this sweep gives that cell (the "
        "sweep's setting, not the run's: precision: bf16, not fp32; batch_size: 64, not "
        "512): if it is this sweep's, give the options after -- it was run with (--status "
        "and --sync read the cells as the sweep trains them); else move it aside, or sweep "
        "into another --out")
    assert {path: path.stat().st_mtime_ns for path in out.rglob("*")} == before
    # The same run with a larger budget is the same cell; a cell without a checkpoint
    # starts afresh with the sweep's settings, whatever its directory held.
    from franka_composer.cli.sweep import _check_trained_as
    from franka_composer.cli.train import run_config

    for run, options in ((trained, ["--total-steps", "9000"]), (untrained, ["--seed", "1",
                                                                            "--precision",
                                                                            "bf16"])):
        args = cli.build_parser().parse_args(["train", "--task", "push", "--algo", "sac",
                                              "--stop-at-success", "0.95", *options])
        _check_trained_as(run, run_config(args))


def test_an_out_that_is_a_run_or_holds_other_things_under_a_cells_name_is_refused(
        tmp_path, monkeypatch):
    """A folder holding no run under a cell's name was taken for a cell stopped before its
    first checkpoint and removed, with what the user kept there; a file there was refused
    as an option after --; --out a run, or inside one, failed its cell after Ray started,
    leaving a log and folders inside the run. All refused before Ray starts."""
    from franka_composer.training import sweep

    monkeypatch.setattr(sweep, "run_sweep", lambda *args, **kwargs: pytest.fail("started"))
    base = ["--tasks", "reach", "--algos", "sac", "--seeds", "0", "--steps", "300"]
    out = tmp_path / "s"
    (out / "reach-sac-seed0").mkdir(parents=True)
    (out / "reach-sac-seed0" / "notes.txt").write_text("precious")
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{out / 'reach-sac-seed0'} is not empty and holds no run, where the sweep's "
            "cell reach-sac-seed0 would train: move it aside, or sweep into another --out")
            + "$"):
        cli.main(["sweep", "--out", str(out), *base])
    assert (out / "reach-sac-seed0" / "notes.txt").read_text() == "precious"
    # A cell begun on such a folder all the same (made after the check) leaves it to train,
    # which refuses it.
    cell, = sweep.grid(["reach"], ["sac"], [0], 300)
    assert sweep.run_cell(cell, out, ())[1] != 0
    assert (out / "reach-sac-seed0" / "notes.txt").read_text() == "precious"
    assert "is not empty and holds no run" in sweep.cell_log(cell, out).read_text()
    (out / "reach-sac-seed0" / "notes.txt").unlink()
    (out / "reach-sac-seed0").rmdir()
    (out / "reach-sac-seed0").write_text("x")
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{out / 'reach-sac-seed0'} is a file where the sweep's cell reach-sac-seed0 "
            "would train: move it aside, or sweep into another --out") + "$"):
        cli.main(["sweep", "--out", str(out), *base])
    run = _write_run(tmp_path, "run", [(0, 1.0, 0.0)]).root
    before = sorted(path.relative_to(run) for path in run.rglob("*"))
    with pytest.raises(ValueError, match="^" + re.escape(
            f"--out {run} is a training run, not a sweep's folder (a sweep's cells are runs "
            "in it)") + "$"):
        cli.main(["sweep", "--out", str(run), *base])
    with pytest.raises(ValueError, match="^" + re.escape(
            f"--out {run / 'sub'} is inside the run {run}: give a folder outside it") + "$"):
        cli.main(["sweep", "--out", str(run / "sub"), *base])
    assert sorted(path.relative_to(run) for path in run.rglob("*")) == before


def test_a_grid_needing_sbx_is_refused_without_it_before_anything_runs(tmp_path,
                                                                        monkeypatch):
    from franka_composer.training.models import SBX_MISSING

    monkeypatch.setitem(sys.modules, "sbx", None)  # import sbx raises ImportError.
    with pytest.raises(ValueError, match=re.escape(SBX_MISSING)):
        cli.main(["sweep", "--grid", "table2", "--out", str(tmp_path / "t")])
    assert not (tmp_path / "t").exists()


def test_cells_picks_a_part_of_a_grid_by_name(tmp_path, capsys):
    assert cli.main(["sweep", "--grid", "table2", "--out", str(tmp_path / "t"), "--status",
                     "--cells", "push-sac-*", "slide-ddpg-seed0"]) == 0
    cells = [line.split(" | ")[0].lstrip("| ") for line in
             capsys.readouterr().out.splitlines()[2:]]
    assert cells == ["push-sac-seed0", "push-sac-seed1", "push-sac-seed2", "slide-ddpg-seed0"]
    with pytest.raises(ValueError, match=re.escape(
            "--cells 'push-tqc-seed9' matches no cell of the grid; its cells: push-sac-seed0, "
            "push-sac-seed1")):
        cli.main(["sweep", "--out", str(tmp_path / "s"), "--tasks", "push", "--algos", "sac",
                  "--seeds", "0", "1", "--steps", "10", "--cells", "push-sac-*",
                  "push-tqc-seed9"])
    assert not (tmp_path / "s").exists()


def test_bad_train_options_and_budgets_are_refused_by_the_parsers(tmp_path, capsys):
    base = ["sweep", "--out", str(tmp_path / "s"), "--tasks", "push", "--algos", "sac",
            "--seeds", "0"]
    with pytest.raises(ValueError, match=re.escape(
            "the options after -- go to each cell's train, which does not take --bogus "
            "(franka-composer train --help lists its options; give them in full)")):
        cli.main([*base, "--steps", "10", "--", "--bogus"])
    # An abbreviation train would take is refused: --tas would set the cell's --task, --ou
    # its --out (where the exact spellings are refused as set by the sweep).
    for option in ("--tas", "--ou", "--total-st"):
        with pytest.raises(ValueError, match=re.escape(
                f"which does not take {option} slide (franka-composer train --help")):
            cli.main([*base, "--steps", "10", "--", option, "slide"])
    with pytest.raises(SystemExit):
        cli.main([*base, "--steps", "shove=10"])
    assert "unknown task 'shove' in --steps" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # The last one was taken.
        cli.main([*base, "--steps", "push=100,push=200"])
    assert "push given two budgets in --steps: give each task one" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_a_bad_train_value_after_the_options_is_the_sweeps_refusal(tmp_path):
    """Not train's usage and `franka-composer train: error`: the user ran sweep."""
    with pytest.raises(ValueError, match=re.escape(
            "the options after -- go to each cell's train, which refuses them: argument "
            "--batch-size: must be a positive integer, got '-3'")):
        cli.main(["sweep", "--out", str(tmp_path / "s"), "--tasks", "push", "--algos", "sac",
                  "--seeds", "0", "--steps", "10", "--", "--batch-size", "-3"])
    assert not (tmp_path / "s").exists()


def test_status_and_sync_check_the_sweep_they_are_given(tmp_path, capsys):
    """--status and --sync read the cells as the sweep trains them: options after -- it
    would refuse, a run given as the sweep's folder, a folder not there to sync, and (for
    --sync) a cell holding another run are refused, where they listed every cell as waiting
    or copied the cell."""
    from franka_composer.training import hyperparameters, loop
    from franka_composer.training.run_config import RunConfig

    grid = ["--tasks", "push", "--algos", "sac", "--seeds", "0", "--steps", "5000"]
    out = tmp_path / "sweep"
    run = loop.start(out / "push-sac-seed0", RunConfig("push", "sac", 0,
                                                       hyperparameters("push", "sac")))
    run.checkpoint.mkdir()
    run.checkpoint_state.write_text(json.dumps({"steps": 2000}))
    for argv, message in (
            (["--out", str(out), "--status", "--", "--bogus"],
             "the options after -- go to each cell's train, which does not take --bogus"),
            (["--out", str(run.root), "--status"],
             f"--out {run.root} is a training run, not a sweep's folder (a sweep's cells are "
             "runs in it)"),
            (["--out", str(tmp_path / "nosuch"), "--sync", str(tmp_path / "kept")],
             f"--out {tmp_path / 'nosuch'} does not exist: no sweep there to sync"),
            (["--out", str(out), "--sync", str(tmp_path / "kept"), "--", "--batch-size", "7"],
             f"{run.root} holds a run other than the one this sweep gives that cell (the "
             "sweep's setting, not the run's: batch_size: 7, not 512)")):
        with pytest.raises(ValueError, match=re.escape(message)):
            cli.main(["sweep", *grid, *argv])
    assert not (tmp_path / "kept").exists()
    # A cell that has not checkpointed yet would be begun again by the sweep, but --sync
    # would copy it, under the sweep's name: another run there is refused too.
    other = tmp_path / "other"
    loop.start(other / "push-sac-seed0", RunConfig(
        "push", "sac", 0, hyperparameters("push", "sac").replace(batch_size=7)))
    with pytest.raises(ValueError, match=re.escape(
            f"{other / 'push-sac-seed0'} holds a run other than the one this sweep gives "
            "that cell (the sweep's setting, not the run's: batch_size: 512, not 7)")):
        cli.main(["sweep", *grid, "--out", str(other), "--sync", str(tmp_path / "kept")])
    assert not (tmp_path / "kept").exists()
    # A grid's cells listed before any sweep is there, as its help says.
    assert cli.main(["sweep", *grid, "--out", str(tmp_path / "nosuch"), "--status"]) == 0
    assert "| push-sac-seed0 | waiting |" in capsys.readouterr().out
    # --status shows such a cell as the other run it holds, not as the cell's state ("done"
    # once that run had finished).
    other_run = RunDir(other / "push-sac-seed0")
    write_eval_rows(other_run.eval_csv, [dict(zip(EVAL_COLUMNS, row)) for row in (
        (0, 1, 0.0, -1.0), (5000, 2, 1.0, -1.0))])
    other_run.write_outcome(5000, False, 2.0)
    assert cli.main(["sweep", *grid, "--out", str(other), "--status"]) == 0
    assert capsys.readouterr().out.splitlines()[2] == (
        "| push-sac-seed0 | another run (batch_size: 512, not 7) | 5,000 | 5,000 | 5000.0 | "
        "100 % |")


@pytest.mark.slow
def test_a_sweeps_own_ray_cluster_listens_on_loopback_only(tmp_path, monkeypatch):
    """Without --address the sweep starts a Ray instance of its own, bound to 127.0.0.1
    (Ray's default is the machine's network address); with one it joins that cluster."""
    import ray
    asked = []

    def init(**kwargs):
        asked.append(kwargs)
        raise RuntimeError("not started")

    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    sweep = ["sweep", "--out", str(tmp_path / "s"), "--tasks", "push", "--algos", "sac",
             "--seeds", "0", "--steps", "200", "--num-cpus", "1"]
    with pytest.raises(OSError, match="could not start a local Ray cluster: not started"):
        cli.main([*sweep, "--", *TINY])
    assert asked[0]["_node_ip_address"] == "127.0.0.1" and asked[0]["num_cpus"] == 1
    assert asked[0]["address"] is None


def test_a_sweep_stopped_while_ray_starts_shuts_down_what_it_started(tmp_path, capsys,
                                                                      monkeypatch):
    """A SIGTERM or Ctrl-C in Ray's first seconds came before the sweep's own handlers and
    outside its shutdown: Ray's agents stayed behind (and SIGTERM said nothing). Ctrl-C
    here (a SIGTERM without the sweep's handler would end the test run itself)."""
    import ray

    shut = []

    def init(**kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # Arrives while Ray starts.
        time.sleep(5)
        pytest.fail("the signal did not stop the sweep")

    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "shutdown", lambda: shut.append(True))
    out = tmp_path / "s"
    assert cli.console(["sweep", "--out", str(out), "--tasks", "push", "--algos", "sac",
                        "--seeds", "0", "--steps", "200", "--num-cpus", "1", "--",
                        *TINY]) == 130
    assert shut == [True] and not out.exists()
    assert "interrupted" in capsys.readouterr().out


def test_a_two_cell_sweep_trains_skips_and_resumes_on_ray(tmp_path, capsys, monkeypatch):
    out = tmp_path / "sweep"
    sweep = ["sweep", "--out", str(out), "--tasks", "push", "--algos", "sac", "--seeds", "0",
             "1", "--num-cpus", "2", "--refresh", "1000"]
    assert cli.main([*sweep, "--steps", "200", "--", *TINY]) == 0
    for seed in (0, 1):
        run = RunDir(out / f"push-sac-seed{seed}")
        assert run.read_config().seed == seed
        assert [r["steps"] for r in read_eval_rows(run.eval_csv)] == [0, 100, 200]
        assert run.read_outcome()["steps"] == 200
    assert "| push-sac-seed1 | done | 200 | 200 |" in capsys.readouterr().out
    # The same sweep again: nothing to do, so Ray is not even started.
    import ray

    monkeypatch.setattr(ray, "init", lambda **kwargs: pytest.fail("Ray started"))
    assert cli.main([*sweep, "--steps", "200", "--", *TINY]) == 0
    monkeypatch.undo()
    # A larger budget resumes both cells from their checkpoints: their first evaluations,
    # wall times included, are kept (a fresh start would have rewritten them).
    before = {seed: read_eval_rows(RunDir(out / f"push-sac-seed{seed}").eval_csv)
              for seed in (0, 1)}
    assert cli.main([*sweep, "--steps", "push=300", "--", *TINY]) == 0
    for seed in (0, 1):
        run = RunDir(out / f"push-sac-seed{seed}")
        rows = read_eval_rows(run.eval_csv)
        assert rows[:3] == before[seed] and [r["steps"] for r in rows] == [0, 100, 200, 300]
        assert run.read_outcome()["steps"] == 300
    capsys.readouterr()
    assert cli.main(["evaluate", str(out), "--episodes", "1", "--device", "cpu"]) == 0
    assert ("push (net_arch 16,16, batch_size 32, buffer_size 2000) / sac: seeds 0, 1; "
            "trained steps 300, 300") in capsys.readouterr().out


def _sweep_in_learn(out: pathlib.Path, run: RunDir, **popen) -> subprocess.Popen:
    """A one-cell push SAC sweep into `out`, started in a process of its own (`popen`: its
    environment or set-up) and returned once its run (`run`) is past learning_starts."""
    sweep = subprocess.Popen(
        [sys.executable, "-m", "franka_composer", "sweep", "--out", str(out), "--tasks", "push",
         "--algos", "sac", "--seeds", "0", "--steps", "100000", "--num-cpus", "1",
         "--refresh", "1000", "--", *TINY], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, **popen)
    deadline = time.monotonic() + 120
    while len(read_eval_rows(run.eval_csv)) < 3:  # Past learning_starts: inside learn.
        assert sweep.poll() is None and time.monotonic() < deadline, sweep.communicate()[0]
        time.sleep(0.2)
    return sweep


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_a_background_sweep_with_its_cells_checkpointed(tmp_path, signum):
    """`kill` (SIGTERM), or SIGINT though a background job ignores it, stops the sweep the
    way Ctrl-C does: the running cell checkpoints, and no train process is left behind. The
    command it says to continue with, and the one its log records, copy into a shell as
    they are (a folder with a space in its name split in two). It exits with the signal's
    status: SIGTERM's was 130, Ctrl-C's (Ray's wait put a bare KeyboardInterrupt of its own
    in place of the one the handler raised)."""
    out = tmp_path / "the sweep"
    run = RunDir(out / "push-sac-seed0")
    sweep = _sweep_in_learn(out, run, preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                       signal.SIG_IGN))
    sweep.send_signal(signum)
    output = sweep.communicate(timeout=120)[0]
    assert sweep.returncode == 128 + signum, output  # 143 for SIGTERM, 130 for SIGINT.
    assert "interrupted: each running cell saved a checkpoint" in output
    assert run.read_state()["steps"] >= 200
    assert (f"interrupted: its checkpoint at step {run.read_state()['steps']:,} is kept; "
            f"continue with franka-composer train --resume --out '{run.root}'") in cell_log(
        Cell("push", "sac", 0, 100000), out).read_text()
    assert f" --out '{run.root}' " in cell_log(Cell("push", "sac", 0, 100000), out).read_text()
    # "--" first: a pattern that starts with "--" is otherwise read as pgrep's option.
    left = subprocess.run(["pgrep", "-f", "--", f"--out {run.root}"], capture_output=True,
                          text=True)
    assert (left.returncode, left.stdout) == (1, "")  # 1: no process matched.


#: Put on PYTHONPATH, makes every run's stop checkpoint wait SLOW_STOP_S seconds first: a
#: run whose checkpoint takes that long to write (a 1e6-step replay buffer, a loaded machine).
SLOW_STOP = """
import importlib.abc, importlib.util, os, sys, time

class _SlowStop(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != "franka_composer.training.callbacks":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        run_module = spec.loader.exec_module

        def exec_module(module):
            run_module(module)
            save = module.LatestCheckpoint.save

            def slow_save(self, *, exact):
                if self.stop_requested_by is not None:
                    time.sleep(float(os.environ["SLOW_STOP_S"]))
                return save(self, exact=exact)

            module.LatestCheckpoint.save = slow_save

        spec.loader.exec_module = exec_module
        return spec

sys.meta_path.insert(0, _SlowStop())
"""


@pytest.mark.slow
def test_a_stopped_sweep_waits_for_a_slow_checkpoint_and_names_a_cell_stopped_without_one(
        tmp_path):
    """The sweep waited 60 s for its cells to checkpoint, then shut Ray down, which killed
    a run still writing its checkpoint, and said "each running cell saved a checkpoint".
    It now waits however long the checkpoint takes (here past those 60 s), and a second
    SIGTERM stops the cells at once: its last line names the cell that stopped without a
    checkpoint, and where it resumes from."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(SLOW_STOP)
    out = tmp_path / "sweep"
    run = RunDir(out / "push-sac-seed0")
    sweep = _sweep_in_learn(out, run, env={**os.environ, "PYTHONPATH": str(hook),
                                           "SLOW_STOP_S": "3600"})
    sweep.send_signal(signal.SIGTERM)
    time.sleep(70)
    assert sweep.poll() is None, sweep.communicate()[0]  # Still waiting for the checkpoint,
    assert run.trainer() is not None  # and the run still making it.
    sweep.send_signal(signal.SIGTERM)
    output = sweep.communicate(timeout=120)[0]
    assert sweep.returncode == 143, output
    assert output.splitlines()[-1] == (
        "interrupted: wrote no checkpoint at the stop: push-sac-seed0 (resumes from zero: it "
        "had none); the same command resumes the sweep")
    assert run.read_state() == {} and run.trainer() is None  # No checkpoint.


def test_one_cpu_runs_one_cell_while_the_others_queue(tmp_path):
    """The live table calls a cell running once its task has started (the start line of
    its log, which names the train command), queued until then."""
    cells = grid(["push"], ["sac"], [0, 1], 100)
    tables = []
    run_sweep(cells, tmp_path, tuple(TINY), num_cpus=1, refresh_s=0.2, show=tables.append)
    states = [[line.split(" | ")[1] for line in table.splitlines()[2:]] for table in tables]
    assert all(row.count("running") <= 1 for row in states[:-1])
    assert any(sorted(row) == ["queued", "running"] for row in states[:-1])
    assert states[-1] == ["done", "done"]
    for cell in cells:
        first = cell_log(cell, tmp_path).read_text().splitlines()[0]
        assert f"-m franka_composer train --out {tmp_path / cell.name}" in first
        assert f"--task push --algo sac --seed {cell.seed}" in first


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "-1"], "argument --seeds: must be an integer from 0 to 2147483647, got '-1'"),
    (["--seeds", "2147483648"], "must be an integer from 0 to 2147483647"),
    (["--refresh", "0"], "argument --refresh: must be a number of seconds > 0, got '0'"),
    (["--refresh", "nan"], "must be a number of seconds > 0"),
])
def test_bad_seeds_and_refresh_periods_are_refused_by_the_parser(tmp_path, capsys, argv,
                                                                 message):
    base = {"--tasks": ["push"], "--algos": ["sac"], "--seeds": ["0"], "--steps": ["10"]}
    base[argv[0]] = argv[1:]
    args = [item for key, values in base.items() for item in (key, *values)]
    with pytest.raises(SystemExit):
        cli.main(["sweep", "--out", str(tmp_path / "s"), *args])
    assert message in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


#: A Zen 4's vector flags: bf16 units, so the scripts that train in bf16 start.
ZEN_4_FLAGS = "fpu sse avx avx2 fma f16c avx512f avx512_bf16"


def _cpu_with_flags(folder: pathlib.Path, flags: str) -> pathlib.Path:
    """A folder whose sitecustomize makes `machine` read a cpuinfo with `flags` (put on
    PYTHONPATH: the scripts' Python then sees that CPU, whatever this machine's is)."""
    folder.mkdir(exist_ok=True)
    (folder / "cpuinfo").write_text(f"processor\t: 0\nflags\t\t: {flags}\n")
    (folder / "sitecustomize.py").write_text(
        "import pathlib\nfrom franka_composer.training import machine\n"
        f"machine._CPUINFO = pathlib.Path({str(folder / 'cpuinfo')!r})\n")
    return folder


def _benchmark_sh(tmp_path, script, command, *arguments, **env):
    """benchmarks/SCRIPT COMMAND ARGUMENTS, its franka-composer one that prints its
    arguments, on a CPU with bf16 units (`ZEN_4_FLAGS`)."""
    bin_dir = tmp_path / "bin"
    if not bin_dir.exists():
        bin_dir.mkdir()
        for name, body in (("python", f'exec {sys.executable} "$@"'),
                           ("franka-composer", 'echo "franka-composer $*"')):
            (bin_dir / name).write_text(f"#!/bin/sh\n{body}\n")
            (bin_dir / name).chmod(0o755)
    cpu = _cpu_with_flags(tmp_path / "zen4", ZEN_4_FLAGS)
    return subprocess.run(
        [str(REPO / "benchmarks" / script), command, *arguments], capture_output=True,
        text=True,
        env={**os.environ, "BIN": str(bin_dir), "RUNS": str(tmp_path / "runs"),
             "KEPT": str(tmp_path / "kept"), "PYTHONPATH": str(cpu), **env})


def _sweep_cells(output):
    words = output.split()
    return words[words.index("--cells") + 1:words.index("--refresh")]


def test_table2_sh_trains_only_the_cells_sync_has_not_kept_as_finished(tmp_path):
    """A machine handed back bare has lost every run directory: the cells sync kept as
    finished are done all the same, and a `run` trains the others (not 16 cells again)."""
    names = [cell.name for cell in GRIDS["table2"]]
    _write_run(tmp_path / "kept", "push-tqc-seed1", [(0, 1, 0.0)], (250000, False, 2))
    _write_run(tmp_path / "kept", "push-sac-seed0", [(0, 1, 0.0), (2000, 2, 0.6)])
    ran = _benchmark_sh(tmp_path, "table2.sh", "run")
    assert ran.returncode == 0, ran.stderr
    assert _sweep_cells(ran.stdout) == [name for name in names if name != "push-tqc-seed1"]
    # Cells named are trained as named.
    named = _benchmark_sh(tmp_path, "table2.sh", "run", CELLS="push-tqc-* slide-ddpg-seed0")
    assert _sweep_cells(named.stdout) == ["push-tqc-*", "slide-ddpg-seed0"]
    reported = _benchmark_sh(tmp_path, "table2.sh", "report")
    assert reported.returncode == 1 and reported.stdout == ""
    assert reported.stderr == ("not finished (PARTIAL=1 reports the rest): "
                               f"{', '.join(n for n in names if n != 'push-tqc-seed1')}\n")
    partial = _benchmark_sh(tmp_path, "table2.sh", "report", PARTIAL="1")
    assert partial.returncode == 0, partial.stderr
    assert partial.stdout.splitlines() == [
        f"franka-composer evaluate {tmp_path}/kept/push-tqc-seed1 --episodes 20 --device cpu "
        f"--out {tmp_path}/kept/table2.md",
        f"franka-composer evaluate {tmp_path}/kept/push-tqc-seed1 --episodes 200 --seed 100 "
        f"--device cpu --out {tmp_path}/kept/table2-200-episodes.md",
        f"franka-composer plot {tmp_path}/kept --out {tmp_path}/kept/curves.png",
        f"franka-composer report {tmp_path}/kept --thresholds 80 90 --paper-curves "
        f"results/paper-curves/curves.csv --out {tmp_path}/kept/report.md"]
    for cell in GRIDS["table2"]:
        _write_run(tmp_path / "kept", cell.name, [(0, 1, 0.0)], (cell.steps, False, 2))
    done = _benchmark_sh(tmp_path, "table2.sh", "run")
    assert (done.returncode, done.stdout) == (0, f"every cell has finished ({tmp_path}/kept)\n")


@pytest.mark.parametrize("script, env, cells, options, kept", [
    ("reference_timing.sh", {}, "--tasks pick_and_place --algos tqc --seeds 0 1 2",
     "--backend sbx --timing reference", "reference-timing"),
    ("reference_timing.sh", {"ALGO": "sac", "SEEDS": "2"},
     "--tasks pick_and_place --algos sac --seeds 2", "--precision bf16 --timing reference",
     "reference-timing"),
    ("reference_timing.sh", {"ALGO": "ddpg"}, "--tasks pick_and_place --algos ddpg --seeds 0 1 2",
     "--timing reference", "reference-timing"),
    ("reference_timing.sh", {"TIMING": "default", "ALGO": "sac"},
     "--tasks pick_and_place --algos sac --seeds 0 1 2", "--precision bf16", "default-timing"),
    ("reference_timing.sh", {"TIMING": "default", "ALGO": "ddpg"},
     "--tasks pick_and_place --algos ddpg --seeds 0 1 2", "", "default-timing"),
    ("learnability.sh", {}, "--tasks stack flip --algos tqc --seeds 0",
     "--backend sbx --guard-ignores-carried false", "learnability"),
])
def test_background_campaigns_train_their_cells_with_their_options(
        tmp_path, script, env, cells, options, kept):
    """Each campaign script's `run` is one sweep of its cells at 5e5 steps, every cell with
    the campaign's stopping rule and checkpoints; an unknown command prints its usage."""
    ran = _benchmark_sh(tmp_path, script, "run", **env)
    assert ran.returncode == 0, ran.stderr
    trained_with = (f"-- {options + ' ' if options else ''}--stop-at-success 0.95 "
                    "--stop-after 5 --checkpoint-every 10000 --threads 1 --device cpu\n")
    assert ran.stdout == (
        f"franka-composer sweep --out {tmp_path}/runs {cells} --steps 500000 --num-cpus 1 "
        f"--refresh 600 {trained_with}")
    # Sync reads the cells as the sweep trains them: with the same options.
    synced = _benchmark_sh(tmp_path, script, "sync", **env)
    assert synced.stdout.endswith(f"--sync {tmp_path}/kept {trained_with}")  # KEPT, if given.
    synced = _benchmark_sh(tmp_path, script, "sync", **env, KEPT="")
    assert synced.stdout.endswith(f"--sync results/{kept} {trained_with}")
    # RUNS, where not given: beside the other campaigns' runs, one folder per campaign.
    status = _benchmark_sh(tmp_path, script, "status", **env, RUNS="", HOME=str(tmp_path))
    assert f"--out {tmp_path}/franka_runs/{kept} " in status.stdout
    usage = _benchmark_sh(tmp_path, script, "train", **env)
    assert usage.returncode == 2 and usage.stdout.startswith("# ")


def test_reference_timing_sh_refuses_an_unknown_algorithm_or_timing(tmp_path):
    refused = _benchmark_sh(tmp_path, "reference_timing.sh", "run", ALGO="td3")
    assert (refused.returncode, refused.stdout) == (2, "")
    assert refused.stderr == "ALGO must be tqc, sac or ddpg, not td3\n"
    refused = _benchmark_sh(tmp_path, "reference_timing.sh", "run", TIMING="fast")
    assert (refused.returncode, refused.stdout) == (2, "")
    assert refused.stderr == "TIMING must be reference or default, not fast\n"


def test_reference_timing_sh_trains_only_the_cells_sync_has_not_kept_as_finished(tmp_path):
    """A machine handed back bare has lost the finished cells' runs: sync kept them, and a
    `run` does not train them again from zero."""
    kept = tmp_path / "kept"
    _write_run(kept, "pick_and_place-tqc-seed1", [(0, 1, 0.0)], (500000, False, 2))
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0)])  # Kept, not finished.
    ran = _benchmark_sh(tmp_path, "reference_timing.sh", "run")
    assert ran.returncode == 0, ran.stderr
    assert "--algos tqc --seeds 0 2 --steps 500000" in ran.stdout
    # Ended at a lower budget (an outcome, short of 5e5, not stopped early): it goes on.
    _write_run(kept, "pick_and_place-tqc-seed0", [(0, 1, 0.0)], (400000, False, 2))
    ran = _benchmark_sh(tmp_path, "reference_timing.sh", "run")
    assert "--algos tqc --seeds 0 2 --steps 500000" in ran.stdout
    # Stopped early by the campaign's rule: finished.
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0)], (120000, True, 2))
    ran = _benchmark_sh(tmp_path, "reference_timing.sh", "run")
    assert "--algos tqc --seeds 0 --steps 500000" in ran.stdout
    other = _benchmark_sh(tmp_path, "reference_timing.sh", "run", ALGO="sac")
    assert "--algos sac --seeds 0 1 2 --steps 500000" in other.stdout
    _write_run(kept, "pick_and_place-tqc-seed0", [(0, 1, 0.0)], (500000, False, 2))
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0)], (500000, False, 2))
    done = _benchmark_sh(tmp_path, "reference_timing.sh", "run")
    assert (done.returncode, done.stdout) == (0, f"every cell has finished ({kept})\n")
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")  # Status shows all.
    assert "--seeds 0 1 2 --steps 500000" in status.stdout


#: What `reference_timing.sh status` shows its table with (a fake franka-composer echoes it):
#: the cells as its sweep trains them, with its options after --.
REFERENCE_TIMING_STATUS = ("--status -- --backend sbx --timing reference --stop-at-success 0.95 "
                           "--stop-after 5 --checkpoint-every 10000 --threads 1 --device cpu\n")


def test_a_campaigns_status_names_the_kept_runs_its_runs_have_not_passed(tmp_path):
    """A machine handed back bare lost the unfinished runs: `status` says, below the table,
    which kept evaluations their runs begun again from zero have still to retrace."""
    kept, runs = tmp_path / "kept", tmp_path / "runs"
    _write_run(kept, "pick_and_place-tqc-seed0", [(0, 1, 0.0), (2000, 9, 0.1), (4000, 18, 0.2)])
    _write_run(kept, "pick_and_place-tqc-seed1", [(0, 1, 0.0), (2000, 9, 0.1)],
               (500000, False, 2))  # Finished: done, whatever is here.
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0), (2000, 9, 0.1)])
    _write_run(runs, "pick_and_place-tqc-seed2", [(0, 1, 0.0), (2000, 8, 0.1)])  # Passed.
    ahead = (f"pick_and_place-tqc-seed0: evaluations kept to step 4,000 in {kept}; "
             "{} (a run begun again from zero retraces them, and is kept once it has passed "
             "them)\n")
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.returncode == 0, status.stderr
    table = REFERENCE_TIMING_STATUS
    assert status.stdout.endswith(table + ahead.format("no run here"))
    _write_run(runs, "pick_and_place-tqc-seed0", [(0, 1, 0.0), (2000, 8, 0.1)])
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.stdout.endswith(
        table + ahead.format("its run here has retraced them to step 2,000"))
    _write_run(runs, "pick_and_place-tqc-seed0", [(0, 1, 0.0), (2000, 8, 0.1), (4000, 17, 0.2)])
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.stdout.endswith(table)
    # A run that has left them is named as soon as it has (sync would refuse it).
    _write_run(runs, "pick_and_place-tqc-seed0", [(0, 1, 0.0), (2000, 8, 0.3)])
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.stdout.endswith(
        f"{table}pick_and_place-tqc-seed0: its run here has left the evaluations kept in "
        f"{kept} at step 2,000 (success rate 0.3, mean reward -1; kept: 0.1, -1): it will not "
        "be kept there\n")


def test_a_campaign_notes_each_machine_it_runs_on_and_says_where_one_changed(tmp_path,
                                                                             monkeypatch):
    """Runs on frozen trees older than the checkpoints' own record of their machine: the
    campaign's folder keeps one line per start, and a start on a machine that differs from
    the last one's is said at the start and by every later `status`."""
    from franka_composer.training import machine

    log = tmp_path / "runs" / "machines.jsonl"
    assert _benchmark_sh(tmp_path, "reference_timing.sh", "run").stderr == ""
    assert _benchmark_sh(tmp_path, "reference_timing.sh", "run").stderr == ""
    # The CPU the scripts saw (`_benchmark_sh`'s), not this machine's.
    monkeypatch.setattr(machine, "_CPUINFO", tmp_path / "zen4" / "cpuinfo")
    noted = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(noted) == 2 and all(
        {k: v for k, v in line.items() if k != "noted"} == machine.fingerprint()
        for line in noted)
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.stdout.endswith(REFERENCE_TIMING_STATUS)  # One machine: nothing to say.
    for line in noted:  # As if both starts had been elsewhere.
        line["libraries"]["torch"] = "2.12.0"
    log.write_text("".join(json.dumps(line) + "\n" for line in noted))
    ran = _benchmark_sh(tmp_path, "reference_timing.sh", "run")
    assert ran.returncode == 0 and ran.stdout.startswith("franka-composer sweep ")
    now = json.loads(log.read_text().splitlines()[-1])["noted"]
    torch_now = machine.fingerprint()["libraries"]["torch"]
    said = (f"{log}: runs resumed from {now} on another machine (torch 2.12.0 then, "
            f"{torch_now} now): a resume there is exact, but from there a run's floating-point "
            "results, and so its course, can differ from the ones the machine before would "
            "have computed\n")
    assert ran.stderr == said
    status = _benchmark_sh(tmp_path, "reference_timing.sh", "status")
    assert status.stdout.endswith(REFERENCE_TIMING_STATUS + said)


def test_reference_timing_sh_reports_the_algorithms_whose_every_seed_has_finished(tmp_path):
    """`report`: the tests over 20 and 200 episodes, the curves and the steps to 50/80/90 %
    of the algorithms whose three seeds sync kept finished; an algorithm still training is
    named and left out (its runs' evaluations too) unless PARTIAL=1."""
    kept = tmp_path / "kept"
    reported = _benchmark_sh(tmp_path, "reference_timing.sh", "report")
    assert (reported.returncode, reported.stdout) == (1, "")
    assert reported.stderr == f"no algorithm has finished its cells in {kept}\n"
    _write_run(kept, "pick_and_place-tqc-seed0", [(0, 1, 0.0)], (500000, False, 2))
    _write_run(kept, "pick_and_place-tqc-seed1", [(0, 1, 0.0)])
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0)], (400000, False, 2))
    (kept / "notes").mkdir()  # Not a run: no config.json.
    reported = _benchmark_sh(tmp_path, "reference_timing.sh", "report")
    assert (reported.returncode, reported.stdout) == (1, "")
    assert reported.stderr == (
        "not reported until every seed has finished: tqc (pick_and_place-tqc-seed1, "
        f"pick_and_place-tqc-seed2)\nno algorithm has finished its cells in {kept}\n")
    partial = _benchmark_sh(tmp_path, "reference_timing.sh", "report", PARTIAL="1")
    assert partial.returncode == 0, partial.stderr
    assert partial.stdout.splitlines() == _report_lines(
        kept, [f"{kept}/pick_and_place-tqc-seed0"], [str(kept)])  # Every cell's curve.
    # TQC finished (seed 2 stopped early by the rule); SAC's seed 0 training, 1 and 2 to come.
    _write_run(kept, "pick_and_place-tqc-seed1", [(0, 1, 0.0)], (500000, False, 2))
    _write_run(kept, "pick_and_place-tqc-seed2", [(0, 1, 0.0)], (120000, True, 2))
    _write_run(kept, "pick_and_place-sac-seed0", [(0, 1, 0.0)])
    _write_run(kept, "notes", [(0, 1, 0.0)])  # Not a cell's name: passed over (a traceback).
    reported = _benchmark_sh(tmp_path, "reference_timing.sh", "report")
    assert reported.returncode == 0, reported.stderr
    assert reported.stderr == ("not reported until every seed has finished: sac "
                               "(pick_and_place-sac-seed0, seed 1 not kept, seed 2 not kept)\n")
    tqc = [f"{kept}/pick_and_place-tqc-seed{seed}" for seed in range(3)]
    assert reported.stdout.splitlines() == _report_lines(kept, tqc, tqc)
    # SAC's seed 0 finished: still not reported, seeds 1 and 2 are not; SEEDS picks them.
    _write_run(kept, "pick_and_place-sac-seed0", [(0, 1, 0.0)], (500000, False, 2))
    reported = _benchmark_sh(tmp_path, "reference_timing.sh", "report")
    assert reported.stdout.splitlines() == _report_lines(kept, tqc, tqc)
    one_seed = _benchmark_sh(tmp_path, "reference_timing.sh", "report", SEEDS="0")
    assert (one_seed.returncode, one_seed.stderr) == (0, "")
    both = [f"{kept}/pick_and_place-{algo}-seed0" for algo in ("sac", "tqc")]
    assert one_seed.stdout.splitlines() == _report_lines(kept, both, both)


def _report_lines(kept, tested, plotted):
    """The commands `reference_timing.sh report` runs: the tests of `tested`, the curves
    and steps to 50/80/90 % of `plotted`."""
    return [
        f"franka-composer evaluate {' '.join(tested)} --episodes 20 --device cpu --out "
        f"{kept}/table.md",
        f"franka-composer evaluate {' '.join(tested)} --episodes 200 --seed 100 --device cpu "
        f"--out {kept}/table-200-episodes.md",
        f"franka-composer plot {' '.join(plotted)} --out {kept}/curves.png",
        f"franka-composer report {' '.join(plotted)} --thresholds 50 80 90 --paper-curves "
        f"results/paper-curves/curves.csv --out {kept}/report.md"]


def test_fast_preset_sh_trains_each_seed_in_turn_and_resumes_a_run_it_finds(tmp_path):
    """benchmarks/fast_preset.sh: the preset's measured runs, one `train` per seed with the
    task's step budget; a run directory already there is resumed, not started again."""
    (tmp_path / "runs" / "push-seed1").mkdir(parents=True)
    (tmp_path / "runs" / "push-seed1" / "config.json").write_text("{}")
    ran = _benchmark_sh(tmp_path, "fast_preset.sh", "push")
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.splitlines() == [
        f"franka-composer train --preset fast --task push --seed {seed} --out "
        f"{tmp_path}/runs/push-seed{seed}{resume} --total-steps 62000 --stop-at-success 0.95 "
        "--stop-after 5 --checkpoint-every 10000 --threads 1 --device cpu --no-progress"
        for seed, resume in ((0, ""), (1, " --resume"), (2, ""))]
    usage = _benchmark_sh(tmp_path, "fast_preset.sh", "slide")
    assert usage.returncode == 2 and usage.stdout.startswith("# The fast preset")
    # Every seed is checked before the first trains (seed 0 trained, then x was refused).
    for seed in ("x", "2147483648", "99999999999999999999"):
        mistyped = _benchmark_sh(tmp_path, "fast_preset.sh", "push", "0", seed,
                                 RUNS=str(tmp_path / "new-runs"))
        assert (mistyped.returncode, mistyped.stdout, mistyped.stderr) == (
            2, "", f"a seed must be an integer from 0 to 2147483647, got '{seed}'\n")
    assert not (tmp_path / "new-runs").exists()
    largest = _benchmark_sh(tmp_path, "fast_preset.sh", "push", "2147483647",
                            RUNS=str(tmp_path / "new-runs"))
    assert largest.returncode == 0 and "--seed 2147483647 " in largest.stdout
    synced = _benchmark_sh(tmp_path, "fast_preset.sh", "sync")
    assert synced.stdout == (f"franka-composer keep {tmp_path}/runs/push-seed1/ --into "
                             "results/fast-preset\n")
    # Stack and flip, beyond the preset's measured lane, are kept apart from it.
    (tmp_path / "runs" / "stack-seed0").mkdir()
    (tmp_path / "runs" / "pick_and_place-seed2").mkdir()
    synced = _benchmark_sh(tmp_path, "fast_preset.sh", "sync")
    assert synced.stdout.splitlines() == [
        f"franka-composer keep {tmp_path}/runs/push-seed1/ {tmp_path}/runs/pick_and_place-seed2/ "
        "--into results/fast-preset",
        f"franka-composer keep {tmp_path}/runs/stack-seed0/ --into results/fast-preset-stack-flip"]


def test_a_cell_another_process_is_training_is_refused_before_the_sweep_starts(tmp_path):
    """The cell's Ray task found the lock held and raised: the sweep ended with Ray's
    traceback and cancelled every other cell (one before its first checkpoint lost it)."""
    from franka_composer.training.sweep import run_sweep

    run = RunDir(tmp_path / "push-sac-seed0")
    holder = subprocess.Popen(
        [sys.executable, "-c", "import pathlib, sys, time\n"
         "from franka_composer.training.runs import RunDir\n"
         "with RunDir(pathlib.Path(sys.argv[1])).training_lock():\n"
         "    print('held', flush=True); time.sleep(60)\n", str(run.root)],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(ValueError, match=re.escape(
                f"{run.root} is being trained by process {holder.pid} on ")):
            run_sweep([Cell("push", "sac", 0, 200), Cell("push", "sac", 1, 200)], tmp_path,
                      show=lambda table: None)
        assert sorted(path.name for path in tmp_path.iterdir()) == ["push-sac-seed0"]
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.parametrize("flags, refused", [
    ("fpu sse avx avx2 fma f16c", True),  # An AVX2 EPYC: torch emulates bf16.
    (ZEN_4_FLAGS, False)])
def test_campaign_scripts_refuse_bf16_runs_on_a_cpu_without_bf16_units(tmp_path, flags,
                                                                      refused):
    """The background scripts' `refuse_emulated_bf16` (SAC's reference-timing cells, the
    fast preset's runs) reads the CPU's flags as `machine.bf16_units` does."""
    cpu = _cpu_with_flags(tmp_path / "cpu", flags)
    bin_dir = pathlib.Path(sys.executable).parent
    script = ("source benchmarks/background_sweep.sh && sweep_settings \"$RUNS_HERE\" && "
              "refuse_emulated_bf16 \"SAC's cells\"")
    done = subprocess.run(["bash", "-c", script], cwd=REPO, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(cpu),
                               "BIN": str(bin_dir), "RUNS_HERE": str(tmp_path / "runs")})
    assert done.returncode == (1 if refused else 0), done.stderr
    assert ("SAC's cells train in bf16, and this CPU has no bf16 units" in done.stderr) == refused
    assert not (tmp_path / "runs").exists()
