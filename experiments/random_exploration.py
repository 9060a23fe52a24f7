"""What uniformly random actions do to the block, in this suite at either timing and in the
paper's reference code: how often the block moves and is lifted, and how many of an
episode's steps have the block 5 cm or more from where it started (the steps whose achieved
goal HER relabels into a goal that differs from the start). Before it learns to grasp, an
off-policy learner with HER trains on such episodes; a suite whose random episodes move the
block more gives it more to learn from.

    python experiments/random_exploration.py --reference-path DIR [--task pick_and_place]
        [--episodes 200] [--seed 0]

A fourth row plays this suite at the reference timing with the fingers closed at reset, as
the reference code's are (this suite's start open). DIR is a checkout of the reference code's repository (`panda_mujoco_gym`, not on PyPI;
without it the reference is left out, saying so). Each suite runs in a process of its own
(`benchmarks/peer_worker.py` imports it: the reference registers the same ids as this
suite), through Gymnasium only: the block's position is the observation's achieved goal in
both. Episode i of every suite starts from `reset(seed=SEED + i)` and plays the same 50
actions, uniform in [-1, 1]^4; an episode ends as the agent's would (success or the
50-step limit). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys

import numpy as np

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import peer_worker  # noqa: E402  (benchmarks/, not a package)

SUITES = ("ours", "ours_reference_timing", "ours_reference_timing_closed", "reference")
RESULT_PREFIX = peer_worker.RESULT_PREFIX
#: The sparse reward's success distance (m), the same in both suites.
THRESHOLD = 0.05
MOVED, LIFTED = 0.01, 0.01


def episode_actions(seed: int, episode: int, action_size: int, steps: int = 50) -> np.ndarray:
    """The actions of episode `episode`, the same in every suite."""
    return np.random.default_rng([seed, episode]).uniform(-1.0, 1.0, (steps, action_size))


def play(env, seed: int, episode: int) -> dict:
    """One random episode: how far the block got from its start, and how high."""
    obs, _ = env.reset(seed=seed + episode)
    start = obs["achieved_goal"].copy()
    away, highest, far_steps, steps = 0.0, 0.0, 0, 0
    for action in episode_actions(seed, episode, env.action_space.shape[0]):
        obs, _, terminated, truncated, _ = env.step(action.astype(env.action_space.dtype))
        offset = obs["achieved_goal"] - start
        away = max(away, float(np.linalg.norm(offset)))
        highest = max(highest, float(offset[2]))
        far_steps += bool(np.linalg.norm(offset) >= THRESHOLD)
        steps += 1
        if terminated or truncated:
            break
    return {"away": away, "highest": highest, "far_steps": far_steps, "steps": steps}


def make_env(suite: str, task: str, reference_path: pathlib.Path | None = None):
    """`task`'s sparse env in `suite` (imported here: one suite per process)."""
    import gymnasium as gym

    ids, _ = peer_worker.prepare(suite.removesuffix("_closed"), reference_path)
    options = {"timing": "reference"} if suite.startswith("ours_reference_timing") else {}
    env = gym.make(ids[task], **options)
    if suite.endswith("_closed"):  # The reference code's reset: the fingers closed.
        env.unwrapped.task._initial_finger_width = 0.0
    return env


def worker(suite: str, task: str, episodes: int, seed: int,
           reference_path: pathlib.Path | None) -> int:
    """Plays the episodes in `suite`; one RESULT line on stdout."""
    answers, sys.stdout = sys.stdout, sys.stderr
    env = make_env(suite, task, reference_path)
    rows = [play(env, seed, episode) for episode in range(episodes)]
    env.close()
    print(RESULT_PREFIX + json.dumps(rows), file=answers, flush=True)
    return 0


def summary(rows: list[dict]) -> dict:
    away = np.array([row["away"] for row in rows])
    highest = np.array([row["highest"] for row in rows])
    far = sum(row["far_steps"] for row in rows) / sum(row["steps"] for row in rows)
    return {"moved 1 cm": np.mean(away >= MOVED), "moved 5 cm": np.mean(away >= THRESHOLD),
            "lifted 1 cm": np.mean(highest >= LIFTED), "lifted 5 cm": np.mean(highest >= 0.05),
            "steps 5 cm away": far, "steps": np.mean([row["steps"] for row in rows])}


def table(results: dict[str, list[dict]]) -> str:
    titles = {"ours": "this suite", "ours_reference_timing": 'this suite, timing="reference"',
              "ours_reference_timing_closed": 'this suite, timing="reference", fingers '
                                              "closed at reset", "reference": "reference code"}
    columns = list(summary(next(iter(results.values()))))
    lines = ["| suite | episodes | " + " | ".join(
                 f"episodes: block {c}" if c[0] in "ml" else
                 ("steps with the block ≥ 5 cm from its start" if c.startswith("steps ")
                  else "mean steps") for c in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    for suite, rows in results.items():
        values = summary(rows)
        cells = [f"{values[c]:.1f}" if c == "steps" else f"{100 * values[c]:.1f} %"
                 for c in columns]
        lines.append(f"| {titles[suite]} | {len(rows)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=tuple(peer_worker.TASK_NAMES), default="pick_and_place")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference-path", type=pathlib.Path, metavar="DIR")
    parser.add_argument("--suite", choices=SUITES, help=argparse.SUPPRESS)  # A worker's.
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: give at least 1")
    if args.reference_path and not (args.reference_path / "panda_mujoco_gym" / "__init__.py").is_file():
        parser.error(f"--reference-path {args.reference_path}: no panda_mujoco_gym/__init__.py "
                     "there; give the folder of a checkout of the reference code's repository")
    if args.suite:
        return worker(args.suite, args.task, args.episodes, args.seed, args.reference_path)
    suites = SUITES if args.reference_path else SUITES[:-1]
    if not args.reference_path:
        print("reference code left out: no --reference-path given", file=sys.stderr)
    results = {}
    for suite in suites:
        command = [sys.executable, __file__, "--suite", suite, "--task", args.task,
                   "--episodes", str(args.episodes), "--seed", str(args.seed)]
        if args.reference_path:
            command += ["--reference-path", str(args.reference_path)]
        out = subprocess.run(command, stdout=subprocess.PIPE, text=True, check=True).stdout
        line = next(line for line in out.splitlines() if line.startswith(RESULT_PREFIX))
        results[suite] = json.loads(line[len(RESULT_PREFIX):])
    print(f"{args.task}, {args.episodes} episodes of uniform random actions, seed {args.seed}\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
