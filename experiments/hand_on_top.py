"""How often a trained pick-and-place policy's open hand is held on the block's top: the
surface guard stops a finger that comes down on the block's top edge there, where the
reference code's finger sinks in and squeezes the block between the fingers, a grasp
(docs/experiments/grasp-margin.md, "What narrows the reach"). If trained policies' hands
often end up there, the guard's narrower catch costs them grasps; if rarely, it is not
what they ran into.

    python experiments/hand_on_top.py RUN_DIR [RUN_DIR ...] [--episodes 200] [--seed 100]

Plays each run's policy through `measure_success`, the loop of `franka-composer evaluate
--episodes N --seed S` (the run's own env and timing), and counts, per episode, the steps
that end with the hand held on the block's top (`held_on_top`: commanded down, it came down
less than 2 mm, its fingers open wider than the block, the tool centre point 24-30 mm
above the block's centre (a finger's tip on its top), within 60 mm of it along the closing
axis and 20 mm across), the steps that end with the hand at the block's height within that
reach of it (`at_block_height`), whether the block rose more than 2 cm (a lift: tipped, it
rises up to 14.6 mm), and whether it tipped (`tipped`). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from played_episodes import EpisodeRecorder, play_recorded  # noqa: E402  (not a package)

#: The tool centre point's height above the block's centre (m) with a finger's tip on its
#: top: half the block (0.02) plus the tip's depth below the point (7.3 mm), give or take.
ON_TOP = (0.024, 0.030)
HALF_BLOCK = 0.02  # m.
ACROSS = 0.020  # m off the block's centre along x, at most.
REACH = 0.060  # m off it along y (the closing axis), at most: a finger still over it.
DOWN = -0.5  # The action's z at or below which the policy commands the hand down.
STILL = 0.002  # m: a hand commanded down that came down less was stopped.
#: m above the block's resting height: a lift. A 4 cm cube tipped onto an edge rises 8.3 mm,
#: onto a corner 14.6 mm, without leaving the floor.
LIFTED = 0.02
#: rad: a block turned this far about x or y (its Euler angles, observation[10:12]) tipped.
TIPPED = 0.3



def held_on_top(offset, width, action_z, came_down):
    """Whether a step ended with the hand, its fingers open wider than the block, stopped
    with a finger's tip on the block's top although commanded down; `offset`: the tool
    centre point minus the block's centre (m, last axis x y z), `came_down`: how far it came
    down (m). Elementwise over arrays of steps."""
    offset = np.asarray(offset)
    return ((np.asarray(action_z) <= DOWN) & (np.asarray(came_down) < STILL)
            & (np.asarray(width) > 2 * HALF_BLOCK)
            & (ON_TOP[0] <= offset[..., 2]) & (offset[..., 2] <= ON_TOP[1])
            & (np.abs(offset[..., 0]) <= ACROSS) & (np.abs(offset[..., 1]) <= REACH))


def tipped(euler):
    """Whether the block's orientation (x-y-z Euler angles, rad) is tipped from upright.
    Elementwise over arrays of steps."""
    euler = np.asarray(euler)
    return (np.abs(euler[..., 0]) > TIPPED) | (np.abs(euler[..., 1]) > TIPPED)


def at_block_height(offset):
    """Whether a step ended with the tool centre point at the block's height and a finger's
    reach of it (where the fingers, open or closed, are on its sides or on it).
    Elementwise over arrays of steps."""
    offset = np.asarray(offset)
    return ((np.abs(offset[..., 2]) <= 0.012) & (np.abs(offset[..., 0]) <= ACROSS)
            & (np.abs(offset[..., 1]) <= REACH))


class HandOnTop(EpisodeRecorder):
    """Records, for each episode, (steps held on top, steps at the block's height, lifted,
    tipped)."""

    def begin(self, obs):
        self._resting = obs["achieved_goal"][2]
        self._on_top = self._down = 0
        self._lifted = self._tipped = False
        self._tcp_z = obs["observation"][2]

    def watch(self, obs, action):
        offset = obs["observation"][:3] - obs["achieved_goal"]
        width = float(obs["observation"][6])
        came_down, self._tcp_z = self._tcp_z - obs["observation"][2], obs["observation"][2]
        self._on_top += bool(held_on_top(offset, width, np.clip(action[2], -1.0, 1.0),
                                         came_down))
        self._down += bool(at_block_height(offset))
        self._lifted |= bool(obs["achieved_goal"][2] - self._resting > LIFTED)
        self._tipped |= bool(tipped(obs["observation"][10:12]))

    def row(self, info):
        return self._on_top, self._down, self._lifted, self._tipped


def episodes_of(run_root: pathlib.Path, episodes: int, seed: int) -> tuple[dict, np.ndarray]:
    """(facts of the run, rows of (steps held on top, steps at the block's height, lifted,
    tipped)) per episode."""
    config, steps, rows = play_recorded(run_root, "pick_and_place", HandOnTop, episodes, seed)
    return {"steps": steps, "timing": config.timing_label or "default"}, rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=pathlib.Path, nargs="+", metavar="RUN_DIR")
    parser.add_argument("--episodes", type=positive_int, default=200)
    parser.add_argument("--seed", type=episode_seed, default=100)
    args = parser.parse_args()
    print(f"{args.episodes} deterministic episodes per policy, first reset seed {args.seed}\n")
    print("| run | timing | steps trained | episodes with the hand held on the block's "
          "top | steps held there (all episodes) | episodes with the hand at the block's "
          "height | episodes lifting it > 2 cm | episodes tipping it |")
    print("|---|---|---|---|---|---|---|---|")
    for root in args.runs:
        facts, rows = episodes_of(root, args.episodes, args.seed)
        count = len(rows)
        print(f"| {root.parent.name}/{root.name} | {facts['timing']} | {facts['steps']:,} | "
              f"{int((rows[:, 0] > 0).sum())}/{count} | {int(rows[:, 0].sum())} | "
              f"{int((rows[:, 1] > 0).sum())}/{count} | {int(rows[:, 2].sum())}/{count} | "
              f"{int(rows[:, 3].sum())}/{count} |",
              flush=True)


if __name__ == "__main__":
    main()
