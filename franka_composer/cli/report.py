"""`franka-composer report`: per cell, the steps to success thresholds and what the runs cost
(issue 15's report beside Table II), read from the run directories without running them."""

from __future__ import annotations

import argparse
import pathlib

from franka_composer.cli.options import add_run_dirs


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "report", help="steps to 80 %% / 90 %% success and wall / CPU hours per cell",
        description="Read each run's eval.csv and outcome.json and print, per cell (task, "
                    "algorithm and setup), a Markdown table of the steps each seed "
                    "reached, how many stopped early, the steps at which the median over "
                    "seeds of the success curves (a trailing mean over 5 evaluations) "
                    "first reaches 80 % and 90 %, and the runs' wall-clock and CPU hours; "
                    "then the total.")
    add_run_dirs(parser)
    parser.add_argument("--out", type=pathlib.Path, default=None,
                        help="also write the Markdown table here")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.learning_report import markdown_table, read_run
    from franka_composer.training.sweep import run_directories

    table = markdown_table([read_run(root) for root in run_directories(args.runs)])
    print(table, end="")
    if args.out:
        args.out.write_text(table)
    return 0
