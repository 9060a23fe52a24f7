"""One suite's env steps/s, in a process of its own, for `benchmarks/peers.py`.

    python benchmarks/peer_worker.py --suite fetch     # then "push 2000" lines on stdin

Imports only Gymnasium and the suite it measures: the paper's reference code registers the
same ids as this suite (`FrankaPushSparse-v0`, ...), and importing franka_composer would also
load dm_control and choose a GL backend in a peer's process. Each request line, `TASK STEPS`,
makes a fresh env through `gym.make` and answers one `RESULT {json}` line on stdout; every
suite is timed by `franka-composer bench`'s loop (`load_timing_loop`).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import re
import sys
import types

import gymnasium as gym

#: The suites a worker can measure: this one at its default timing and at the reference
#: code's (`timing="reference"`, 250 physics steps per env step), Fetch, the reference code.
SUITES = ("ours", "ours_reference_timing", "fetch", "reference")
#: The peers' names for the three tasks they share with this suite.
TASK_NAMES = {"push": "Push", "slide": "Slide", "pick_and_place": "PickAndPlace"}
#: Marks the worker's answers on stdout, which a library may also print to.
RESULT_PREFIX = "RESULT "


def load_timing_loop():
    """`franka_composer.cli.speed.random_steps_per_second`, loaded by its file's path: the same
    loop as `franka-composer bench`, without importing franka_composer."""
    package = importlib.util.find_spec("franka_composer")
    path = pathlib.Path(package.origin).parent / "cli" / "speed.py"
    spec = importlib.util.spec_from_file_location("franka_composer_speed", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.random_steps_per_second


def joint_types_as_ints() -> bool:
    """Make Gymnasium-Robotics' joint helpers work on mujoco >= 3.12; True if needed.

    `gymnasium_robotics.utils.mujoco_utils` (1.4.2) compares `model.jnt_type[i]`, a numpy
    integer, with `mujoco.mjtJoint` members inside tuples (`t in (mjJNT_HINGE, ...)`), which
    mujoco >= 3.12's enums answer False: every Fetch env and the reference code fail their
    first reset with an AssertionError. Their module gets a copy of `mujoco` whose joint
    types are plain ints; every function it calls is MuJoCo's own, so no step costs more.
    """
    import mujoco
    import numpy as np
    from gymnasium_robotics.utils import mujoco_utils

    slide = mujoco.mjtJoint.mjJNT_SLIDE
    if np.int32(int(slide)) in (slide,):
        return False
    patched = types.ModuleType("mujoco")
    patched.__dict__.update(vars(mujoco))
    patched.mjtJoint = types.SimpleNamespace(
        **{name: int(getattr(mujoco.mjtJoint, name))
           for name in ("mjJNT_FREE", "mjJNT_BALL", "mjJNT_SLIDE", "mjJNT_HINGE")})
    mujoco_utils.mujoco = patched
    return True


def latest_version(base: str) -> str:
    """The highest `base-vN` registered (Fetch's ids change version with its dynamics)."""
    versions = [int(match.group(1)) for name in gym.registry
                if (match := re.fullmatch(rf"{re.escape(base)}-v(\d+)", name))]
    if not versions:
        raise RuntimeError(f"no {base}-vN id registered by the installed gymnasium-robotics")
    return f"{base}-v{max(versions)}"


def reference_path_error(path: pathlib.Path | None) -> str | None:
    """Why `path` (--reference-path) is not a checkout of the reference code, or None."""
    if path is not None and not (path / "panda_mujoco_gym" / "__init__.py").is_file():
        return (f"--reference-path {path}: no panda_mujoco_gym/__init__.py there; give the "
                "folder of a checkout of the reference code's repository")
    return None


def import_reference(path: pathlib.Path) -> None:
    """Import `panda_mujoco_gym` from the checkout at `path`, and no other copy of it."""
    sys.path.insert(0, str(path))
    import panda_mujoco_gym

    origin = pathlib.Path(panda_mujoco_gym.__file__).resolve()
    if path.resolve() not in origin.parents:
        raise RuntimeError(f"panda_mujoco_gym was imported from {origin}, not from {path}")


def prepare(suite: str, reference_path: pathlib.Path | None) -> tuple[dict, dict]:
    """Import the suite; ({task: env id}, facts for the report)."""
    if suite in ("ours", "ours_reference_timing"):
        from franka_composer.adapters.registration import env_id

        return {task: env_id(task, "sparse") for task in TASK_NAMES}, {}
    import gymnasium_robotics

    facts = {"joint_types_as_ints": joint_types_as_ints()}
    if suite == "fetch":
        gym.register_envs(gymnasium_robotics)
        return {task: latest_version(f"Fetch{name}") for task, name in TASK_NAMES.items()}, facts
    if reference_path is None:
        raise RuntimeError("the reference suite needs --reference-path")
    import_reference(reference_path)
    ids = {task: f"Franka{name}Sparse-v0" for task, name in TASK_NAMES.items()}
    for name in ids.values():
        if not gym.spec(name).entry_point.startswith("panda_mujoco_gym"):
            raise RuntimeError(f"{name} is not the reference code's: {gym.spec(name).entry_point}")
    return ids, facts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--suite", choices=SUITES, required=True)
    parser.add_argument("--reference-path", type=pathlib.Path)
    args = parser.parse_args(argv)
    answers, sys.stdout = sys.stdout, sys.stderr
    ids, facts = prepare(args.suite, args.reference_path)
    options = {"timing": "reference"} if args.suite == "ours_reference_timing" else {}
    print(RESULT_PREFIX + json.dumps({"ids": ids, **facts}), file=answers, flush=True)
    random_steps_per_second = load_timing_loop()
    for line in sys.stdin:
        task, steps = line.split()
        env = gym.make(ids[task], **options)
        rate = random_steps_per_second(env, int(steps))
        env.close()
        print(RESULT_PREFIX + json.dumps({"task": task, "steps_per_s": rate}), file=answers,
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
