"""How much of a full command does `joints` cover in a step, held over several steps? The
controllers page's first-step figure (83-100 % of 0.05 rad per joint) is measured from the
neutral pose at rest (`tests/test_controllers.py`); a joint already moving carries on past
its target, which the servo sets 0.05 rad from where the joint is, not from the last target.

On push (no contact), from the neutral pose after a reset: five steps of a full command,
one joint at a time (+1, then -1), and all seven together (+1, then -1). Prints each step's
move of each commanded joint as a share of 0.05 rad (%): the first step, and the least and
most of steps 2-5.

    python experiments/joint_tracking.py [--timing default|reference] [--steps 5]
"""

from __future__ import annotations

import argparse

import numpy as np

from franka_composer.cli.options import positive_int

MAX_JOINT_STEP = 0.05  # rad: a full action's target offset (ControlSettings.max_joint_step).


def shares(env, commanded: list[int], sign: int, steps: int) -> np.ndarray:
    """Each step's move of each joint in `commanded` (%), shape (steps, len(commanded))."""
    angles = [env.reset().observation["panda/joints_pos"].copy()]
    action = np.zeros(7, np.float32)
    action[commanded] = sign
    for _ in range(steps):
        angles.append(env.step(action).observation["panda/joints_pos"].copy())
    moves = np.diff(np.array(angles), axis=0)[:, commanded]
    return 100 * sign * moves / MAX_JOINT_STEP


def main(argv: list[str] | None = None) -> int:
    import franka_composer
    from franka_composer.tasks.options import TIMINGS

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--timing", default="default", choices=tuple(TIMINGS))
    parser.add_argument("--steps", type=positive_int, default=5)
    args = parser.parse_args(argv)
    if args.steps < 2:
        parser.error("--steps must be at least 2 (the first step, then the ones after it)")
    env = franka_composer.load("push", seed=0, control="joints", terminate_on_success=False,
                               time_limit=None, timing=args.timing)
    print(f"| command | sign | first step (%) | steps 2-{args.steps}: least-most (%) |")
    print("|---|---|---|---|")
    for label, commanded in [*((f"joint {j + 1}", [j]) for j in range(7)),
                             ("all seven", list(range(7)))]:
        for sign in (1, -1):
            covered = shares(env, commanded, sign, args.steps)
            first = ", ".join(f"{value:.0f}" for value in covered[0])
            later = covered[1:]
            print(f"| {label} | {sign:+d} | {first} | {later.min():.0f}-{later.max():.0f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
