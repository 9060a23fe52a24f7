"""franka-composer's `train` and `evaluate` on the paper's reference code's own environment
(`panda_mujoco_gym`'s `Franka{Push,Slide,PickAndPlace}Sparse-v0`): Table I's training, its
evaluations, checkpoints and exact resumes, on the env the paper's Table II came from. Set
beside the same runs on this suite, it tells this suite's pick-and-place apart from the
algorithm, its settings and the training loop (issue 37).

    python experiments/reference_env_runs.py --reference-path DIR train --task pick_and_place \
        --algo tqc --backend sbx --seed 0 --out RUN_DIR [--total-steps 500000] [--resume]
    python experiments/reference_env_runs.py --reference-path DIR evaluate RUN_DIR [...]

A run made so holds `"environment": "panda_mujoco_gym"` in its config.json and is labelled
"panda_mujoco_gym's env"; franka-composer refuses to resume or play it without this script.
The reference env has its own controller, timing and termination (on success): a run that
asks for others (--control, --timing, --control-timestep, --randomization,
--no-terminate-on-success, --demos, --expert-demos, --preset) is refused before its
directory is made. DIR is a checkout of the reference code's repository (not on PyPI); it
registers the same ids as this suite, so it is imported with this suite's ids kept as they
are, and its envs are made from its own specs.

Resumes there go on with the same episodes and generators but not bit for bit: a run of 200
steps resumed to 400 stored the uninterrupted run's transitions up to its first step after
the resume, whose next observation then differed by 1.7e-6 (tiny SAC, seed 0; with or
without evaluations between), where the same check on this suite's env is bit-exact. A
rebuilt reference env, reset as the resume resets it, replays that step exactly outside
training, so what differs is not its reset; the cause is not found. State such runs'
resumes with their results.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import pathlib
import sys
import warnings

import gymnasium as gym

from franka_composer import cli
from franka_composer.cli import train as train_cli
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.training import models

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import peer_worker  # noqa: E402  (benchmarks/, not a package)

#: How config.json names the reference code's environment (`RunConfig.environment`).
NAME = "panda_mujoco_gym"
COMMANDS = ("train", "evaluate")


def reference_specs(path: pathlib.Path) -> dict[str, gym.envs.registration.EnvSpec]:
    """{task: the reference code's sparse env spec}, imported from the checkout at `path`;
    the ids it registers over this suite's are given back to this suite."""
    ours = dict(gym.registry)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Gymnasium's "Overriding environment" notices.
        ids, _ = peer_worker.prepare("reference", path)
    specs = {task: gym.spec(env_id) for task, env_id in ids.items()}
    for env_id, spec in list(gym.registry.items()):
        if isinstance(spec.entry_point, str) and spec.entry_point.startswith(NAME):
            if env_id in ours:
                gym.registry[env_id] = ours[env_id]
            else:
                del gym.registry[env_id]
    return specs


def unsupported(specs: dict, task: str, *, terminate_on_success: bool, control: str,
                randomization: str | None, timing: dict, demos: bool = False,
                preset: str | None = None) -> list[str]:
    """What of a run's settings the reference env does not have, as the options that ask
    for it; [] when it can be trained there."""
    default = TASK_CONFIGS[task]
    default_timing = {"control_timestep": default.control_timestep, "velocity_timestep": None,
                      "weld_time_constant": default.control.weld_time_constant}
    given = {name: value for name, value in timing.items() if value is not None}
    return [option for asked, option in (
        (task not in specs, f"--task {task} (the reference code has {', '.join(specs)})"),
        (control != "mocap", f"--control {control}"),
        (any(value != default_timing[name] for name, value in given.items()),
         "--timing or --control-timestep"),
        (randomization is not None, f"--randomization {randomization}"),
        (not terminate_on_success, "--no-terminate-on-success"),
        (demos, "--demos or --expert-demos"),
        (preset is not None, f"--preset {preset}")) if asked]


def refusal(options: list[str]) -> ValueError:
    return ValueError(f"the reference code's env has its own controller, timing and "
                      f"termination and no demonstrations: {', '.join(options)} cannot be "
                      "given with it")


def build(specs: dict, task: str, *, terminate_on_success: bool, control: str,
          randomization: str | None, control_timestep, velocity_timestep, weld_time_constant,
          **render_options) -> gym.Env:
    """`models.make_env` for a run in the reference env (`models.ENVIRONMENTS`)."""
    options = unsupported(specs, task, terminate_on_success=terminate_on_success,
                          control=control, randomization=randomization,
                          timing=dict(control_timestep=control_timestep,
                                      velocity_timestep=velocity_timestep,
                                      weld_time_constant=weld_time_constant))
    if options:
        raise refusal(options)
    return gym.make(specs[task], **render_options)


def checked_run_config(specs: dict, run_config):
    """`train`'s `run_config`, in the reference env, refused before a directory is made
    where the env cannot train it."""
    @functools.wraps(run_config)
    def reference_run_config(args: argparse.Namespace):
        config = dataclasses.replace(run_config(args), environment=NAME)
        options = unsupported(
            specs, config.task, terminate_on_success=config.terminate_on_success,
            control=config.control, randomization=config.randomization,
            timing=config.timing_options,
            demos=config.demos is not None or config.expert_demos is not None,
            preset=config.preset)
        if options:
            raise refusal(options)
        return config
    return reference_run_config


def install(specs: dict) -> None:
    """Makes this process train and play runs in the reference env `specs` describes."""
    models.ENVIRONMENTS[NAME] = functools.partial(build, specs)
    if not hasattr(train_cli.run_config, "__wrapped__"):
        train_cli.run_config = checked_run_config(specs, train_cli.run_config)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        usage="%(prog)s --reference-path DIR {train,evaluate} [franka-composer's options]")
    parser.add_argument("--reference-path", type=pathlib.Path, required=True, metavar="DIR")
    parser.add_argument("command", choices=COMMANDS)
    parser.add_argument("arguments", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    error = peer_worker.reference_path_error(args.reference_path)
    if error:
        parser.error(error)
    install(reference_specs(args.reference_path))
    return cli.console([args.command, *args.arguments])


if __name__ == "__main__":
    sys.exit(main())
