"""What domain randomisation (`randomization`) costs: env steps/s and reset time, in one
process, against the same env without it, as ratios.

    python benchmarks/randomization.py [--tasks push pick_and_place] [--steps 1000] [--rounds 3]

Each round times every (task, setting) once through `gym.make` under seeded random actions,
resets included, and 20 resets (`franka-composer bench`'s measurement); the best round
counts. Settings: none; each group of the default preset alone (physics, visual, sensing
noise, a one-step observation delay, action noise); the whole preset; and one 84 x 84
camera without and with the preset.
"""

from __future__ import annotations

from franka_composer.cli.bench import best_of_rounds, rounds_parser
from franka_composer.randomization import PARAMETERS, PRESETS

DEFAULT = PRESETS["default"]


def _group(group: str, noise: bool | None = None) -> dict:
    return {name: distribution for name, distribution in DEFAULT.items()
            if PARAMETERS[name].group == group
            and (noise is None or (PARAMETERS[name].kind == "noise") == noise)}


CAMERA = dict(observation_mode="pixels", cameras=("workspace",))
SETTINGS = {
    "none": {},
    "physics": dict(randomization=_group("physics")),
    "visual": dict(randomization=_group("visual")),
    "sensing noise": dict(randomization=_group("sensing", noise=True)),
    "delay 1 step": dict(randomization={"observation_delay": 1}),
    "action noise": dict(randomization=_group("action")),
    "default preset": dict(randomization="default"),
    "1 camera": CAMERA,
    "1 camera, default preset": dict(CAMERA, randomization="default"),
}


def main(argv: list[str] | None = None) -> int:
    args = rounds_parser(__doc__, ("push", "pick_and_place"),
                         "tasks to time (default: push, pick_and_place)", steps=1000,
                         rounds=3).parse_args(argv)
    best = best_of_rounds(args.tasks, SETTINGS, args.steps, args.rounds)
    print("| task | setting | env steps/s | / none | reset ms | / none |")
    print("|---|---|---|---|---|---|")
    for task in args.tasks:
        for name in SETTINGS:
            base = best[task, "1 camera" if "camera" in name else "none"]
            result = best[task, name]
            print(f"| {task} | {name} | {result['steps_per_s']:.0f} | "
                  f"{result['steps_per_s'] / base['steps_per_s']:.2f} | "
                  f"{result['reset_ms']:.2f} | {result['reset_ms'] / base['reset_ms']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
