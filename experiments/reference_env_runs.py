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
The reference env has its own controller, timing, block and termination (on success): a run
that asks for others (--control, --timing, --control-timestep, --object-damping,
--randomization, --no-terminate-on-success, --demos, --expert-demos, --preset) is refused
before its directory is made. DIR is a checkout of the reference code's repository (not on PyPI); it
registers the same ids as this suite, so it is imported with this suite's ids kept as they
are, and its envs are made from its own specs.

Resumes there go on bit for bit, as on this suite's env, because the checkpoint also keeps
what the reference env carries from one episode into the next (`CARRIED`): its reset
(`FrankaEnv._reset_sim`) sets positions, velocities and the mocap target but leaves MuJoCo's
solver warm start (`qacc_warmstart`) as the last episode ended it, and the next episode's
first step starts from it. A resumed env, rebuilt by resets alone, held the warm start of its
first step instead. Measured on pick-and-place (tiny SAC, seed 0, 200 steps resumed to 400
against 400 uninterrupted): without the warm start kept, the runs stored the same transitions
up to the first step after the resume, whose next observation differed by up to 2.6e-4;
with it, all 400 transitions and the evaluations are equal bit for bit.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import pathlib
import pickle
import sys
import warnings

import gymnasium as gym

from franka_composer import cli
from franka_composer.cli import train as train_cli
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.training import exact_resume, models
from franka_composer.training.run_files import unpickling

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import peer_worker  # noqa: E402  (benchmarks/, not a package)

#: How config.json names the reference code's environment (`RunConfig.environment`).
NAME = "panda_mujoco_gym"
COMMANDS = ("train", "evaluate")
#: The fields of the reference env's MjData that its reset leaves as they were, which a
#: checkpoint keeps beside the generators (`exact_resume`) under NAME.
CARRIED = ("qacc_warmstart",)


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
                randomization: str | None, timing: dict, object_damping: float = 0.0,
                demos: bool = False, preset: str | None = None) -> list[str]:
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
        (object_damping != 0, f"--object-damping {object_damping:g}"),
        (not terminate_on_success, "--no-terminate-on-success"),
        (demos, "--demos or --expert-demos"),
        (preset is not None, f"--preset {preset}")) if asked]


def refusal(options: list[str]) -> ValueError:
    return ValueError(f"the reference code's env has its own controller, timing, block and "
                      f"termination and no demonstrations: {', '.join(options)} cannot be "
                      "given with it")


def build(specs: dict, task: str, *, terminate_on_success: bool, control: str,
          randomization: str | None, control_timestep, velocity_timestep, weld_time_constant,
          object_damping: float = 0.0, **render_options) -> gym.Env:
    """`models.make_env` for a run in the reference env (`models.ENVIRONMENTS`)."""
    options = unsupported(specs, task, terminate_on_success=terminate_on_success,
                          control=control, randomization=randomization,
                          timing=dict(control_timestep=control_timestep,
                                      velocity_timestep=velocity_timestep,
                                      weld_time_constant=weld_time_constant),
                          object_damping=object_damping)
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
            timing=config.timing_options, object_damping=config.object_damping,
            demos=config.demos is not None or config.expert_demos is not None,
            preset=config.preset)
        if options:
            raise refusal(options)
        return config
    return reference_run_config


def training_physics(model):
    """The MjData of `model`'s training env (the reference env's own, `FrankaEnv.data`)."""
    return model.get_env().envs[0].unwrapped.data


def saving_carried_state(save):
    """`exact_resume.save`, keeping the training env's `CARRIED` fields too."""
    @functools.wraps(save)
    def save_with_carried_state(model, stream, path: pathlib.Path) -> None:
        save(model, stream, path)
        state = pickle.loads(path.read_bytes())
        data = training_physics(model)
        state[NAME] = {name: getattr(data, name).copy() for name in CARRIED}
        path.write_bytes(pickle.dumps(state))
    return save_with_carried_state


def restoring_carried_state(restore):
    """`exact_resume.restore`, giving the rebuilt training env its kept `CARRIED` fields
    (after the resets that rebuild it); a checkpoint without them resumes as before."""
    @functools.wraps(restore)
    def restore_with_carried_state(model, path: pathlib.Path):
        stream = restore(model, path)
        if stream is not None:
            with unpickling(path):
                carried = pickle.loads(path.read_bytes()).get(NAME, {})
            data = training_physics(model)
            for name, value in carried.items():
                getattr(data, name)[:] = value
        return stream
    return restore_with_carried_state


def install(specs: dict) -> None:
    """Makes this process train and play runs in the reference env `specs` describes, and
    resume them exactly."""
    models.ENVIRONMENTS[NAME] = functools.partial(build, specs)
    if not hasattr(train_cli.run_config, "__wrapped__"):
        train_cli.run_config = checked_run_config(specs, train_cli.run_config)
    if not hasattr(exact_resume.save, "__wrapped__"):
        exact_resume.save = saving_carried_state(exact_resume.save)
        exact_resume.restore = restoring_carried_state(exact_resume.restore)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
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
