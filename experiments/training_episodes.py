"""What a learner did while it trained, read from its run's replay buffer: per window of
training steps, the share of its episodes (exploration noise and all) that reached each
stage on the way to its task's goal, which the finished policy, one greedy path, cannot show.

- pick_and_place: the hand held on the block's top, came to the block's height, lifted the
  block (more than 2 cm), tipped it; success; flung it (more than 5 cm up, above the hand:
  `edge_flick.py`). Set side by side, runs in this suite and in the reference code's env
  (`experiments/reference_env_runs.py`) show whether their learners met the block alike on
  the way (`hand_on_top.py`'s measures).
- stack: a block pushed (moved more than 2 cm across the floor), a block lifted (more than
  2 cm), block 1 within 5 cm of its goal, one block resting on the other; success; a block
  flung.
- flip: the cube tipped onto another face; success over all episodes, over those whose goal
  needs a tip (another face up than the start's) and over those whose goal needs none (the
  start's face up, turned).

    python experiments/training_episodes.py RUN_DIR [RUN_DIR ...] [--window 50000]

Reads each run's latest checkpoint's replay buffer (SB3's HerReplayBuffer, one env; every
transition since the start while fewer than its size were stored), and its config for the
task. A buffer holds the steps' ends: what happens within a step and is undone by its end
(a block flung and landed within the reference timing's 0.5 s) is not seen. Prints a
Markdown table per run; a share over some episodes only gives their count.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import positive_int

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import hand_on_top  # noqa: E402  (experiments/, not a package)

LIFTED = hand_on_top.LIFTED
#: m across the floor: a block moved this far from where its episode began was pushed.
PUSHED = 0.02
#: m: block 1 this close to its goal is there (the floor target).
AT_GOAL = 0.05
#: m: a block this far above where its episode began, and 2 cm above the tool centre point
#: (not carried between the fingers), was flung (`edge_flick.py`).
FLUNG = 0.05
#: A block rests on the other: centres this close across (m), and this far apart in height
#: (m; 4 cm, a block's size, when one rests flat on the other).
ON_OTHER_ACROSS = 0.02
ON_OTHER_HEIGHT = (0.03, 0.05)


class Steps:
    """The transitions a replay buffer stored, in the order trained: observations before
    (`obs`) and after (`nxt`), actions, each step's episode (an index into `first_step`,
    the episodes' first steps) and whether it succeeded."""

    def __init__(self, buffer) -> None:
        if buffer.n_envs != 1:
            raise SystemExit(f"a replay buffer of {buffer.n_envs} envs; this reads one")
        if buffer.full:
            raise SystemExit("the replay buffer has wrapped round: its oldest steps are gone")
        count = buffer.pos
        self.obs = {key: value[:count, 0] for key, value in buffer.observations.items()}
        self.nxt = {key: value[:count, 0] for key, value in buffer.next_observations.items()}
        self.actions = buffer.actions[:count, 0]
        self.start = buffer.ep_start[:count, 0]
        self.success = buffer.rewards[:count, 0] == 0.0
        self.first_step, self.episode = np.unique(self.start, return_inverse=True)

    def any_step(self, flags: np.ndarray) -> np.ndarray:
        """Per episode, whether `flags` (per step) held at any of its steps."""
        return np.bincount(self.episode, weights=flags.astype(float),
                           minlength=len(self.first_step)) > 0

    def at_start(self, values: np.ndarray) -> np.ndarray:
        """Per step, `values` (per step, before it) at its episode's first step."""
        return values[self.start]


def flung(steps: Steps, blocks: np.ndarray, began: np.ndarray) -> np.ndarray:
    """Per episode, whether a block (`blocks`, `began`: per step, block, x y z) flew: more
    than `FLUNG` above where it began and 2 cm above the tool centre point."""
    tcp_height = steps.nxt["observation"][:, 2:3]
    up = (blocks[..., 2] - began[..., 2] > FLUNG) & (blocks[..., 2] > tcp_height + 0.02)
    return steps.any_step(up.any(axis=1))


#: A measure: (its column's title, per episode whether it holds, the episodes its share is
#: over, or None for all).
Measure = tuple[str, np.ndarray, "np.ndarray | None"]


def pick_and_place_measures(steps: Steps) -> list[Measure]:
    obs, nxt = steps.obs, steps.nxt
    offset = nxt["observation"][:, :3] - nxt["achieved_goal"]
    came_down = obs["observation"][:, 2] - nxt["observation"][:, 2]
    on_top = hand_on_top.held_on_top(offset, nxt["observation"][:, 6],
                                     np.clip(steps.actions[:, 2], -1.0, 1.0), came_down)
    lifted = nxt["achieved_goal"][:, 2] - steps.at_start(obs["achieved_goal"][:, 2]) > LIFTED
    return [("hand held on the block's top", steps.any_step(on_top), None),
            ("hand at the block's height",
             steps.any_step(hand_on_top.at_block_height(offset)), None),
            ("block lifted > 2 cm", steps.any_step(lifted), None),
            ("block tipped", steps.any_step(hand_on_top.tipped(nxt["observation"][:, 10:12])),
             None),
            ("succeeded", steps.any_step(steps.success), None),
            ("block flung > 5 cm up", flung(steps, nxt["achieved_goal"][:, None],
                                            steps.at_start(obs["achieved_goal"])[:, None]),
             None)]


def stack_measures(steps: Steps) -> list[Measure]:
    blocks = steps.nxt["achieved_goal"].reshape(-1, 2, 3)
    began = steps.at_start(steps.obs["achieved_goal"]).reshape(-1, 2, 3)
    pushed = (np.linalg.norm(blocks[..., :2] - began[..., :2], axis=-1) > PUSHED).any(axis=1)
    lifted = (blocks[..., 2] - began[..., 2] > LIFTED).any(axis=1)
    at_goal = np.linalg.norm(blocks[:, 0] - steps.nxt["desired_goal"][:, :3], axis=-1) < AT_GOAL
    across = np.linalg.norm(blocks[:, 1, :2] - blocks[:, 0, :2], axis=-1)
    height = np.abs(blocks[:, 1, 2] - blocks[:, 0, 2])
    on_other = ((across < ON_OTHER_ACROSS) & (ON_OTHER_HEIGHT[0] < height)
                & (height < ON_OTHER_HEIGHT[1]))
    return [("a block pushed > 2 cm", steps.any_step(pushed), None),
            ("a block lifted > 2 cm", steps.any_step(lifted), None),
            ("block 1 within 5 cm of its goal", steps.any_step(at_goal), None),
            ("a block resting on the other", steps.any_step(on_other), None),
            ("succeeded", steps.any_step(steps.success), None),
            ("a block flung > 5 cm up", flung(steps, blocks, began), None)]


def face_up(quaternions: np.ndarray) -> np.ndarray:
    """Which of a cube's faces is up (0-5: +x, +y, +z, -x, -y, -z of its own frame) at each
    orientation (unit quaternions w, x, y, z): the one whose normal points highest."""
    w, x, y, z = np.moveaxis(np.asarray(quaternions), -1, 0)
    heights = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
                       axis=-1)
    return np.argmax(np.concatenate([heights, -heights], axis=-1), axis=-1)


def flip_measures(steps: Steps) -> list[Measure]:
    began = face_up(steps.at_start(steps.obs["achieved_goal"]))
    tipped = face_up(steps.nxt["achieved_goal"]) != began
    needs_tip = steps.any_step(face_up(steps.nxt["desired_goal"]) != began)
    succeeded = steps.any_step(steps.success)
    return [("cube tipped onto another face", steps.any_step(tipped), None),
            ("succeeded", succeeded, None),
            ("succeeded, goals that need a tip", succeeded, needs_tip),
            ("succeeded, goals that need none", succeeded, ~needs_tip)]


MEASURES = {"pick_and_place": pick_and_place_measures, "stack": stack_measures,
            "flip": flip_measures}


def load_buffer(run_root: pathlib.Path):
    from stable_baselines3.common.save_util import load_from_pkl

    path = run_root / "checkpoint" / "replay_buffer.pkl"
    if not path.is_file():
        raise SystemExit(f"{run_root}: no checkpoint/replay_buffer.pkl")
    return load_from_pkl(path)


def table(first_step: np.ndarray, measures: list[Measure], window: int) -> list[str]:
    lines = ["| training steps | episodes | " + " | ".join(m[0] for m in measures) + " |",
             "|---" * (len(measures) + 2) + "|"]
    window_of = first_step // window
    for index in np.unique(window_of):
        mask = window_of == index
        cells = []
        for _, holds, among in measures:
            over = mask if among is None else mask & among
            share = f"{100 * holds[over].mean():.1f} %" if over.any() else "–"
            cells.append(share if among is None else f"{share} of {int(over.sum())}")
        lines.append(f"| {index * window:,}–{(index + 1) * window:,} | {int(mask.sum())} | "
                     + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=pathlib.Path, nargs="+", metavar="RUN_DIR")
    parser.add_argument("--window", type=positive_int, default=50_000,
                        help="training steps per row")
    args = parser.parse_args(argv)
    from franka_composer.training.runs import RunDir

    for root in args.runs:
        try:
            task = RunDir(root).read_config().task
        except ValueError as error:
            raise SystemExit(str(error)) from None
        if task not in MEASURES:
            raise SystemExit(f"{root}: a {task} run; this reads {', '.join(MEASURES)}")
        buffer = load_buffer(root)
        print(f"\n{root} ({buffer.pos:,} steps stored)\n")
        steps = Steps(buffer)
        del buffer
        print("\n".join(table(steps.first_step, MEASURES[task](steps), args.window)),
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
