"""How often does the surface guard take a block held in the grip for a surface beneath the
hand? Its rays start 3 cm above the fingertips' corners; with a block held low between the
fingers, the inner corners' rays start inside it and meet its underside, and the guard
holds the hand up by what it carries (docs/guide/physics.md, "What the guard does not
stop"). The palm's check already leaves held bodies out; the rays do not.

    python experiments/held_rays.py --expert stack pick_and_place [--episodes 30] [--seed 0]
    python experiments/held_rays.py RUN_DIR [RUN_DIR ...] [--episodes 20] [--seed 2024]
    ... [--exclude-held] [--held-test carried]

Counts, over the episodes played, the guard's probes (each call that casts its rays down
from a set of the hand's points), those in which a ray's counted hit was a body both
fingers touch (`meeting a held body`), those in which that hit was the nearest surface
found (`the nearest surface`: cast again past the held body, the ray finds a farther one,
or none; with `--exclude-held`, what it would have been), and the episodes with at least
one meeting a held body. `--expert` plays each task's scripted expert (`make_expert`, reset seeds
`--seed` + i); RUN_DIRs play each trained run's policy on the episodes
`franka-composer evaluate --episodes N --seed S` plays (the run's own env and timing).
`--exclude-held` plays the guard as it would be with held bodies left out of the hand's
rays (each ray that meets one cast again past it): how the outcomes would change.
`--held-test` says what counts as held: a body both fingers touch (`both-fingers`, the
guard's own test, which its palm check uses), or one both fingers touch that touches
nothing but the hand (`carried`: off the floor and off every other object, so a block
pushed or turned over on the floor, or set down on another, is not).

This wraps the guard's ray cast (`BoundSurfaceGuard._lowest_hit`) for the run of this
script only: it is an investigation of the guard, not a mode of it. The experts play the
guard that counts what the hand carries as a surface, v0's (`guard_ignores_carried=False`:
stack's v1 leaves carried blocks out, which `--held-test carried --exclude-held` plays).
"""

from __future__ import annotations

import argparse
import contextlib
import pathlib
import sys

import mujoco
import numpy as np

from franka_composer.cli.options import episode_seed, positive_int

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from played_episodes import EpisodeRecorder, play_recorded  # noqa: E402  (not a package)


class Probes:
    """What the wrapped ray cast saw, since the last `clear()`."""

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        self.probes = self.meets_held = self.decides = 0


#: What counts as held, by `--held-test`.
HELD_TESTS = ("both-fingers", "carried")


def held_hits(guard, points: np.ndarray, start_above: float,
              held_test: str = "both-fingers") -> tuple[bool, float]:
    """(whether a counted hit below `points` is a held body, by `held_test`, the lowest
    clearance with every such ray cast again past that body): the guard's own ray law
    (`_lowest_hit`), held bodies left out."""
    from franka_composer import surface_guard as sg

    held_of = guard._held_bodies if held_test == "both-fingers" else guard._carried_bodies
    model, data, geom = guard._model, guard._data, np.zeros(1, np.int32)
    held, met, lowest = None, False, np.inf
    for point in points:
        start = point.copy()
        start[2] += start_above
        distance = mujoco.mj_ray(model, data, start, sg._DOWN, sg.VISIBLE_GROUPS, 1, -1, geom)
        body = int(model.geom_bodyid[geom[0]]) if distance >= 0.0 else 0
        counted = distance >= 0.0 and distance - start_above >= -sg.BENEATH_TOLERANCE
        if counted and body:
            held = held_of() if held is None else held
            if body in held:
                met = True
                distance = mujoco.mj_ray(model, data, start, sg._DOWN, sg.VISIBLE_GROUPS, 1,
                                         body, geom)
                counted = distance >= 0.0 and distance - start_above >= -sg.BENEATH_TOLERANCE
        if counted:
            lowest = min(lowest, distance - start_above)
    return met, lowest


@contextlib.contextmanager
def watching_rays(probes: Probes, exclude_held: bool, held_test: str = "both-fingers"):
    """The guard's ray cast wrapped to count into `probes` (and, with `exclude_held`, to
    return the clearance with held bodies, by `held_test`, left out), restored on exit."""
    from franka_composer.surface_guard import BoundSurfaceGuard

    original = BoundSurfaceGuard._lowest_hit

    def counted(guard, points, start_above):
        lowest = original(guard, points, start_above)
        met, without_held = held_hits(guard, points, start_above, held_test)
        probes.probes += 1
        probes.meets_held += met
        probes.decides += met and without_held > lowest
        return without_held if exclude_held else lowest

    BoundSurfaceGuard._lowest_hit = counted
    try:
        yield probes
    finally:
        BoundSurfaceGuard._lowest_hit = original


def recorder_of(probes: Probes) -> type[EpisodeRecorder]:
    """An episode recorder keeping, per episode, (probes, meeting a held body, decided by
    it, success)."""

    class HeldRays(EpisodeRecorder):
        def begin(self, obs):
            probes.clear()

        def watch(self, obs, action):
            pass

        def row(self, info):
            return (probes.probes, probes.meets_held, probes.decides,
                    float(info["is_success"]))

    return HeldRays


def expert_rows(task: str, episodes: int, seed: int, probes: Probes) -> np.ndarray:
    """Rows of `recorder_of(probes)` for `episodes` of `task`'s scripted expert."""
    import gymnasium as gym

    import franka_composer  # noqa: F401  (registers the ids)
    from franka_composer.adapters.registration import env_id
    from franka_composer.policies import make_expert, rollout

    env = recorder_of(probes)(gym.make(env_id(task, "sparse"), guard_ignores_carried=False))
    rollout(env, make_expert(env), episodes, seed=seed)
    env.close()
    return np.array(env.rows, dtype=float)


def _task_of(run_root: pathlib.Path) -> str:
    from franka_composer.training.runs import RunDir

    try:
        return RunDir(run_root).read_config().task
    except ValueError as error:
        raise SystemExit(str(error)) from None


def table_row(name: str, rows: np.ndarray) -> str:
    count = len(rows)
    return (f"| {name} | {count} | {int(rows[:, 3].sum())}/{count} | {int(rows[:, 0].sum())} | "
            f"{int(rows[:, 1].sum())} | {int(rows[:, 2].sum())} | "
            f"{int((rows[:, 1] > 0).sum())}/{count} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=pathlib.Path, nargs="*", metavar="RUN_DIR")
    parser.add_argument("--expert", nargs="+", default=[], metavar="TASK",
                        choices=("push", "slide", "pick_and_place", "stack", "flip"))
    parser.add_argument("--episodes", type=positive_int, default=None,
                        help="episodes each (default: 30 of an expert, 20 of a run)")
    parser.add_argument("--seed", type=episode_seed, default=None,
                        help="first reset seed (default: 0 for an expert, 2024 for a run)")
    parser.add_argument("--exclude-held", action="store_true",
                        help="leave held bodies out of the hand's rays (what it would change)")
    parser.add_argument("--held-test", choices=HELD_TESTS, default="both-fingers",
                        help="what counts as held: both fingers touch it (default), or that "
                             "and it touches nothing but the hand (carried)")
    args = parser.parse_args(argv)
    if not args.runs and not args.expert:
        parser.error("name RUN_DIRs, --expert TASKs, or both")
    probes = Probes()
    held = ("a body both fingers touch" if args.held_test == "both-fingers" else
            "a body both fingers touch that touches nothing but the hand")
    print(f"The guard with held bodies ({held}) left out of the hand's rays (the nearest "
          "surface: as it would have been with them in).\n" if args.exclude_held
          else f"The guard as it is; held: {held}.\n")
    print("| played | episodes | successes | probes | meeting a held body | the nearest surface | "
          "episodes with one meeting it |")
    print("|---|---|---|---|---|---|---|")
    with watching_rays(probes, args.exclude_held, args.held_test):
        for task in args.expert:
            rows = expert_rows(task, args.episodes or 30, 0 if args.seed is None else args.seed,
                               probes)
            print(table_row(f"{task} expert", rows), flush=True)
        for root in args.runs:
            _, steps, rows = play_recorded(
                root, _task_of(root), recorder_of(probes), args.episodes or 20,
                2024 if args.seed is None else args.seed)
            print(table_row(f"{root.parent.name}/{root.name} ({steps:,} steps)", rows),
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
