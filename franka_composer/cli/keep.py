"""`franka-composer keep`: the small files of runs still training or finished, copied where
they can be committed (`training.keep`; `sweep --sync` does the same for a sweep's
cells)."""

from __future__ import annotations

import argparse

from franka_composer.cli.options import add_run_dirs, output_folder
from franka_composer.validation import repeated


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "keep", help="copy runs' config, evaluations and finished policy into a folder to commit",
        description="Copy into DIR/<run> what each run has kept, small enough to commit while "
                    "it goes on: config.json, eval.csv up to its checkpoint (the evaluations "
                    "a resume keeps; all of them before its first checkpoint, which a run "
                    "begun again from zero retraces), and once it has finished outcome.json "
                    "and policy.pt (the actor alone). Run it again as the runs go on; a run "
                    "taken on to a larger budget loses its outcome and policy in DIR until it "
                    "finishes again. What DIR holds is only extended by the same run: a copy "
                    "of another run, or evaluations the run has not reached or has "
                    "otherwise, are refused. `sweep --sync DIR` does this for a sweep's "
                    "cells.")
    add_run_dirs(parser)
    parser.add_argument("--into", type=output_folder, required=True, metavar="DIR",
                        help="the folder to copy into (made if missing)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.keep import check_kept_apart, files_to_keep, keep_run
    from franka_composer.training.runs import RunDir
    from franka_composer.training.sweep import run_directories

    runs = [root.resolve() for root in run_directories(args.runs)]  # `.` has no name.
    names = [root.name for root in runs]
    twice = repeated(names)
    if twice:
        raise ValueError(f"two runs named {', '.join(twice)}: each is kept as --into "
                         "DIR/<its name>, so one would overwrite the other")
    check_kept_apart(runs, args.into, "--into")
    copies = [RunDir(args.into / root.name) for root in runs]
    kept = [files_to_keep(RunDir(root), copy)  # Every run checked first.
            for root, copy in zip(runs, copies)]
    for files, copy in zip(kept, copies):
        keep_run(files, copy)
    print(f"{args.into}: {', '.join(names)}")
    return 0
