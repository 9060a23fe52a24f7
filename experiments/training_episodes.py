"""What a pick-and-place learner did while it trained, read from its run's replay buffer:
per window of training steps, the share of its episodes (exploration noise and all) in
which the hand was held on the block's top, came to the block's height, lifted the block
(more than 2 cm), tipped it, and succeeded. Set side by side, runs in this suite and in the
reference code's env (`experiments/reference_env_runs.py`) show whether their learners met
the block alike on the way, which the finished policies cannot (`hand_on_top.py`).

    python experiments/training_episodes.py RUN_DIR [RUN_DIR ...] [--window 50000]

Reads each run's latest checkpoint's replay buffer (SB3's HerReplayBuffer, one env; every
transition since the start while fewer than its size were stored) with the measures of
`hand_on_top.py` applied to each stored transition. Prints a Markdown table per run.
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


def episodes(buffer) -> dict[str, np.ndarray]:
    """Per stored episode, in the order trained: its first step (0-based), and whether the
    hand was held on the block's top, came to its height, lifted it, tipped it, succeeded."""
    if buffer.n_envs != 1:
        raise SystemExit(f"a replay buffer of {buffer.n_envs} envs; this reads one")
    if buffer.full:
        raise SystemExit("the replay buffer has wrapped round: its oldest steps are gone")
    count = buffer.pos
    obs = {key: value[:count, 0] for key, value in buffer.observations.items()}
    nxt = {key: value[:count, 0] for key, value in buffer.next_observations.items()}
    offset = nxt["observation"][:, :3] - nxt["achieved_goal"]
    came_down = obs["observation"][:, 2] - nxt["observation"][:, 2]
    on_top = hand_on_top.held_on_top(offset, nxt["observation"][:, 6],
                                     np.clip(buffer.actions[:count, 0, 2], -1.0, 1.0),
                                     came_down)
    at_height = hand_on_top.at_block_height(offset)
    start = buffer.ep_start[:count, 0]
    lifted = nxt["achieved_goal"][:, 2] - obs["achieved_goal"][start, 2] > LIFTED
    tipped = hand_on_top.tipped(nxt["observation"][:, 10:12])
    success = buffer.rewards[:count, 0] == 0.0
    firsts, episode = np.unique(start, return_inverse=True)

    def any_step(flags: np.ndarray) -> np.ndarray:
        return np.bincount(episode, weights=flags.astype(float)) > 0

    return {"first_step": firsts, "held_on_top": any_step(on_top),
            "at_block_height": any_step(at_height), "lifted": any_step(lifted),
            "tipped": any_step(tipped), "succeeded": any_step(success)}


def load_buffer(run_root: pathlib.Path):
    from stable_baselines3.common.save_util import load_from_pkl

    path = run_root / "checkpoint" / "replay_buffer.pkl"
    if not path.is_file():
        raise SystemExit(f"{run_root}: no checkpoint/replay_buffer.pkl")
    return load_from_pkl(path)


def table(rows: dict[str, np.ndarray], window: int) -> list[str]:
    lines = ["| training steps | episodes | hand held on the block's top | hand at the "
             "block's height | block lifted > 2 cm | block tipped | succeeded |",
             "|---|---|---|---|---|---|---|"]
    window_of = rows["first_step"] // window
    for index in np.unique(window_of):
        mask = window_of == index
        shares = [f"{100 * rows[key][mask].mean():.1f} %" for key in
                  ("held_on_top", "at_block_height", "lifted", "tipped", "succeeded")]
        lines.append(f"| {index * window:,}–{(index + 1) * window:,} | {int(mask.sum())} | "
                     + " | ".join(shares) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=pathlib.Path, nargs="+", metavar="RUN_DIR")
    parser.add_argument("--window", type=positive_int, default=50_000,
                        help="training steps per row")
    args = parser.parse_args(argv)
    for root in args.runs:
        buffer = load_buffer(root)
        print(f"\n{root} ({buffer.pos:,} steps stored)\n")
        print("\n".join(table(episodes(buffer), args.window)), flush=True)
        del buffer
    return 0


if __name__ == "__main__":
    sys.exit(main())
