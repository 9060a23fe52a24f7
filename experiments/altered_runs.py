"""franka-composer's `train` and `evaluate` on this suite's envs with one of its deliberate
differences from the paper's reference code undone (`ALTERATIONS`), for issue 37's checks of
what keeps TQC from lifting at the reference timing:

- `unguarded`: the surface guard let go, the hand's target as deep as the action sends it
  (down to z = 0), as in the reference code: a finger landing on the block's top edge sinks
  into it and squeezes it between the fingers, a wider catch (docs/experiments/
  grasp-margin.md, "What narrows the reach");
- `reference_physics`: every difference `env_differences.py` undoes, undone together (the
  block damped, the fingers closed at reset, the guard let go, the reference code's finger
  and block contacts, its solver): the env in which a policy trained in the reference
  code's env succeeds as often as there (docs/experiments/cross-play.md);
- `damped_block`: the block's free joint damped as the reference code's (0.01 on all six
  degrees of freedom): a turn of the 4 cm cube then dies out within milliseconds, so a push
  slides it where here it tips it over (docs/experiments/push-tip.md). The package has
  since had it as `train --object-damping 0.01`; the alteration stays for the run started
  with it (frozen tree 42d36b4, which set the damping after each reset instead: a run
  stores the same transitions bit for bit both ways, tests/test_experiments.py).

    python experiments/altered_runs.py ALTERATION train --task pick_and_place --algo tqc \
        --backend sbx --seed 0 --timing reference --out RUN_DIR [...] [--resume]
    python experiments/altered_runs.py ALTERATION evaluate RUN_DIR [...]

Every option of franka-composer's `train` and `evaluate` holds. A run made so holds its
alteration's name in config.json's `"environment"` and is labelled by it; franka-composer
refuses to resume or play it without this script, which builds all its envs (training and
evaluation alike) altered, and refuses it under another ALTERATION. Checkpoints and exact
resumes are franka-composer's.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import pathlib
import sys

import gymnasium as gym

from franka_composer import cli
from franka_composer.cli import train as train_cli
from franka_composer.tasks.records import REFERENCE_OBJECT_DAMPING
from franka_composer.training import models

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import env_differences  # noqa: E402  (experiments/, not a package)
import random_exploration  # noqa: E402


def unguarded(task: str, **options) -> gym.Env:
    random_exploration.let_guard_go()
    return models.make_env(task, **options)


def damped_block(task: str, **options) -> gym.Env:
    return models.make_env(task, **{**options, "object_damping": REFERENCE_OBJECT_DAMPING})


def reference_physics(task: str, **options) -> gym.Env:
    random_exploration.let_guard_go()
    env = models.make_env(task, **{**options, "object_damping": REFERENCE_OBJECT_DAMPING})
    env_differences.undo_on_env(env, set(env_differences.DIFFERENCES))
    return env


#: name on the command line: (the environment's name in config.json, its builder).
ALTERATIONS = {
    "unguarded": ("unguarded franka_composer", unguarded),
    "damped_block": ("franka_composer with the reference code's block damping", damped_block),
    "reference_physics": ("franka_composer with the reference code's physics",
                          reference_physics),
}


def labelled_run_config(run_config, name: str):
    """`train`'s `run_config`, naming this environment in a new run's config."""
    @functools.wraps(run_config)
    def altered_run_config(args: argparse.Namespace):
        return dataclasses.replace(run_config(args), environment=name)
    return altered_run_config


def install(alteration: str) -> None:
    """Makes this process train and play runs of `alteration`, and only those."""
    name, build = ALTERATIONS[alteration]
    models.ENVIRONMENTS[name] = build
    if not hasattr(train_cli.run_config, "__wrapped__"):
        train_cli.run_config = labelled_run_config(train_cli.run_config, name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        usage="%(prog)s ALTERATION {train,evaluate} [franka-composer's options]")
    parser.add_argument("alteration", choices=tuple(ALTERATIONS))
    parser.add_argument("command", choices=("train", "evaluate"))
    parser.add_argument("arguments", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    install(args.alteration)
    return cli.console([args.command, *args.arguments])


if __name__ == "__main__":
    sys.exit(main())
