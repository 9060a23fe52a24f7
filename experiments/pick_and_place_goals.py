"""Which pick-and-place goals a trained policy solves, and whether it ever lifts the block:
its success split by the goal's height above the block's resting height (on the floor, as
30 % of goals are; below the 5 cm threshold, reachable by pushing; higher, reachable only
by lifting). A policy that pushes but has not learned to grasp scores on the first two only.

    python experiments/pick_and_place_goals.py RUN_DIR [RUN_DIR ...] [--episodes 200] [--seed 100]
        [--object-damping D]

Plays each run's policy through `measure_success`, the loop of `franka-composer evaluate
--episodes N --seed S`, so on its episodes (the "all" row is evaluate's success), and prints a
Markdown table: per goal band, episodes, success, and the episodes in which the block rose
more than 1 cm above its resting height at some step. `--object-damping` plays it on a block
damped so instead of as it trained (0.01: the reference code's block).
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import add_object_damping, episode_seed, positive_int
from franka_composer.tasks import TASK_CONFIGS

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from played_episodes import EpisodeRecorder, play_recorded  # noqa: E402  (not a package)

#: Goal heights above the resting height (m) that split the bands; the sparse reward's
#: threshold, 0.05 m, is where pushing alone stops reaching the goal.
BANDS = (("on the floor", 0.0, 0.0), ("0-5 cm up", 0.0, 0.05), ("5-20 cm up", 0.05, np.inf))
LIFTED = 0.01


class GoalBands(EpisodeRecorder):
    """Records, for each episode, (goal height above rest, lifted, success)."""

    def begin(self, obs):
        self._resting = obs["achieved_goal"][2]
        self._height = obs["desired_goal"][2] - self._resting
        self._lifted = False

    def watch(self, obs, action):
        self._lifted |= bool(obs["achieved_goal"][2] - self._resting > LIFTED)

    def row(self, info):
        return self._height, self._lifted, bool(info.get("is_success", False))


def episodes_of(run_root: pathlib.Path, episodes: int, seed: int,
                object_damping: float | None = None) -> tuple[int, np.ndarray]:
    """(steps trained, rows of (goal height above rest, lifted, success)) per episode, on
    the run's env, its objects damped by `object_damping` where given."""
    damping = {} if object_damping is None else {"object_damping": object_damping}
    _, steps, rows = play_recorded(run_root, "pick_and_place", GoalBands, episodes, seed,
                                   **damping)
    return steps, rows


def check_object_damping(parser: argparse.ArgumentParser, damping: float | None) -> None:
    """--object-damping checked as pick-and-place's task checks it, before any policy is
    loaded (a parser error naming it)."""
    if damping is not None:
        try:
            TASK_CONFIGS["pick_and_place"].replace(object_damping=damping)
        except ValueError as error:
            parser.error(str(error))


def band_rows(rows: np.ndarray) -> list[tuple[str, int, float, float]]:
    """(band, episodes, success %, lifted %) for each band with episodes, then all."""
    height = rows[:, 0]  # Exactly 0 for a goal on the floor (the block starts at rest).
    masks = [(name, height == 0.0 if high == 0.0 else (height > low) & (height <= high))
             for name, low, high in BANDS] + [("all", np.ones(len(rows), bool))]
    return [(name, int(mask.sum()), 100 * rows[mask, 2].mean(), 100 * rows[mask, 1].mean())
            for name, mask in masks if mask.any()]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=pathlib.Path)
    parser.add_argument("--episodes", type=positive_int, default=200)
    parser.add_argument("--seed", type=episode_seed, default=100)
    add_object_damping(parser, "as the run trained")
    args = parser.parse_args()
    check_object_damping(parser, args.object_damping)
    print("| run | steps | goal | episodes | success | block rose > 1 cm |")
    print("|---|---|---|---|---|---|")
    for root in args.runs:
        steps, rows = episodes_of(root, args.episodes, args.seed, args.object_damping)
        label = root.name + ("" if args.object_damping is None
                             else f", object_damping={args.object_damping:g}")
        for name, count, success, lifted in band_rows(rows):
            print(f"| {label} | {steps:,} | {name} | {count} | {success:.1f} % "
                  f"| {lifted:.1f} % |")


if __name__ == "__main__":
    main()
