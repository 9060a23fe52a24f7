"""`franka-composer plot`: success-rate curves of training runs (the paper's Fig. 4)."""

from __future__ import annotations

import argparse

from franka_composer.cli.options import add_run_dirs, figure_file, report_waiting
from franka_composer.wording import counted


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "plot", help="success-rate curves of runs: one panel per task, one line per algorithm",
        description="Read each run's eval.csv and draw the median success rate over seeds "
                    "(runs of the same task, algorithm and setup), with median ± std shaded, "
                    "one panel per task and one line per algorithm and setup, as in the "
                    "paper's Fig. 4. A run that stopped early (--stop-at-success) is held "
                    "at the mean of the evaluations its stopping rule counted (train's "
                    "--stop-after: 5 in the campaigns) over the steps its cell's other seeds "
                    "go on to.")
    add_run_dirs(parser)
    parser.add_argument("--wall-clock", action="store_true",
                        help="each run's wall-clock minutes on the x axis, not environment "
                             "steps: how recipes whose steps cost differently compare")
    parser.add_argument("--out", type=figure_file, default="curves.png",
                        help="image file to write (default: curves.png here), in the format "
                             "its extension names (png, pdf, svg or another matplotlib "
                             "writes)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.curves import plot_curves
    from franka_composer.training.sweep import run_directories, split_evaluated

    roots, waiting = split_evaluated(run_directories(args.runs))
    drawn = plot_curves(roots, args.out, wall_clock=args.wall_clock)
    print(f"{counted(len(drawn), 'curve')} -> {args.out}")
    report_waiting(waiting)
    return 0
