"""`franka-composer sweep`: a grid of training runs as Ray tasks, resumable, with a live
table (`franka_composer/training/sweep.py`)."""

from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import pathlib

from franka_composer.cli.options import (add_tasks_argument, folder_path, output_folder,
                                         positive_int, positive_seconds, training_seed)
from franka_composer.signals import exit_status
from franka_composer.tasks import ALL_TASKS
from franka_composer.training.hyperparams import ALGOS
from franka_composer.validation import check_writable

#: `train` options the sweep sets itself, per cell.
_SET_BY_THE_SWEEP = ("--task", "--algo", "--seed", "--out", "--total-steps", "--resume")


def add_parser(subparsers) -> None:
    from franka_composer.training.sweep import GRIDS

    parser = subparsers.add_parser(
        "sweep", help="train a grid of runs (tasks x algorithms x seeds) as Ray tasks",
        description="Train every cell of a grid (a named campaign, or --tasks x --algos x "
                    "--seeds with --steps each) as an ordinary `franka-composer train` run "
                    "in OUT/TASK-ALGO-seedN, one CPU each, as Ray tasks on a local Ray (or "
                    "the cluster at --address; OUT must then be on a file system all its "
                    "nodes share). Running the same sweep again resumes unfinished cells "
                    "from their checkpoints (with the settings they were started with: a cell "
                    "trained with settings other than the grid's is refused) and skips "
                    "finished ones; Ctrl-C checkpoints the running cells. `evaluate OUT` and "
                    "`plot OUT` read the sweep. Options "
                    "after `--` go to every cell's `train` (e.g. -- --update-schedule "
                    "episode --threads 1). Needs Ray: pip install 'franka_composer[sweep]'.")
    parser.add_argument("--out", type=folder_path, required=True,
                        help="the sweep's directory: one run directory per cell (only read "
                             "by --status and --sync)")
    parser.add_argument("--grid", choices=sorted(GRIDS),
                        help="a named grid: table2 is the paper's Table II with this suite's "
                             "budgets and the early-stopping rule, SAC in bf16, TQC on sbx "
                             "and slide's networks 256,256,256 with batch 512 "
                             "(docs/guide/training.md)")
    add_tasks_argument(parser, None, "the grid's tasks (with --algos, --seeds and --steps)")
    parser.add_argument("--algos", nargs="+", choices=ALGOS, metavar="ALGO",
                        help=f"the grid's algorithms ({', '.join(ALGOS)})")
    parser.add_argument("--seeds", nargs="+", type=training_seed, metavar="SEED",
                        help="the grid's seeds, one cell each")
    parser.add_argument("--steps", type=_budgets, metavar="N|TASK=N,...",
                        help="each cell's step budget, or one per task (push=250000,...)")
    parser.add_argument("--cells", nargs="+", metavar="PATTERN", default=None,
                        help="only the cells whose names (TASK-ALGO-seedN) match one of "
                             "these shell patterns, e.g. 'push-sac-*': a part of a grid, "
                             "to split it across machines or hold some cells back")
    parser.add_argument("--address", default=None,
                        help="an existing Ray cluster (e.g. auto, or ray://host:10001); "
                             "default: start a local Ray")
    parser.add_argument("--num-cpus", type=positive_int, default=None,
                        help="cells at once on the local Ray (default: every CPU)")
    parser.add_argument("--refresh", type=positive_seconds, default=30.0, metavar="SECONDS",
                        help="how often the table of cells is shown (default 30)")
    parser.add_argument("--status", action="store_true",
                        help="show the table of cells (what OUT holds) and exit: from a "
                             "second terminal, or to list a grid's cells and budgets")
    parser.add_argument("--sync", type=output_folder, default=None, metavar="DIR",
                        help="copy into DIR/<cell> what each cell has kept, small enough to "
                             "commit as the sweep goes on: config.json, eval.csv up to its "
                             "checkpoint (all of it before the first: a cell without one "
                             "begins again and retraces them), and once it has finished "
                             "outcome.json and policy.pt (what DIR holds is only extended by "
                             "the same run, as `keep` does); then exit")
    parser.add_argument("train_args", nargs="*", metavar="-- TRAIN_OPTION",
                        help="options passed to every cell's `train`")
    parser.set_defaults(func=run)


def _budgets(text: str):
    """N, or TASK=N,TASK=N."""
    if "=" not in text:
        return positive_int(text)
    budgets = {}
    for item in text.split(","):
        task, _, steps = item.partition("=")
        if task not in ALL_TASKS:
            raise argparse.ArgumentTypeError(f"unknown task {task!r} in --steps; valid "
                                             f"tasks: {', '.join(ALL_TASKS)}")
        if task in budgets:
            raise argparse.ArgumentTypeError(f"{task} given two budgets in --steps: give "
                                             "each task one")
        budgets[task] = positive_int(steps)
    return budgets


def cells_of(args: argparse.Namespace):
    """The grid the arguments ask for (the part of it --cells names); a clear error if
    they ask for none or two, or a pattern names no cell."""
    cells, rule = _grid_of(args)
    if args.cells is None:
        return cells, rule
    names = [cell.name for cell in cells]
    matched = {pattern: [name for name in names if fnmatch.fnmatchcase(name, pattern)]
               for pattern in args.cells}
    for pattern, matches in matched.items():
        if not matches:
            raise ValueError(f"--cells {pattern!r} matches no cell of the grid; its cells: "
                             f"{', '.join(names)}")
    wanted = set().union(*matched.values())
    return [cell for cell in cells if cell.name in wanted], rule


def _grid_of(args: argparse.Namespace):
    from franka_composer.training.sweep import GRIDS, STOPPING_RULE, grid

    explicit = [args.tasks, args.algos, args.seeds, args.steps]
    if args.grid:
        if any(value is not None for value in explicit):
            raise ValueError("--grid names a whole grid: give it alone, or --tasks, --algos, "
                             "--seeds and --steps instead")
        return GRIDS[args.grid], STOPPING_RULE
    if any(value is None for value in explicit):
        raise ValueError("a sweep needs --grid, or all of --tasks, --algos, --seeds and "
                         "--steps")
    if isinstance(args.steps, dict) and set(args.tasks) - set(args.steps):
        missing = ", ".join(sorted(set(args.tasks) - set(args.steps)))
        raise ValueError(f"--steps has no budget for {missing}")
    return grid(args.tasks, args.algos, args.seeds, args.steps), ()


def _check_trained_as(run, config, *, started: bool = True) -> None:
    """A cell resumes from its checkpoint with the settings it was started with: if the
    grid or the options after -- now describe another run, say so rather than go on with
    the old one under the new one's name. (A cell without a checkpoint starts afresh; with
    `started` False, any run there counts: what --sync would copy under the cell's name.)"""
    if not run.config_path.is_file() or (started and not (run.read_state()
                                                           or run.read_outcome())):
        return
    differences = config.differences(run.read_config())
    if differences:
        raise ValueError(f"{run.root} holds a run other than the one this sweep gives that "
                         f"cell (the sweep's setting, not the run's: "
                         f"{'; '.join(differences)}): if it is this sweep's, give the "
                         "options after -- it was run with (--status and --sync read the "
                         "cells as the sweep trains them); else move it aside, or sweep into "
                         "another --out")


def _check_sweep_folder(out, *, synced: bool) -> None:
    """--out for --status, --sync or training: a sweep's folder (its cells are runs in it),
    or, but for --sync, none yet (--status lists the grid's cells, all waiting)."""
    from franka_composer.training.runs import RunDir

    if RunDir(out).config_path.is_file():
        raise ValueError(f"--out {out} is a training run, not a sweep's folder (a sweep's "
                         "cells are runs in it)")
    if synced and not out.is_dir():
        raise ValueError(f"--out {out} does not exist: no sweep there to sync")


def _check_cell_folders(cells, out) -> None:
    """--out to train in: a sweep's folder, not a run nor inside one (its next checkpoint or
    `keep` would take the cells along), where each cell's name is free, a run, or an empty
    folder: anything else there would be taken for a cell stopped before its first
    checkpoint, and removed."""
    from franka_composer.training.runs import RunDir, check_not_inside_a_run

    _check_sweep_folder(out, synced=False)
    check_not_inside_a_run(out)
    for cell in cells:
        run = RunDir(out / cell.name)
        if run.root.exists() and not run.root.is_dir():
            raise ValueError(f"{run.root} is a file where the sweep's cell {cell.name} would "
                             "train: move it aside, or sweep into another --out")
        if run.holds_other_things():
            raise ValueError(f"{run.root} is not empty and holds no run, where the sweep's "
                             f"cell {cell.name} would train: move it aside, or sweep into "
                             "another --out")


def cell_arguments(cell, out, train_args: tuple[str, ...], *,
                   reading: bool = False) -> argparse.Namespace:
    """The `train` arguments of `cell` under `out` with `train_args`, read by train's own
    parser; an option it does not take is a ValueError saying it came after --. Options are
    taken as spelled, not abbreviated: `--tas` would otherwise be the --task the sweep sets.
    `reading`: only to read the cell's settings, --out not checked as a place to write."""
    from franka_composer.cli import command_parser
    from franka_composer.training.sweep import train_arguments

    parser = command_parser("train")
    parser.allow_abbrev = False
    if reading:
        parser._option_string_actions["--out"].type = pathlib.Path
    parser.exit_on_error = False

    def refuse(message: str):  # Not train's usage and exit: the user ran sweep.
        raise ValueError(f"the options after -- go to each cell's train, which refuses them: "
                         f"{message}")
    parser.error = refuse  # type: ignore[method-assign]  # Deliberate: a ValueError, not exit.
    try:
        args, unknown = parser.parse_known_args(train_arguments(cell, out, train_args))
    except argparse.ArgumentError as error:
        refuse(str(error))
    if unknown:
        raise ValueError(f"the options after -- go to each cell's train, which does not take "
                         f"{' '.join(unknown)} (franka-composer train --help lists its "
                         "options; give them in full)")
    return args


def cell_config(cell, out, train_args: tuple[str, ...], *, reading: bool = False):
    """The run (`RunConfig`) the sweep trains as `cell` under `out` with `train_args`
    (`reading`: as `cell_arguments`)."""
    from franka_composer.cli.train import run_config

    return run_config(cell_arguments(cell, out, train_args, reading=reading))


def check_cells(cells, out, train_args: tuple[str, ...], *, local: bool = True) -> None:
    """What `train` would refuse of any cell (`train.check_new_run`: its options, sbx, the
    device, the buffer, --demos; on a `local` sweep, more --threads than this machine has
    CPUs: a cluster's machines may have more), and a cell trained before as another run,
    found out before Ray starts. Cells that differ only in seed and directory are checked
    once (a --demos dataset is loaded once per task and algorithm, not once per seed)."""
    from franka_composer.cli.train import check_new_run, check_threads, run_config
    from franka_composer.training.runs import RunDir

    checked = set()
    for cell in cells:
        args = cell_arguments(cell, out, train_args)
        if local:
            check_threads(args.threads)
        alike = repr(sorted((name, value) for name, value in vars(args).items()
                            if name not in ("seed", "out", "func")))
        config = run_config(args) if alike in checked else check_new_run(args)
        checked.add(alike)
        _check_trained_as(RunDir(out / cell.name), config)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.runs import RunDir
    from franka_composer.training.sweep import (cell_status, run_sweep, status_table,
                                                sync_cells)

    cells, rule = cells_of(args)
    if args.status and args.sync:
        raise ValueError("--status shows the cells and --sync copies their results: give "
                         "one of them")
    for option in args.train_args:
        if option.split("=", 1)[0] in _SET_BY_THE_SWEEP:
            raise ValueError(f"{option} is set by the sweep for each cell; valid after --: "
                             "the other options of `franka-composer train`")
    train_args = (*rule, *args.train_args)
    if args.status or args.sync:
        _check_sweep_folder(args.out, synced=bool(args.sync))
        # The cells as the sweep would train them: its options after -- checked, and a cell
        # holding another run not copied under the sweep's name (these only read --out: a
        # read-only mount may be looked at).
        others = {}
        for cell in cells:
            config = cell_config(cell, args.out, train_args, reading=True)
            run = RunDir(args.out / cell.name)
            if args.sync:
                _check_trained_as(run, config, started=False)
            elif run.config_path.is_file():
                others[cell] = config.differences(run.read_config())
    if args.status:
        # A cell holding another run is that run's state, not the cell's: said so.
        print(status_table([
            dataclasses.replace(status, state=f"another run ({'; '.join(others[cell])})")
            if others.get(cell) else status
            for cell, status in ((cell, cell_status(cell, args.out)) for cell in cells)]))
        return 0
    if args.sync:
        synced = sync_cells(cells, args.out, args.sync)
        print(f"{args.sync}: {', '.join(synced) if synced else 'no cell has a run yet'}")
        return 0
    try:
        check_writable(args.out, folder=True)
    except ValueError as error:
        raise ValueError(f"--out: {error}") from None
    _check_cell_folders(cells, args.out)
    try:
        import ray  # noqa: F401
    except ImportError as error:
        raise ValueError("franka-composer sweep runs its cells on Ray: pip install "
                         "'franka_composer[sweep]' (or pip install ray)") from error
    check_cells(cells, args.out, train_args, local=args.address is None)
    try:
        statuses = run_sweep(cells, args.out, train_args, address=args.address,
                             num_cpus=args.num_cpus, refresh_s=args.refresh,
                             show=lambda table: print(table + "\n", flush=True))
    except KeyboardInterrupt as stop:  # Ctrl-C, SIGINT or SIGTERM.
        print(f"interrupted: {_what_the_stop_kept(stop)}; the same command resumes the "
              "sweep", flush=True)
        return exit_status(stop)
    failed = [s.name for s in statuses if s.state == "failed"]
    if failed:
        print(f"failed: {', '.join(failed)} (see {args.out}/<cell>.log)")
        return 1
    return 0


def _what_the_stop_kept(stop: KeyboardInterrupt) -> str:
    """What a stop left of the cells that were training (`SweepStopped`), as measured;
    nothing is claimed of a stop that cut the measuring short."""
    from franka_composer.training.sweep import SweepStopped

    if not isinstance(stop, SweepStopped):
        return "the cells' checkpoints were not checked (stopped again)"
    if not stop.running:
        return "no cell was training"
    if not stop.unsaved:
        return "each running cell saved a checkpoint"
    return "wrote no checkpoint at the stop: " + "; ".join(
        f"{name} ({where})" for name, where in stop.unsaved.items())
