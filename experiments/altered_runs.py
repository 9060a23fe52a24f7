"""franka-composer's `train` and `evaluate` on this suite's envs with one of its deliberate
differences from the paper's reference code undone (`ALTERATIONS`), for issue 37's checks of
what keeps TQC from lifting at the reference timing:

- `unguarded`: the surface guard let go, the hand's target as deep as the action sends it
  (down to z = 0), as in the reference code: a finger landing on the block's top edge sinks
  into it and squeezes it between the fingers, a wider catch (docs/experiments/
  grasp-margin.md, "What narrows the reach");
- `damped_block`: the block's free joint damped as the reference code's (0.01 on all six
  degrees of freedom): a turn of the 4 cm cube then dies out within milliseconds, so a push
  slides it where here it tips it over (docs/experiments/push-tip.md).

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
from franka_composer.tasks.config import REFERENCE_OBJECT_DAMPING
from franka_composer.training import models

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import random_exploration  # noqa: E402  (experiments/, not a package)

#: The reference code's block's free-joint damping (the task option `object_damping` sets
#: it in the package; set here at run time, as the damped-block cell was started).
BLOCK_DAMPING = REFERENCE_OBJECT_DAMPING


def damp_block(env) -> None:
    """Damps the free joint of `env`'s object (this suite's env, its physics compiled) as
    the reference code's block's."""
    physics = env.unwrapped.composer_env.physics
    model = physics.model
    geom = int(physics.bind(env.unwrapped.task.prop.mjcf_model.find_all("geom")).element_id[0])
    joint = model.body_jntadr[model.geom_bodyid[geom]]  # The free joint Composer attached.
    if model.jnt_type[joint] != 0:  # mjJNT_FREE
        raise ValueError("the object's body does not hang from a free joint")
    start = model.jnt_dofadr[joint]
    model.dof_damping[start:start + 6] = BLOCK_DAMPING


class DampedBlock(gym.Wrapper):
    """Damps the object's free joint as soon as a reset has built the physics (damping
    changes no position, so the first state is the same either way)."""

    def reset(self, **kwargs):
        result = self.env.reset(**kwargs)
        damp_block(self.env)
        return result


def unguarded(task: str, **options) -> gym.Env:
    random_exploration.let_guard_go()
    return models.make_env(task, **options)


def damped_block(task: str, **options) -> gym.Env:
    return DampedBlock(models.make_env(task, **options))


#: name on the command line: (the environment's name in config.json, its builder).
ALTERATIONS = {
    "unguarded": ("unguarded franka_composer", unguarded),
    "damped_block": ("franka_composer with the reference code's block damping", damped_block),
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
        description=__doc__.splitlines()[0],
        usage="%(prog)s ALTERATION {train,evaluate} [franka-composer's options]")
    parser.add_argument("alteration", choices=tuple(ALTERATIONS))
    parser.add_argument("command", choices=("train", "evaluate"))
    parser.add_argument("arguments", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    install(args.alteration)
    return cli.console([args.command, *args.arguments])


if __name__ == "__main__":
    sys.exit(main())
