"""Env steps/s with camera observations (`observation_mode`), beside the state-only env, in
one process, as ratios.

    python benchmarks/pixels.py [--tasks push pick_and_place] [--steps 1000] [--rounds 2]

Each round times every (task, setting) once through `gym.make` under seeded random actions,
resets included (`franka-composer bench`'s measurement); the best round counts. Settings:
state only; 84 x 84 pixels from the workspace camera; from the workspace and wrist cameras;
from the workspace camera with the Panda's visual meshes instead of its hulls.
"""

from __future__ import annotations

import os

from franka_composer.cli.bench import best_of_rounds, rounds_parser

SETTINGS = {
    "state": {},
    "1 camera": dict(observation_mode="pixels", cameras=("workspace",)),
    "2 cameras": dict(observation_mode="pixels", cameras=("workspace", "wrist")),
    "1 camera, visual meshes": dict(observation_mode="pixels", cameras=("workspace",),
                                    camera_meshes="visual"),
}


def main(argv: list[str] | None = None) -> int:
    args = rounds_parser(__doc__, ("push", "pick_and_place"),
                         "tasks to time (default: push, pick_and_place)", steps=1000,
                         rounds=2).parse_args(argv)
    best = best_of_rounds(args.tasks, SETTINGS, args.steps, args.rounds)
    print(f"MUJOCO_GL={os.environ.get('MUJOCO_GL')}; 84 x 84 images")
    print("| task | " + " | ".join(f"{name} steps/s" for name in SETTINGS) + " |")
    print("|---|" + "---|" * len(SETTINGS))
    for task in args.tasks:
        print(f"| {task} | " + " | ".join(f"{best[task, name]['steps_per_s']:.0f}"
                                        for name in SETTINGS)
              + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
