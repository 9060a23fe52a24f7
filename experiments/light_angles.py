"""How far the default randomisation's `light_direction` turns each light: the angle between
a light's drawn direction and its nominal one, over seeded resets of a task made with
`randomization="default"` (each offset added to the nominal direction, then normalised, as
the randomiser writes it into the compiled model). The preset's reason in
`randomization/settings.py` (and the table of docs/guide/randomization.md) quotes it.

    python experiments/light_angles.py [--task push] [--episodes 2000] [--seed 0]

Prints a Markdown table: per light, the median, 90th and 99th percentile and largest angle
in degrees.
"""

from __future__ import annotations

import argparse

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int
from franka_composer.tasks import ALL_TASKS

PERCENTILES = (50, 90, 99, 100)


def light_angles(task: str = "push", episodes: int = 2000, seed: int = 0):
    """(light names, angles in degrees, one row per reset and a column per light)."""
    import franka_composer

    plain = franka_composer.load(task)
    model = plain.physics.model
    names = [model.id2name(i, "light") for i in range(model.nlight)]
    unit = model.light_dir / np.linalg.norm(model.light_dir, axis=1, keepdims=True)
    plain.close()
    env = franka_composer.load(task, randomization="default", seed=seed)
    angles = []
    for _ in range(episodes):
        env.reset()
        drawn = env.physics.model.light_dir
        cosine = (drawn * unit).sum(axis=1) / np.linalg.norm(drawn, axis=1)
        angles.append(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
    env.close()
    return names, np.array(angles)


def table(names, angles) -> str:
    rows = ["| light | median | 90th percentile | 99th percentile | largest |",
            "|---|---|---|---|---|"]
    for name, column in zip(names, angles.T):
        rows.append(f"| {name} | " + " | ".join(
            f"{value:.1f}°" for value in np.percentile(column, PERCENTILES)) + " |")
    return "\n".join(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", choices=ALL_TASKS, default="push")
    parser.add_argument("--episodes", type=positive_int, default=2000)
    parser.add_argument("--seed", type=episode_seed, default=0)
    args = parser.parse_args(argv)
    names, angles = light_angles(args.task, args.episodes, args.seed)
    print(f"{args.task}, {args.episodes} resets (seed {args.seed}):\n")
    print(table(names, angles))


if __name__ == "__main__":
    main()
