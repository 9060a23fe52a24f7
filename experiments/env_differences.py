"""Which of the reference code's differences make this suite's pick-and-place, at the
reference timing, harder for a policy that learnt in the reference code's env. A policy
trained there (`experiments/reference_env_runs.py`) succeeds less often here
(`experiments/cross_play.py`); here it plays this suite's env with each difference the
physics page lists undone alone (`DIFFERENCES`), then all of them together, on the same
seeded episodes, its success split by the goal's height (`pick_and_place_goals.py`'s
bands). Each difference that closes part of the gap is one a learner here meets and the
paper's did not; what stays after all of them is in what cannot be undone on a built model
(the robot's XML and the arm's drive).

    python experiments/env_differences.py RUN_DIR [--only NAME ...] [--leave-one-out]
        [--episodes 200] [--seed 100]

RUN_DIR is any pick-and-place run whose policy `franka-composer evaluate` takes (its
model.zip, else its latest checkpoint, else its policy.pt). The differences, read from the
reference code's `panda_mujoco_gym/assets/pick_and_place.xml` and `panda_mocap.xml` at
e9881d9 (docs/guide/physics.md): the contacts are changed on the compiled model after the
env is made (they hold through resets: no option rebuilds it), the guard on its class for
the play of its row only. `--leave-one-out` plays, after the rows of none and all undone,
a row per difference with all the others undone instead of it alone: what the rest cannot
stand in for. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import contextlib
import pathlib
import sys

import mujoco
import numpy as np

from franka_composer.cli.options import episode_seed, positive_int
from franka_composer.tasks.options import TIMINGS
from franka_composer.tasks.records import REFERENCE_OBJECT_DAMPING
from franka_composer.training.evaluation import measure_success
from franka_composer.training.models import make_env
from franka_composer.training.policy_file import load_trained
from franka_composer.training.runs import RunDir

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import random_exploration  # noqa: E402  (experiments/, not a package)
from pick_and_place_goals import BANDS, GoalBands, band_rows  # noqa: E402

TASK = "pick_and_place"
BAND_NAMES = [name for name, _, _ in BANDS]
FINGERS = ("panda/left_finger", "panda/right_finger")
#: MuJoCo's default contact softness, the reference code's everywhere.
DEFAULT_SOLREF = (0.02, 1.0)
DEFAULT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)

#: name: what undoing it sets, as the reference code has it.
DIFFERENCES = {
    "damped_block": "the block's free joint damped 0.01 (`object_damping`)",
    "closed_fingers": "the fingers closed at reset",
    "unguarded": "the surface guard let go: the hand's target as deep as z = 0",
    "finger_contact": "the fingers' geoms friction 0.8 in all three coefficients and condim "
                      "3, the block's condim 6",
    "soft_contacts": "the block's and the floor's contacts at MuJoCo's default softness",
    "solver": "Euler integrator, pyramidal friction cone, 3 noslip iterations",
}


def contact_geoms(model: mujoco.MjModel, bodies: tuple[str, ...]) -> list[int]:
    """The colliding geoms of `bodies` (none found is an error: the model changed)."""
    geoms = [geom for geom in range(model.ngeom)
             if model.body(model.geom_bodyid[geom]).name in bodies
             and (model.geom_contype[geom] or model.geom_conaffinity[geom])]
    if not geoms:
        raise RuntimeError(f"no colliding geom on {', '.join(bodies)}")
    return geoms


def undo_on_model(model: mujoco.MjModel, undone: set[str]) -> None:
    """The differences of `undone` that live in the compiled model, undone on it (the
    block's contact with the floor is a contact pair, with parameters of its own:
    `contacts.add_surface_pair`)."""
    on_floor = model.pair("block_floor").id
    if "finger_contact" in undone:
        for geom in contact_geoms(model, FINGERS):
            model.geom_friction[geom] = 0.8
            model.geom_condim[geom] = 3
        model.geom_condim[model.geom("block/geom").id] = 6
        model.pair_dim[on_floor] = 6
    if "soft_contacts" in undone:
        for geom in (model.geom("block/geom").id, model.geom("floor").id):
            model.geom_solref[geom] = DEFAULT_SOLREF
            model.geom_solimp[geom] = DEFAULT_SOLIMP
        model.pair_solref[on_floor] = DEFAULT_SOLREF
        model.pair_solimp[on_floor] = DEFAULT_SOLIMP
    if "solver" in undone:
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
        model.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
        model.opt.noslip_iterations = 3


@contextlib.contextmanager
def guard_let_go(undone: set[str]):
    """The surface guard keeps only z >= 0 while the block runs, where `unguarded` is
    undone, as the reference code's target; put back after."""
    from franka_composer.surface_guard import BoundSurfaceGuard

    guard = BoundSurfaceGuard.guard
    if "unguarded" in undone:
        random_exploration.let_guard_go()
    try:
        yield
    finally:
        BoundSurfaceGuard.guard = guard


def undo_on_env(env, undone: set[str]) -> None:
    """The differences of `undone` that a built env holds (the fingers' width at reset and
    the compiled model), undone on it; the damping is an option of the env's, the guard
    lives on its class (`guard_let_go`)."""
    if "closed_fingers" in undone:  # The reference code's reset: width 0.
        env.unwrapped.task._initial_finger_width = 0.0
    undo_on_model(env.unwrapped.composer_env.physics.model, undone)


def make_undone(undone: set[str]) -> GoalBands:
    """This suite's pick-and-place at the reference timing, `undone` undone, its episodes
    recorded by goal band."""
    options = dict(TIMINGS["reference"])
    if "damped_block" in undone:
        options["object_damping"] = REFERENCE_OBJECT_DAMPING
    env = GoalBands(make_env(TASK, **options))
    undo_on_env(env, undone)
    return env


def play(root: pathlib.Path, undone: set[str], episodes: int, seed: int):
    """(steps trained, rows of (goal height, lifted, success)) of `root`'s policy."""
    env = make_undone(undone)
    try:
        model = load_trained(RunDir(root), env, device="cpu")
        with guard_let_go(undone):
            measure_success(model, env, episodes, seed=seed)
        return int(model.num_timesteps), np.array(env.rows, dtype=float)
    finally:
        env.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=pathlib.Path, metavar="RUN_DIR")
    parser.add_argument("--only", nargs="+", choices=tuple(DIFFERENCES), metavar="NAME",
                        help="these differences alone, and together (default: each)")
    parser.add_argument("--leave-one-out", action="store_true",
                        help="each with all the others undone, instead of alone")
    parser.add_argument("--episodes", type=positive_int, default=200)
    parser.add_argument("--seed", type=episode_seed, default=100)
    args = parser.parse_args(argv)
    try:
        config = RunDir(args.run).read_config()
    except (OSError, ValueError) as bad:
        parser.error(str(bad))
    if config.task != TASK:
        parser.error(f"{args.run} trained {config.task}; this plays {TASK}")
    names = args.only or list(DIFFERENCES)
    rows = [("none (this suite)", set())]
    if args.leave_one_out:
        if len(names) < 2:
            parser.error("--leave-one-out needs two differences or more")
        rows += [("all of them", set(names))]
        rows += [(f"all but {name}", set(names) - {name}) for name in names]
    else:
        rows += [(name, {name}) for name in names]
        if len(names) > 1:
            rows.append(("all of the above", set(names)))
    print(f"{args.run.name}, {args.episodes} deterministic episodes per row, first reset "
          f"seed {args.seed}; this suite at the reference timing with the reference code's "
          "difference undone\n")
    print("| undone | steps | success | on the floor | 0-5 cm up | 5-20 cm up "
          "| block rose > 1 cm |")
    print("|---|---|---|---|---|---|---|")
    for label, undone in rows:
        steps, played = play(args.run, undone, args.episodes, args.seed)
        bands = {band: f"{success:.1f} % of {count}"
                 for band, count, success, _ in band_rows(played)}
        lifted = 100 * played[:, 1].mean()
        print(f"| {label} | {steps:,} | {bands.pop('all')} | "
              + " | ".join(bands.get(band, "–") for band in BAND_NAMES)
              + f" | {lifted:.1f} % |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
