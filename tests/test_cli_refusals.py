"""Bad input to the subcommands is refused with one clear error naming what was wrong, before
anything is built or written: output paths where nothing can be written, damaged run files
(also before `keep` and `sweep --sync` copy anything), and options that would be ignored."""

from __future__ import annotations

import json
import os
import pathlib
import re
import stat

import pytest

from conftest import write_policy_file
from franka_composer import cli
from franka_composer.training import hyperparameters
from franka_composer.training.run_config import RunConfig
from franka_composer.training.runs import RunDir, read_eval_rows

#: A folder in which not even root can make a file (Linux's /proc).
PROC = pathlib.Path("/proc")
needs_proc = pytest.mark.skipif(not PROC.is_dir(), reason="no /proc here")
HEADER = "steps,wall_time_s,success_rate,mean_reward\n"


def _run(root: pathlib.Path, rows: str = "0,1,0.0,-1\n2000,2,0.5,-1\n",
         outcome: bool = True, seed: int = 0) -> RunDir:
    """A push SAC run of 2000 steps with `rows` in its eval.csv, finished if `outcome`."""
    run = RunDir(root)
    run.write_config(RunConfig("push", "sac", seed, hyperparameters("push", "sac").replace(
        total_steps=2000)))
    run.eval_csv.write_text(HEADER + rows)
    if outcome:
        run.write_outcome(2000, False, 2.0)
    return run


def _parse_error(argv: list[str], capsys) -> str:
    """The last line argparse prints refusing `argv`."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(argv)
    assert exit_info.value.code == 2
    return capsys.readouterr().err.splitlines()[-1]


#: Each output option, as (command line before it, the option); RUN is a run directory.
OUTPUTS = [(["demo"], "--out"), (["train"], "--out"), (["keep", "RUN"], "--into"),
           (["sweep", "--grid", "table2", "--out", "sweep"], "--sync"),
           (["evaluate", "RUN"], "--out"), (["plot", "RUN"], "--out"),
           (["report", "RUN"], "--out")]


@pytest.mark.parametrize("before, option", OUTPUTS)
def test_an_output_path_under_a_file_is_refused_as_parsed(before, option, tmp_path, capsys):
    (tmp_path / "afile").write_text("kept")
    path = tmp_path / "afile" / ("x.png" if before[0] == "plot" else "x")
    error = _parse_error([*before, option, str(path)], capsys)
    assert error.endswith(f"error: argument {option}: cannot write to {path}: "
                          f"{tmp_path / 'afile'} is not a folder")
    assert (tmp_path / "afile").read_text() == "kept"


@pytest.mark.parametrize("before, option", [*OUTPUTS, (["rollout", "--task", "push"], "--out"),
                                            (["evaluate"], "RUN_DIR")])
def test_an_empty_path_is_refused_as_parsed(before, option, capsys):
    """pathlib reads "" as the working folder: `evaluate ""` scanned it for runs, and
    `rollout --out ""` said "." must end in .npz."""
    given = [option, ""] if option.startswith("--") else [""]
    error = _parse_error([*before, *given], capsys)
    assert error.endswith(f"error: argument {option}: must be a path, got an empty one ('')")


@needs_proc
@pytest.mark.parametrize("before, option", OUTPUTS)
def test_an_output_path_where_no_file_can_be_made_is_refused_as_parsed(before, option, capsys):
    """os.access says yes to root in /proc: a file made and removed again says no."""
    path = PROC / "franka-composer" / ("x.png" if before[0] == "plot" else "x")
    error = _parse_error([*before, option, str(path)], capsys)
    assert re.search(f"error: argument {option}: cannot write to {path}: no file can be made "
                     r"in /proc \(.+\)$", error)


@pytest.mark.parametrize("before, option", [o for o in OUTPUTS if o[1] == "--out"
                                             and o[0][0] in ("evaluate", "plot", "report")])
def test_an_output_file_that_is_a_fifo_is_refused_as_parsed_and_left_one(before, option,
                                                                        tmp_path, capsys):
    """Written over atomically, a FIFO, a device or a socket would be replaced by a file
    (as root, /dev/null was): refused instead, and left as it was."""
    fifo = tmp_path / ("fifo.png" if before[0] == "plot" else "fifo")
    os.mkfifo(fifo)
    error = _parse_error([*before, option, str(fifo)], capsys)
    assert error.endswith(f"error: argument {option}: cannot write to {fifo}: it is not a "
                          "regular file (a device, FIFO or socket), which a file written in "
                          "its place would replace; give a file's path")
    assert stat.S_ISFIFO(fifo.lstat().st_mode)


def test_an_output_file_through_a_link_is_written_through_and_the_link_kept(tmp_path):
    from franka_composer.atomic_files import replace_atomically
    from franka_composer.validation import check_writable

    (tmp_path / "real").mkdir()
    target = tmp_path / "real" / "table.md"
    target.write_text("old")
    link = tmp_path / "table.md"
    link.symlink_to(target)
    assert check_writable(link) == link
    replace_atomically(link, lambda path: path.write_text("new"))
    assert link.is_symlink() and target.read_text() == "new"
    assert sorted(path.name for path in (tmp_path / "real").iterdir()) == ["table.md"]
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match=f"cannot write to {fifo}: it is not a regular file"):
        replace_atomically(fifo, lambda path: path.write_text("new"))
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    # A link to a FIFO is one; a link into a folder that is not there is refused before the
    # work whose file would then find no place.
    to_fifo, dangling = tmp_path / "to-fifo", tmp_path / "dangling.md"
    to_fifo.symlink_to(fifo)
    dangling.symlink_to(tmp_path / "missing" / "table.md")
    with pytest.raises(ValueError, match=f"cannot write to {to_fifo}: it is not a regular"):
        check_writable(to_fifo)
    with pytest.raises(ValueError, match=re.escape(
            f"cannot write to {dangling}: it is a link to {tmp_path / 'missing' / 'table.md'}, "
            "in a folder that does not exist")):
        check_writable(dangling)


def test_plot_refuses_a_format_that_cannot_be_written_here_as_parsed(tmp_path, monkeypatch,
                                                                     capsys):
    """pgf passed the extension check and, with no TeX to measure its text, failed with a
    RuntimeError once the figure was drawn."""
    monkeypatch.setenv("PATH", str(tmp_path / "no-tex"))
    run, out = _run(tmp_path / "run"), tmp_path / "curves.pgf"
    error = _parse_error(["plot", str(run.root), "--out", str(out)], capsys)
    assert error.endswith(f"error: argument --out: cannot write pgf files here, got "
                          f"'{out}': 'xelatex' not found; install it or change "
                          "rcParams['pgf.texsystem'] to an available TeX implementation")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["run"]


def test_a_writable_output_path_is_taken_and_its_folder_left_as_it_was(tmp_path):
    """Not even the folder's modification time changes (`sweep` parses each cell's `train`
    --out, and a look must not touch a run)."""
    before = tmp_path.stat().st_mtime_ns
    args = cli.build_parser().parse_args(["keep", "RUN", "--into", str(tmp_path / "a" / "b")])
    assert args.into == tmp_path / "a" / "b"
    args = cli.build_parser().parse_args(["report", "RUN", "--out", str(tmp_path / "r.md")])
    assert args.out == tmp_path / "r.md"
    assert list(tmp_path.iterdir()) == [] and tmp_path.stat().st_mtime_ns == before


@pytest.mark.parametrize("format, name, message", [
    ("npz", "afile/x.npz", "cannot write to {tmp}/afile/x.npz: {tmp}/afile is not a folder"),
    ("npz", "folder.npz", "an npz dataset is a file, and {tmp}/folder.npz is a folder"),
    ("minari", "afile/data", "cannot write to {tmp}/afile/data: {tmp}/afile is not a folder"),
    ("rlds", "afile/data", "cannot write to {tmp}/afile/data: {tmp}/afile is not a folder"),
])
def test_rollout_refuses_an_out_it_cannot_write_before_recording(format, name, message,
                                                                   tmp_path):
    (tmp_path / "afile").write_text("kept")
    (tmp_path / "folder.npz").mkdir()
    with pytest.raises(ValueError, match=f"^{re.escape(message.format(tmp=tmp_path))}$"):
        cli.main(["rollout", "--task", "push", "--episodes", "1", "--format", format,
                  "--out", str(tmp_path / name)])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["afile", "folder.npz"]
    assert list((tmp_path / "folder.npz").iterdir()) == []


@needs_proc
@pytest.mark.parametrize("format, name", [("npz", "x.npz"), ("minari", "data"),
                                          ("rlds", "data")])
def test_rollout_refuses_an_out_where_no_file_can_be_made(format, name):
    with pytest.raises(ValueError, match=re.escape(f"cannot write to /proc/{name}: no file "
                                                   "can be made in /proc (")):
        cli.main(["rollout", "--task", "push", "--episodes", "1", "--format", format,
                  "--out", f"/proc/{name}"])


def test_an_os_error_that_escapes_is_one_line_and_status_1(monkeypatch, capsys):
    def fails(argv):
        raise PermissionError(13, "Permission denied", "table.md")

    monkeypatch.setattr(cli, "main", fails)
    assert cli.console(["report", "RUN"]) == 1
    assert capsys.readouterr().err == (
        "franka-composer: error: [Errno 13] Permission denied: 'table.md'\n")


def test_rollout_refuses_a_dataset_id_outside_minari(tmp_path):
    for format in ("npz", "rlds"):
        out = tmp_path / ("x.npz" if format == "npz" else "x")
        with pytest.raises(ValueError, match="^--dataset-id names a Minari dataset: give it "
                                             "with --format minari$"):
            cli.main(["rollout", "--task", "push", "--episodes", "1", "--format", format,
                      "--dataset-id", "foo", "--out", str(out)])
    assert list(tmp_path.iterdir()) == []


def test_demo_refuses_more_video_episodes_than_episodes(tmp_path):
    with pytest.raises(ValueError, match="^--video-episodes 5 is more than --episodes 1: "
                                         "each task's video shows its first episodes$"):
        cli.main(["demo", "--episodes", "1", "--video-episodes", "5", "--out",
                  str(tmp_path / "videos")])
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="^--video-episodes sets what the videos show, and "
                                         "--no-video writes none: give one of them$"):
        cli.main(["demo", "--episodes", "1", "--video-episodes", "1", "--no-video"])
    # Without --video-episodes, a short demo's video shows every episode it has.
    assert cli.build_parser().parse_args(["demo", "--episodes", "1"]).video_episodes is None


def test_a_policy_or_run_that_does_not_exist_is_named_so(tmp_path):
    missing = tmp_path / "nothere"
    for argv in (["rollout", "--task", "push", "--episodes", "1", "--policy", str(missing),
                  "--out", str(tmp_path / "x.npz")],
                 ["report", str(missing)]):
        with pytest.raises(ValueError, match=f"^{re.escape(str(missing))} does not exist$"):
            cli.main(argv)
    with pytest.raises(ValueError, match="is not a training run \\(no config.json\\)$"):
        RunDir(tmp_path).read_config()


def test_a_policy_run_with_nothing_trained_is_named_before_anything_is_made(tmp_path,
                                                                              monkeypatch):
    """A run still training, kept without a model: demo and rollout with --policy say so
    before an env is built or a dataset begun."""
    import shutil

    import gymnasium

    from franka_composer.training import models

    made = []
    monkeypatch.setattr(gymnasium, "make", lambda *args, **kwargs: made.append(args))
    monkeypatch.setattr(models, "make_env", lambda *args, **kwargs: made.append(args))
    kept = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-ddpg-seed1"
    training = tmp_path / "training"
    training.mkdir()
    shutil.copy(kept / "config.json", training / "config.json")
    no_model = f"^{re.escape(str(training))} has no model yet \\(no model.zip, no checkpoint, "
    for argv in (["demo", "--policy", str(training), "--out", str(tmp_path / "videos")],
                 ["rollout", "--task", "push", "--episodes", "1", "--policy", str(training),
                  "--out", str(tmp_path / "x.npz")]):
        with pytest.raises(ValueError, match=no_model):
            cli.main(argv)
    assert made == [] and sorted(path.name for path in tmp_path.iterdir()) == ["training"]


def test_rollout_of_a_policy_takes_its_runs_task_and_controller(tmp_path):
    """`rollout --policy RUN` needed --task and --control repeated (an osc run without
    them was refused as a mocap push); now, like `demo --policy`, it takes the run's, and
    names a --task or --control that asks for others."""
    from franka_composer.policies import Trajectories

    committed = pathlib.Path(__file__).parents[1] / "results" / "push-osc-sac-seed0"
    out = tmp_path / "osc.npz"
    assert cli.main(["rollout", "--policy", str(committed), "--episodes", "1", "--out",
                     str(out)]) == 0
    recorded = Trajectories.load(out).metadata
    assert (recorded["id"], recorded["source"]) == ("FrankaPushOscSparse-v0", "policy")
    for given, message in ((["--task", "slide"], "was trained on push, not --task slide"),
                           (["--control", "mocap"], "acts through osc control, not "
                                                    "--control mocap")):
        with pytest.raises(ValueError, match=f"^--policy {re.escape(str(committed))} "
                                             f"{message}$"):
            cli.main(["rollout", "--policy", str(committed), *given, "--episodes", "1",
                      "--out", str(tmp_path / "other.npz")])
    with pytest.raises(ValueError, match=re.escape(
            "rollout needs --task (or --policy RUN_DIR: its run's task)")):
        cli.main(["rollout", "--episodes", "1", "--out", str(tmp_path / "none.npz")])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["osc.npz"]


def test_a_policy_that_cannot_act_is_named_before_anything_is_made(tmp_path, monkeypatch):
    """A damaged policy.pt, and a timing given that is not the run's, were found only once
    the env was built (and, by demo, its episode begun)."""
    import shutil

    import gymnasium

    from franka_composer.training import models

    made = []
    monkeypatch.setattr(gymnasium, "make", lambda *args, **kwargs: made.append(args))
    monkeypatch.setattr(models, "make_env", lambda *args, **kwargs: made.append(args))
    kept = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-ddpg-seed1"
    damaged, committed = tmp_path / "damaged", tmp_path / "committed"
    for run in (damaged, committed):
        run.mkdir()
        shutil.copy(kept / "config.json", run / "config.json")
    (damaged / "policy.pt").write_text("junk")
    shutil.copy(kept / "policy.pt", committed / "policy.pt")
    not_a_policy = f"^{re.escape(str(damaged / 'policy.pt'))} is not a policy file \\(torch "
    for argv in (["demo", "--policy", str(damaged), "--no-video"],
                 ["rollout", "--task", "push", "--episodes", "1", "--policy", str(damaged),
                  "--out", str(tmp_path / "x.npz")]):
        with pytest.raises(ValueError, match=not_a_policy):
            cli.main(argv)
    for argv in (["demo", "--policy", str(committed), "--no-video"],
                 ["rollout", "--task", "push", "--episodes", "1", "--policy", str(committed),
                  "--out", str(tmp_path / "x.npz")]):
        with pytest.raises(ValueError, match=re.escape(
                f"{committed} acts every 0.05 s, not every 0.5 s")):
            cli.main([*argv, "--control-timestep", "0.5"])
    # Into the run's own files: its expert's demonstrations, written over.
    with pytest.raises(ValueError, match=re.escape(
            f"--out {committed / 'expert-demos.npz'} is one of the run {committed}'s own "
            "files: give another file")):
        cli.main(["rollout", "--task", "push", "--episodes", "1", "--policy", str(committed),
                  "--out", str(committed / "expert-demos.npz")])
    assert sorted(path.name for path in committed.iterdir()) == ["config.json", "policy.pt"]
    elsewhere = tmp_path / "elsewhere"  # Trained in another suite's env.
    shutil.copytree(committed, elsewhere)
    config = json.loads((elsewhere / "config.json").read_text())
    (elsewhere / "config.json").write_text(json.dumps({**config,
                                                       "environment": "panda_mujoco_gym"}))
    with pytest.raises(ValueError, match=re.escape(
            f"{elsewhere} trained in panda_mujoco_gym's push environment, not this suite's")):
        cli.main(["demo", "--policy", str(elsewhere), "--no-video"])
    assert made == []
    assert sorted(path.name for path in tmp_path.iterdir()) == ["committed", "damaged",
                                                                "elsewhere"]


@pytest.mark.parametrize("row, problem", [
    ("2000,2,7.0,-1", "success_rate must be within [0, 1], got 7.0"),
    ("2000,2,0.5,nan", "mean_reward must be a finite number, got nan"),
    ("2000,2,0.5,-inf", "mean_reward must be a finite number, got -inf"),
    ("2000,2,-2,-1", "success_rate must be within [0, 1], got -2.0"),
    ("2000,2,inf,-1", "success_rate must be within [0, 1], got inf"),
    ("2000,2,nan,-1", "success_rate must be within [0, 1], got nan"),
    ("2000,nan,0.5,-1", "wall_time_s must be a finite number >= 0, got nan"),
    ("2000,-1,0.5,-1", "wall_time_s must be a finite number >= 0, got -1.0"),
    ("2000,inf,0.5,-1", "wall_time_s must be a finite number >= 0, got inf"),
    ("-100,2,0.5,-1", "steps must be a whole number >= 0, got -100.0"),
    ("1500.5,2,0.5,-1", "steps must be a whole number >= 0, got 1500.5"),
    ("inf,2,0.5,-1", "steps must be a whole number >= 0, got inf"),
    ("1000,2,0.5,-1", "steps must increase from row to row, got 1000 after 1000"),
    ("500,2,0.5,-1", "steps must increase from row to row, got 500 after 1000"),
])
def test_an_eval_csv_row_no_run_writes_is_named_with_its_line(row, problem, tmp_path):
    path = tmp_path / "eval.csv"
    path.write_text(HEADER + "0,1,0.0,-1\n1000,1.5,0.25,-1\n" + row + "\n")
    with pytest.raises(ValueError, match=f"^{re.escape(f'{path}, line 4: {problem}')}$"):
        read_eval_rows(path)


@pytest.mark.parametrize("command, written", [("plot", "curves.png"), ("report", "report.md")])
def test_plot_and_report_refuse_a_success_rate_out_of_range(command, written, tmp_path):
    run = _run(tmp_path / "run", rows="0,1,0.0,-1\n2000,2,7.0,-1\n")
    with pytest.raises(ValueError, match=re.escape(
            f"{run.eval_csv}, line 3: success_rate must be within [0, 1], got 7.0")):
        cli.main([command, str(run.root), "--out", str(tmp_path / written)])
    assert not (tmp_path / written).exists()


@pytest.mark.parametrize("damage, message", [
    (("eval.csv", HEADER + "0,1,7.0,-1\n"),
     "eval.csv, line 2: success_rate must be within [0, 1], got 7.0"),
    (("outcome.json", "{x"), "outcome.json is not a run's outcome: Expecting property name"),
    (("outcome.json", '{"wall_time_s": 2}'), "outcome.json is not a run's outcome: it needs "
                                             "a whole number of steps, 0 or more, and "
                                             "stopped_early true or false"),
    # Read as "steps reached -5" and "inf wall-clock hours, -0.0 CPU hours" by `report`.
    (("outcome.json", '{"steps": -5, "stopped_early": false}'),
     "outcome.json is not a run's outcome: it needs a whole number of steps, 0 or more, and "
     "stopped_early true or false"),
    (("outcome.json", '{"steps": 2000, "stopped_early": false, "wall_time_s": Infinity}'),
     "outcome.json is not a run's outcome: its wall_time_s must be a number of seconds, 0 "
     "or more, got inf"),
    (("outcome.json", '{"steps": 2000, "stopped_early": false, "cpu_time_s": -3}'),
     "outcome.json is not a run's outcome: its cpu_time_s must be a number of seconds, 0 or "
     "more, got -3"),
    # Copied by `keep` ("eval.csv up to its checkpoint"), counted by `report`.
    (("eval.csv", HEADER + "0,1,0.0,-1\n2000,2,0.5,-1\n3000,3,0.5,-1\n"),
     "eval.csv, line 4: an evaluation at step 3,000, past the run's end at step 2,000 "
     "(outcome.json): edited, or another run's?"),
    (("config.json", "{x"), "config.json is not a run's config: Expecting property name"),
    (("eval.csv", HEADER + "0,1,0.0,-1\n"),
     "eval.csv ends at step 0, and the run ended at step 2,000 (outcome.json), where it "
     "evaluated last: cut short, or another run's?"),
])
def test_keep_checks_every_run_before_copying_anything(damage, message, tmp_path):
    good, bad = _run(tmp_path / "runs" / "a"), _run(tmp_path / "runs" / "b", seed=1)
    name, text = damage
    (bad.root / name).write_text(text)
    kept = tmp_path / "kept"
    with pytest.raises(ValueError, match=re.escape(f"{bad.root / message}")):
        cli.main(["keep", str(good.root), str(bad.root), "--into", str(kept)])
    assert not kept.exists()


def test_keep_refuses_a_folder_where_a_finished_runs_policy_file_belongs(tmp_path):
    """It kept the run without its policy, saying nothing (a folder is not a file)."""
    good, bad = _run(tmp_path / "runs" / "a"), _run(tmp_path / "runs" / "b", seed=1)
    bad.policy_file.mkdir()
    kept = tmp_path / "kept"
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{bad.policy_file} is a folder, where {bad.root} keeps a model file: move it "
            "away") + "$"):
        cli.main(["keep", str(good.root), str(bad.root), "--into", str(kept)])
    assert not kept.exists()


@pytest.mark.parametrize("command", ["keep", "report", "plot"])
def test_a_run_that_has_ended_without_its_evaluations_is_refused(command, tmp_path):
    """`keep` copied it as a header-only eval.csv beside its outcome and policy, which
    `report` then refused."""
    run = _run(tmp_path / "run")
    run.eval_csv.unlink()
    out = {"keep": ["--into", str(tmp_path / "kept")],
           "report": ["--out", str(tmp_path / "report.md")],
           "plot": ["--out", str(tmp_path / "curves.png")]}[command]
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{run.root} has ended and has no evaluations (its eval.csv lost or emptied?)")):
        cli.main([command, str(run.root), *out])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("command", ["keep", "report", "plot"])
def test_a_run_that_has_ended_with_its_evaluations_cut_short_is_refused(command, tmp_path):
    """`report` read the curve as ending where eval.csv was cut (no crossing found past it,
    exit 0) and `plot` drew it so; an ended run evaluates at its last step."""
    run = _run(tmp_path / "run", rows="0,1,0.0,-1\n1000,2,0.5,-1\n")
    out = {"keep": ["--into", str(tmp_path / "kept")],
           "report": ["--out", str(tmp_path / "report.md")],
           "plot": ["--out", str(tmp_path / "curves.png")]}[command]
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{run.eval_csv} ends at step 1,000, and the run ended at step 2,000 "
            "(outcome.json), where it evaluated last: cut short, or another run's?") + "$"):
        cli.main([command, str(run.root), *out])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("edit, message", [
    ({"total_steps": None}, "total_steps must be a whole number >= 1, got None"),
    ({"eval_every": None}, "eval_every must be a whole number >= 1, got None"),
    ({"demos": 5}, "demos must be a dataset's path or None, got 5"),
    ({"demos": ["push.npz"]}, "demos must be a dataset's path or None, got ['push.npz']"),
    ({"terminate_on_success": "false"}, "terminate_on_success must be True or False, got "
                                        "'false'"),
    ({"seed": 7.9}, "seed must be a whole number >= 0 and <= 2147483647, got 7.9"),
    ({"seed": -3}, "seed must be >= 0 and <= 2147483647, got -3"),
    ({"demo_episodes": "abc"}, "demo_episodes must be a whole number >= 1, got 'abc'"),
    ({"contrl": "joints"}, "unknown key(s) 'contrl'; valid keys: algo, backend, control, "
                           "control_timestep, demo_episodes, demos, environment, "
                           "expert_demos, guard_ignores_carried, hyperparameters, "
                           "object_damping, precision, preset, randomization, seed, task, "
                           "terminate_on_success, velocity_timestep, weld_time_constant"),
])
def test_a_config_json_value_of_the_wrong_type_or_null_is_refused_by_name(edit, message,
                                                                          tmp_path):
    """A null total_steps was read as 500,000 steps, "false" as True and seed 7.9 as 7;
    demos 5 raised a TypeError from `report`, `evaluate` and `keep`; a misspelt key was
    passed over (the default read in its place). The nulls that some
    runs record (SAC's n_critics, no stopping rule) stay readable."""
    run = _run(tmp_path / "run")
    config = json.loads(run.config_path.read_text())
    assert config["hyperparameters"]["n_critics"] is None
    assert config["hyperparameters"]["stop_success_rate"] is None
    assert run.read_config().hyperparameters.n_critics is None
    name, value = next(iter(edit.items()))
    if name in config["hyperparameters"]:
        config["hyperparameters"][name] = value
    else:
        config[name] = value
    run.config_path.write_text(json.dumps(config))
    refused = "^" + re.escape(f"{run.config_path} is not a run's config: {message}") + "$"
    with pytest.raises(ValueError, match=refused):
        run.read_config()
    for command in (["report", str(run.root)], ["evaluate", str(run.root)],
                    ["keep", str(run.root), "--into", str(tmp_path / "kept")]):
        with pytest.raises(ValueError, match=refused):
            cli.main(command)
    assert not (tmp_path / "kept").exists()


def test_keep_refuses_a_file_where_a_run_would_go_before_copying_anything(tmp_path):
    """It raised FileExistsError (exit status 1) after the runs before it were copied."""
    good, other = _run(tmp_path / "runs" / "a"), _run(tmp_path / "runs" / "b", seed=1)
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "b").write_text("x")
    with pytest.raises(ValueError, match=re.escape(
            f"{kept / 'b'} is a file, not a folder: move it away to keep {other.root} "
            "there")):
        cli.main(["keep", str(good.root), str(other.root), "--into", str(kept)])
    assert sorted(path.name for path in kept.iterdir()) == ["b"]


def test_keep_copies_each_file_whole_or_not_at_all(tmp_path, monkeypatch):
    """A copy that fails halfway (a full disk) leaves the kept file as it was, not half of
    the run's: what keep writes is committed."""
    import shutil

    run = _run(tmp_path / "run")
    write_policy_file(run.policy_file, 1000)
    kept = tmp_path / "kept"
    assert cli.main(["keep", str(run.root), "--into", str(kept)]) == 0
    copied = (kept / "run" / "policy.pt").read_bytes()
    write_policy_file(run.policy_file, 2000)
    copy = shutil.copy

    def half(source, target):
        copy(source, target)
        if pathlib.Path(source).name == "policy.pt":
            with open(target, "r+b") as written:
                written.truncate(100)
            raise OSError(28, "No space left on device")
        return target

    monkeypatch.setattr(shutil, "copy", half)
    with pytest.raises(OSError, match="No space left"):
        cli.main(["keep", str(run.root), "--into", str(kept)])
    assert (kept / "run" / "policy.pt").read_bytes() == copied
    assert sorted(path.name for path in (kept / "run").iterdir()) == [
        "config.json", "eval.csv", "outcome.json", "policy.pt"]  # No partial file left.


def test_keep_refuses_a_damaged_policy_file_and_keeps_a_lost_ones_copy(tmp_path):
    """A finished run's policy.pt is read before anything is copied: a damaged one would
    replace the whole one kept. A finished run that lost its policy.pt leaves the kept copy
    (of the same run) as it was; one taken on to a larger budget drops it until it ends."""
    run = _run(tmp_path / "run")
    write_policy_file(run.policy_file, 10)
    kept = tmp_path / "kept"
    assert cli.main(["keep", str(run.root), "--into", str(kept)]) == 0
    whole = (kept / "run" / "policy.pt").read_bytes()
    run.policy_file.write_bytes(b"")
    with pytest.raises(ValueError, match=re.escape(f"{run.policy_file} is not a policy file "
                                                   "(torch cannot read it")):
        cli.main(["keep", str(run.root), "--into", str(kept)])
    assert (kept / "run" / "policy.pt").read_bytes() == whole
    run.policy_file.unlink()
    assert cli.main(["keep", str(run.root), "--into", str(kept)]) == 0
    assert (kept / "run" / "policy.pt").read_bytes() == whole
    run.outcome_path.unlink()  # Taken on: not finished.
    assert cli.main(["keep", str(run.root), "--into", str(kept)]) == 0
    assert not (kept / "run" / "policy.pt").exists()


def test_keep_refuses_to_keep_a_run_into_itself(tmp_path):
    run = _run(tmp_path / "run")
    before = sorted(os.listdir(run.root))
    with pytest.raises(ValueError, match=f"^--into {re.escape(str(run.root))} is the run "
                                         "itself: give a folder outside the runs$"):
        cli.main(["keep", str(run.root), "--into", str(run.root)])
    inside = run.root / "kept"
    with pytest.raises(ValueError, match=f"^--into {re.escape(str(inside))} is inside the run "
                                         f"{re.escape(str(run.root))}: give a folder outside "
                                         "the runs$"):
        cli.main(["keep", str(run.root), "--into", str(inside)])
    assert sorted(os.listdir(run.root)) == before


def test_a_resume_of_a_kept_copy_says_it_is_one(tmp_path):
    """It said the copy had stopped before its first checkpoint, and to delete it: the
    kept results."""
    run = _run(tmp_path / "runs" / "run")
    write_policy_file(run.policy_file, 10)
    assert cli.main(["keep", str(run.root), "--into", str(tmp_path / "kept")]) == 0
    kept = tmp_path / "kept" / "run"
    files = {path.name: path.read_bytes() for path in kept.iterdir()}
    assert sorted(files) == ["config.json", "eval.csv", "outcome.json", "policy.pt"]
    for budget in ([], ["--total-steps", "4000"]):
        with pytest.raises(ValueError, match="^" + re.escape(
                f"{kept} is a kept copy of a finished run (its policy.pt kept, no checkpoint "
                "to resume from): resume the run it was kept from, or start a new one") + "$"):
            cli.main(["train", "--resume", "--out", str(kept), *budget])
    assert {path.name: path.read_bytes() for path in kept.iterdir()} == files


def _sweep(out: pathlib.Path, *more: str) -> list[str]:
    return ["sweep", "--out", str(out), "--tasks", "push", "--algos", "sac", "--seeds", "0",
            "1", "--steps", "2000", *more]


def test_sweep_status_and_sync_name_a_cells_damaged_config(tmp_path, capsys):
    """A finished cell whose config.json is garbage is not "done", nor copied."""
    out = tmp_path / "sweep"
    _run(out / "push-sac-seed0")
    damaged = _run(out / "push-sac-seed1", seed=1)
    damaged.config_path.write_text("{x")
    message = (f"^{re.escape(str(damaged.config_path))} is not a run's config: Expecting "
               "property name enclosed in double quotes")
    with pytest.raises(ValueError, match=message):
        cli.main(_sweep(out, "--status"))
    with pytest.raises(ValueError, match=message):
        cli.main(_sweep(out, "--sync", str(tmp_path / "kept")))
    assert not (tmp_path / "kept").exists()
    assert capsys.readouterr().out == ""


@needs_proc
def test_sweep_reads_an_out_it_cannot_write_and_refuses_to_train_there(capsys, monkeypatch):
    """--status and --sync only read --out (a sweep on a read-only mount can be looked at);
    a sweep that would train there is refused before Ray starts."""
    import ray

    monkeypatch.setattr(ray, "init", lambda *args, **kwargs: pytest.fail("Ray started"))
    out = PROC / "franka-composer-sweep"
    assert cli.main(_sweep(out, "--status")) == 0
    assert capsys.readouterr().out.splitlines()[2:] == [
        "| push-sac-seed0 | waiting | 0 | 2,000 | – | – |",
        "| push-sac-seed1 | waiting | 0 | 2,000 | – | – |"]
    with pytest.raises(ValueError, match=f"^--out: cannot write to {re.escape(str(out))}: no "
                                         r"file can be made in /proc \(.+\)$"):
        cli.main(_sweep(out))


def test_sweep_sync_refuses_the_sweeps_own_folder(tmp_path):
    out = tmp_path / "sweep"
    run = _run(out / "push-sac-seed0", rows="0,1,0.0,-1\n1000,2,0.2,-1\n2000,3,0.4,-1\n",
               outcome=False)
    run.checkpoint.mkdir()
    run.checkpoint_state.write_text(json.dumps({"steps": 1000}))
    before = run.eval_csv.read_bytes()
    with pytest.raises(ValueError, match="push-sac-seed0 is the run itself: give --sync a "
                                         "folder other than the one holding the runs$"):
        cli.main(_sweep(out, "--sync", str(out)))
    assert run.eval_csv.read_bytes() == before  # Not cut back to its checkpoint.


def test_stop_after_without_a_rate_is_refused_before_the_run_exists(tmp_path):
    """It counts evaluations for --stop-at-success: alone, it was silently ignored."""
    with pytest.raises(ValueError, match=re.escape(
            "--stop-after counts evaluations for --stop-at-success RATE, and no "
            "--stop-at-success was given")):
        cli.main(["train", "--task", "push", "--stop-after", "3", "--out",
                  str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


def test_train_names_a_folder_that_holds_a_run_before_loading_its_demos(tmp_path,
                                                                        monkeypatch):
    """It loaded and checked the whole dataset (seconds, an env built) first."""
    from franka_composer.training import demos

    run = _run(tmp_path / "run", outcome=False)
    monkeypatch.setattr(demos, "load_episodes",
                        lambda *args, **kwargs: pytest.fail("the demos were loaded"))
    with pytest.raises(ValueError, match=re.escape(f"{run.root} already holds a run; pass "
                                                   "--resume to continue it")):
        cli.main(["train", "--task", "push", "--algo", "sac", "--out", str(run.root),
                  "--demos", str(tmp_path / "push.npz")])


@pytest.mark.skipif(__import__("torch").cuda.is_available(), reason="a CUDA GPU is here")
def test_device_cuda_without_a_gpu_is_refused_before_an_env_is_built(tmp_path, monkeypatch):
    """evaluate built the first run's env, and a resume two, before saying so."""
    from franka_composer.training import models

    monkeypatch.setattr(models, "make_env",
                        lambda *args, **kwargs: pytest.fail("an env was built"))
    run = _run(tmp_path / "run")
    message = "^--device cuda, but torch sees no CUDA GPU"
    with pytest.raises(ValueError, match=message):
        cli.main(["evaluate", str(run.root), "--device", "cuda"])
    with pytest.raises(ValueError, match=message):
        cli.main(["train", "--resume", "--out", str(run.root), "--device", "cuda"])


def test_demo_refuses_videos_inside_a_run(tmp_path):
    """Into a run's checkpoint folder they went, and its next checkpoint deleted them."""
    run = _run(tmp_path / "run", outcome=False)
    inside = run.root / "checkpoint-500-0a1b2c3d"
    with pytest.raises(ValueError, match="^" + re.escape(
            f"--out {inside} is inside the run {run.root}: give a folder outside it") + "$"):
        cli.main(["demo", "--tasks", "reach", "--episodes", "1", "--out", str(inside)])
    assert sorted(path.name for path in run.root.iterdir()) == ["config.json", "eval.csv"]


def test_a_control_step_that_would_run_for_hours_is_refused(tmp_path):
    """1e9 s reached MuJoCo as 5e11 steps and failed there with a traceback; 2000001 s (a
    mistyped 0.002) was 1e9 steps, which MuJoCo takes in one call: each step ran for hours,
    and `timeout`'s SIGTERM waited for it (the run's directory made). At most 100 s."""
    import franka_composer

    for seconds in (1e9, 2000001.0, 100.002):
        with pytest.raises(ValueError, match=re.escape(
                "control_timestep must be at most 50,000 physics steps of 0.002 s (100 s), "
                f"got {seconds!r}")):
            franka_composer.load("push", control_timestep=seconds)
    assert franka_composer.load("push", control_timestep=100.0).control_timestep() == 100.0
    out = tmp_path / "run"
    with pytest.raises(ValueError, match="at most 50,000 physics steps"):
        cli.main(["train", "--task", "push", "--control-timestep", "2000001", "--out",
                  str(out)])
    assert not out.exists()


def test_report_and_evaluate_refuse_to_write_over_a_runs_own_files(tmp_path):
    """`report RUN --out RUN/eval.csv` replaced the run's evaluations with the table."""
    run = _run(tmp_path / "run")
    before = {path.name: path.read_bytes() for path in run.root.iterdir()}
    for command, own in (("report", run.eval_csv), ("evaluate", run.config_path),
                         ("report", run.checkpoint / "state.json"),
                         ("evaluate", run.evaluations_npz)):
        with pytest.raises(ValueError, match=f"^--out {re.escape(str(own))} is one of the run "
                                             f"{re.escape(str(run.root))}'s own files: give "
                                             "another file$"):
            cli.main([command, str(run.root), "--out", str(own)])
    assert {path.name: path.read_bytes() for path in run.root.iterdir()} == before
    assert cli.main(["report", str(run.root), "--out", str(run.root / "report.md")]) == 0
    # Nor over another run's: a mistyped --out left that run unreadable (its config.json a
    # table), and `rollout` checked no run at all.
    other = _run(tmp_path / "other", seed=1)
    kept = {path.name: path.read_bytes() for path in other.root.iterdir()}
    for command in (["report", str(run.root)], ["evaluate", str(run.root)],
                    ["rollout", "--task", "push", "--episodes", "1"]):
        for own in (other.config_path, other.root / "expert-demos.npz"):
            with pytest.raises(ValueError, match=f"^--out {re.escape(str(own))} is one of the "
                                                 f"run {re.escape(str(other.root))}'s own "
                                                 "files: give another file$"):
                cli.main([*command, "--out", str(own)])
    assert {path.name: path.read_bytes() for path in other.root.iterdir()} == kept


def test_keep_refuses_to_keep_a_run_into_another(tmp_path):
    """The copy went inside the other run's folder, a run within a run."""
    run, other = _run(tmp_path / "a"), _run(tmp_path / "b", seed=1)
    for into, words in ((other.root, "is the run"), (other.root / "kept", "is inside the run")):
        with pytest.raises(ValueError, match=f"^--into {re.escape(str(into))} {words} "
                                             f"{re.escape(str(other.root))}: give a folder "
                                             "outside the runs$"):
            cli.main(["keep", str(run.root), "--into", str(into)])
    assert sorted(os.listdir(other.root)) == ["config.json", "eval.csv", "outcome.json"]
    # A project's own config.json above --into is no run.
    project = tmp_path / "project"
    project.mkdir()
    (project / "config.json").write_text('{"learning_rate": 0.001}')
    assert cli.main(["keep", str(run.root), "--into", str(project / "kept")]) == 0
    assert (project / "kept" / "a" / "config.json").is_file()


def test_sweep_refuses_status_with_sync_and_too_many_threads_before_ray(tmp_path,
                                                                        monkeypatch):
    import ray

    monkeypatch.setattr(ray, "init", lambda *args, **kwargs: pytest.fail("Ray started"))
    out = tmp_path / "sweep"
    with pytest.raises(ValueError, match="^--status shows the cells and --sync copies their "
                                         "results: give one of them$"):
        cli.main(_sweep(out, "--status", "--sync", str(tmp_path / "kept")))
    cpus = len(os.sched_getaffinity(0))
    with pytest.raises(ValueError, match=f"^--threads {cpus + 1} is more than the {cpus} CPUs "
                                         "this process may use$"):
        cli.main(_sweep(out, "--", "--threads", str(cpus + 1)))
    assert not out.exists() and not (tmp_path / "kept").exists()
    # On a cluster (--address) the threads are the cells' machines' to count: Ray is asked.
    monkeypatch.setattr(ray, "init", lambda *args, **kwargs: (_ for _ in ()).throw(
        ConnectionError("no cluster here")))
    with pytest.raises(ConnectionError, match="no cluster here"):
        cli.main(_sweep(out, "--address", "auto", "--", "--threads", str(cpus + 1)))


def test_a_sweep_whose_ray_does_not_start_leaves_no_folder(tmp_path, monkeypatch):
    """`--address auto` with no cluster running: Ray's error, and no empty --out left."""
    import ray

    def no_cluster(*args, **kwargs):
        raise ConnectionError("Could not find any running Ray instance.")

    monkeypatch.setattr(ray, "init", no_cluster)
    out = tmp_path / "sweep"
    with pytest.raises(ConnectionError, match="Could not find any running Ray instance"):
        cli.main(_sweep(out, "--address", "auto"))
    assert not out.exists()


def test_a_local_ray_that_cannot_start_is_one_line_naming_its_logs(tmp_path, monkeypatch,
                                                                  capsys):
    """Ray raises a bare Exception when its raylet cannot start (its object store did not
    fit a memory limit: "mmap failed" in raylet.err), which ended the sweep in Ray's
    traceback."""
    import ray

    def no_start(*args, **kwargs):
        raise Exception("The current node timed out during startup. This could happen "
                        "because some of the Ray processes failed to startup.\nmore")

    monkeypatch.setattr(ray, "init", no_start)
    out = tmp_path / "sweep"
    assert cli.console(_sweep(out)) == 1
    assert capsys.readouterr().err == (
        "franka-composer: error: the sweep could not start a local Ray cluster: The current "
        "node timed out during startup. This could happen because some of the Ray processes "
        "failed to startup. Ray's logs say why (/tmp/ray/session_latest/logs/raylet.err): an "
        "object store larger than the memory this process may map "
        "(RAY_DEFAULT_OBJECT_STORE_MEMORY_PROPORTION=0.05 asks for 5 % of the machine's "
        "memory), or a full /tmp or /dev/shm\n")
    assert not out.exists()


def test_a_presets_setting_that_the_options_cannot_take_names_the_preset(tmp_path):
    with pytest.raises(ValueError, match=re.escape(
            "--precision bf16 (the fast preset's; --precision fp32 with it trains in fp32) "
            "runs the networks under torch.autocast: it needs --backend sb3, not sbx")):
        cli.main(["train", "--task", "push", "--preset", "fast", "--backend", "sbx", "--out",
                  str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


def test_a_run_that_would_never_update_its_networks_is_warned_of():
    from franka_composer.cli import command_parser
    from franka_composer.cli.train import check_new_run

    args = command_parser("train").parse_args(["--task", "push", "--learning-starts", "1000",
                                               "--total-steps", "200"])
    with pytest.warns(RuntimeWarning, match=re.escape(
            "--learning-starts 1000 is not below --total-steps 200: the run takes random "
            "actions only and never updates its networks")):
        check_new_run(args)


def test_raising_the_budget_of_a_run_whose_dataset_is_gone_says_why_it_is_needed(tmp_path):
    """It said only that the dataset does not exist."""
    gone = tmp_path / "gone.npz"
    run = RunDir(tmp_path / "run")
    run.write_config(RunConfig("push", "sac", 0, hyperparameters("push", "sac").replace(
        total_steps=2000), demos=str(gone)))
    run.eval_csv.write_text(HEADER + "0,1,0.0,-1\n")
    run.checkpoint.mkdir()
    run.checkpoint_state.write_text(json.dumps({"steps": 1000, "wall_time_s": 1.0}))
    with pytest.raises(ValueError, match=re.escape(
            f"--total-steps 3000: {run.root} keeps the demonstrations of {gone} in its replay "
            "buffer, and that dataset is not there to count them (whether more steps would "
            "overwrite them): put it back, or resume without --total-steps")):
        cli.main(["train", "--resume", "--out", str(run.root), "--total-steps", "3000"])
