"""Which flip goals a trained policy solves: its success split by the tips each goal needs
from the cube's start (none: the start's face up, turned about the vertical, one goal in
six; one: a side face up, four in six; two: the opposite face up, one in six), with the
episodes in which it tipped the cube at all. A policy that only turns the cube scores on
the first group alone.

    python experiments/flip_goals.py RUN_DIR [RUN_DIR ...] [--episodes 200] [--seed 100]

Plays each run's policy through `measure_success`, the loop of `franka-composer evaluate
--episodes N --seed S`, so on its episodes (the "all" row is evaluate's success), and prints
a Markdown table: per group, episodes, success, and the episodes in which the cube came to
rest on another face than its start's at some step's end.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from played_episodes import EpisodeRecorder, play_recorded  # noqa: E402  (not a package)
from training_episodes import face_up  # noqa: E402

GROUPS = ("no tip", "one tip", "two tips")


def tips_between(start_face: int, goal_face: int) -> int:
    """The fewest tips (quarter turns about a horizontal axis) that bring `goal_face` up from
    `start_face` up (`face_up`'s numbering: +x, +y, +z, -x, -y, -z)."""
    if start_face == goal_face:
        return 0
    return 2 if (start_face + 3) % 6 == goal_face else 1


class FlipGoals(EpisodeRecorder):
    """Records, for each episode, (tips its goal needs, tipped, success)."""

    def begin(self, obs):
        self._start = int(face_up(obs["achieved_goal"]))
        self._tips = tips_between(self._start, int(face_up(obs["desired_goal"])))
        self._tipped = False

    def watch(self, obs, action):
        self._tipped |= int(face_up(obs["achieved_goal"])) != self._start

    def row(self, info):
        return self._tips, self._tipped, bool(info.get("is_success", False))


def episodes_of(run_root: pathlib.Path, episodes: int, seed: int) -> tuple[int, np.ndarray]:
    """(steps trained, rows of (tips needed, tipped, success)) per episode, on the run's env."""
    _, steps, rows = play_recorded(run_root, "flip", FlipGoals, episodes, seed)
    return steps, rows


def group_rows(rows: np.ndarray) -> list[tuple[str, int, float, float]]:
    """(group, episodes, success %, tipped %) for each group with episodes, then all."""
    masks = [(name, rows[:, 0] == tips) for tips, name in enumerate(GROUPS)]
    masks.append(("all", np.ones(len(rows), bool)))
    return [(name, int(mask.sum()), 100 * rows[mask, 2].mean(), 100 * rows[mask, 1].mean())
            for name, mask in masks if mask.any()]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=pathlib.Path, metavar="RUN_DIR")
    parser.add_argument("--episodes", type=positive_int, default=200)
    parser.add_argument("--seed", type=episode_seed, default=100)
    args = parser.parse_args(argv)
    print("| run | steps | goal | episodes | success | cube tipped |")
    print("|---|---|---|---|---|---|")
    for root in args.runs:
        steps, rows = episodes_of(root, args.episodes, args.seed)
        for name, count, success, tipped in group_rows(rows):
            print(f"| {root.name} | {steps:,} | {name} | {count} | {success:.1f} % "
                  f"| {tipped:.1f} % |")


if __name__ == "__main__":
    main()
