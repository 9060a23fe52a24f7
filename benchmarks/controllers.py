"""Env steps/s of every task under each controller, in one process, as ratios to mocap.

    python benchmarks/controllers.py [--tasks push slide ...] [--steps 2000] [--rounds 3]

Each round times every (task, controller) once through `gym.make` under seeded random
actions, resets included (`franka-composer bench`'s measurement); the best round counts, so
a burst of load on the shared machine spoils one round, not the ratio.
"""

from __future__ import annotations

from franka_composer.cli.bench import best_of_rounds, rounds_parser
from franka_composer.controllers import CONTROLS
from franka_composer.tasks import ALL_TASKS


def main(argv: list[str] | None = None) -> int:
    args = rounds_parser(__doc__, ALL_TASKS, "tasks to time (default: all)", steps=2000,
                         rounds=3, steps_per="round, task and controller").parse_args(argv)
    best = best_of_rounds(args.tasks, {c: {"control": c} for c in CONTROLS}, args.steps,
                          args.rounds)
    print("| task | " + " | ".join(f"{c} steps/s" for c in CONTROLS)
          + " | osc / mocap | joints / mocap | reset ms (mocap, osc, joints) |")
    print("|---|" + "---|" * (len(CONTROLS) + 3))
    for task in args.tasks:
        rates = [best[(task, c)]["steps_per_s"] for c in CONTROLS]
        resets = ", ".join(f"{best[(task, c)]['reset_ms']:.2f}" for c in CONTROLS)
        print(f"| {task} | " + " | ".join(f"{r:.0f}" for r in rates)
              + f" | {rates[1] / rates[0]:.2f} | {rates[2] / rates[0]:.2f} | {resets} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
