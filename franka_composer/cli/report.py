"""`franka-composer report`: per cell, the steps to success thresholds and what the runs cost
(beside Table II), read from the run directories without running them."""

from __future__ import annotations

import argparse
import pathlib

from franka_composer.cli.options import (add_run_dirs, output_file, report_waiting,
                                         success_percent)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "report", help="steps to success thresholds (80 %% / 90 %%) and wall / CPU hours per "
                       "cell",
        description="Read each run's eval.csv and outcome.json and print, per cell (task, "
                    "algorithm and setup), a Markdown table of the steps each seed "
                    "reached, how many stopped early, the steps at which the median over "
                    "seeds of the success curves (a trailing mean over 5 evaluations) "
                    "first reaches each threshold (80 % and 90 % unless --thresholds), and "
                    "the runs' wall-clock and CPU hours; then the total.")
    add_run_dirs(parser)
    parser.add_argument("--paper-curves", type=pathlib.Path, default=None, metavar="CSV",
                        help="the paper's published curves (results/paper-curves/curves.csv, "
                             "from experiments/paper_curves.py): its steps to each threshold "
                             "beside each cell's")
    parser.add_argument("--thresholds", type=success_percent, nargs="+", default=None,
                        metavar="PERCENT",
                        help="the success rates whose first crossing is reported, in percent "
                             "above 1 (default: 80 90; e.g. 50 80 90 for a cell that stays "
                             "below 80)")
    parser.add_argument("--wall-clock", action="store_true",
                        help="also the minutes at which the median seed's smoothed curve "
                             "first reaches each threshold (each seed's own wall-clock): "
                             "how recipes whose steps cost differently compare")
    parser.add_argument("--out", type=output_file, default=None,
                        help="also write the Markdown table here")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.learning_report import (THRESHOLDS, markdown_table,
                                                          read_paper_curves, read_run)
    from franka_composer.training.runs import check_out_apart
    from franka_composer.training.sweep import run_directories, split_evaluated

    if args.paper_curves is not None and not args.paper_curves.is_file():
        raise ValueError(f"--paper-curves: {args.paper_curves} is not a file")
    if args.out is not None and args.paper_curves is not None and (
            args.out.resolve() == args.paper_curves.resolve()):
        raise ValueError(f"--out {args.out} is the --paper-curves file: the table would "
                         "replace the curves it read; give another file")
    paper = read_paper_curves(args.paper_curves) if args.paper_curves else None
    thresholds = tuple(sorted(set(args.thresholds))) if args.thresholds else THRESHOLDS
    roots = run_directories(args.runs)
    check_out_apart(args.out, roots)
    roots, waiting = split_evaluated(roots)
    table = markdown_table([read_run(root) for root in roots], paper,
                           wall_clock=args.wall_clock, thresholds=thresholds)
    print(table, end="")
    report_waiting(waiting)
    if args.out:
        from franka_composer.atomic_files import folders_made_for, replace_atomically

        with folders_made_for(args.out):
            replace_atomically(args.out, lambda path: path.write_text(table))
    return 0
