"""franka-composer's `train` and `evaluate` on this suite's envs with the surface guard let
go: the hand's target as deep as the action sends it, as in the paper's reference code. A
finger that lands on the block's top edge then sinks into it and squeezes it aside between
the fingers, as there, which widens the window a chance close catches the block in
(docs/experiments/grasp-margin.md, "What narrows the reach"). Issue 37's check of whether
that window is what keeps TQC from lifting at the reference timing.

    python experiments/unguarded_runs.py train --task pick_and_place --algo tqc \
        --backend sbx --seed 0 --timing reference --out RUN_DIR [...] [--resume]
    python experiments/unguarded_runs.py evaluate RUN_DIR [...]

Every option of franka-composer's `train` and `evaluate` holds. A run made so holds
`"environment": "unguarded franka_composer"` in its config.json and is labelled so;
franka-composer refuses to resume or play it without this script, which builds its envs
(training and evaluation alike) with the guard let go. Nothing else changes: checkpoints and
exact resumes are franka-composer's.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import pathlib
import sys

from franka_composer import cli
from franka_composer.cli import train as train_cli
from franka_composer.training import models

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import random_exploration  # noqa: E402  (experiments/, not a package)

#: How config.json names the environment (`RunConfig.environment`).
NAME = "unguarded franka_composer"
COMMANDS = ("train", "evaluate")


def build(task: str, **options):
    """`models.make_env` for a run in this suite's env with the guard let go
    (`models.ENVIRONMENTS`)."""
    random_exploration.let_guard_go()
    return models.make_env(task, **options)


def labelled_run_config(run_config):
    """`train`'s `run_config`, naming this environment in the run's config."""
    @functools.wraps(run_config)
    def unguarded_run_config(args: argparse.Namespace):
        return dataclasses.replace(run_config(args), environment=NAME)
    return unguarded_run_config


def install() -> None:
    """Makes this process train and play runs with the guard let go."""
    models.ENVIRONMENTS[NAME] = build
    if not hasattr(train_cli.run_config, "__wrapped__"):
        train_cli.run_config = labelled_run_config(train_cli.run_config)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        usage="%(prog)s {train,evaluate} [franka-composer's options]")
    parser.add_argument("command", choices=COMMANDS)
    parser.add_argument("arguments", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    install()
    return cli.console([args.command, *args.arguments])


if __name__ == "__main__":
    sys.exit(main())
