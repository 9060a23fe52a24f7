"""Where the block starts and where its goal lies, in this suite and in the paper's reference
code, from the same number of seeded resets: one of the hypotheses for pick-and-place
learning slower here (issue 37) is that the two draw other episodes. Reading both codes says
they draw alike; this measures it.

    python experiments/goal_sampling.py --reference-path DIR [--task pick_and_place]
        [--episodes 10000] [--seed 0]

Each suite runs in a process of its own through Gymnasium only, as
`experiments/random_exploration.py` does (DIR as there; without it the reference is left
out, saying so): reset i is `reset(seed=SEED + i)`, and the block's start and the goal are
the observation's achieved and desired goals. Prints a Markdown table per suite (ranges,
the share of goals on the floor, the start-to-goal distance, the episodes solved at reset)
and, with both suites, the two-sample Kolmogorov-Smirnov statistic of each quantity beside
its 1 % critical value: a statistic below it is no evidence that the two draw differently.
"""

from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import random_exploration  # noqa: E402  (experiments/, not a package)

SUITES = ("ours", "reference")
RESULT_PREFIX = random_exploration.RESULT_PREFIX
#: A goal this close (m) to the block's resting height is on the floor.
FLOOR = 1e-3
#: What is compared: name -> its values from (block starts, goals), each (N, 3).
QUANTITIES = {
    "block x": lambda block, goal: block[:, 0],
    "block y": lambda block, goal: block[:, 1],
    "goal x": lambda block, goal: goal[:, 0],
    "goal y": lambda block, goal: goal[:, 1],
    "goal height above the block's start": lambda block, goal: goal[:, 2] - block[:, 2],
    "start-to-goal distance": lambda block, goal: np.linalg.norm(goal - block, axis=1),
}


def draw(env, seed: int, episodes: int) -> tuple[np.ndarray, np.ndarray]:
    """(block starts, goals) of resets `seed` to `seed + episodes - 1`, each (episodes, 3)."""
    blocks, goals = [], []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        blocks.append(np.array(obs["achieved_goal"], dtype=np.float64))
        goals.append(np.array(obs["desired_goal"], dtype=np.float64))
    return np.array(blocks), np.array(goals)


def worker(suite: str, task: str, episodes: int, seed: int,
           reference_path: pathlib.Path | None) -> int:
    """Draws the resets in `suite`; one RESULT line on stdout."""
    answers, sys.stdout = sys.stdout, sys.stderr
    env = random_exploration.make_env(suite, task, reference_path)
    blocks, goals = draw(env, seed, episodes)
    env.close()
    print(RESULT_PREFIX + json.dumps({"blocks": blocks.tolist(), "goals": goals.tolist()}),
          file=answers, flush=True)
    return 0


def ks_statistic(a: np.ndarray, b: np.ndarray) -> float:
    """The two-sample Kolmogorov-Smirnov statistic: the largest gap between the samples'
    empirical distribution functions."""
    values = np.concatenate([a, b])
    gap = (np.searchsorted(np.sort(a), values, side="right") / len(a)
           - np.searchsorted(np.sort(b), values, side="right") / len(b))
    return float(np.abs(gap).max())


def ks_critical(n: int, m: int, alpha: float = 0.01) -> float:
    """The statistic two samples of sizes n and m exceed with probability `alpha` when drawn
    from one distribution (the asymptotic formula)."""
    return float(np.sqrt(-np.log(alpha / 2) / 2) * np.sqrt((n + m) / (n * m)))


def describe(blocks: np.ndarray, goals: np.ndarray) -> dict[str, str]:
    """One suite's draws in words."""
    floor = np.abs(goals[:, 2] - blocks[:, 2]) < FLOOR
    distance = np.linalg.norm(goals - blocks, axis=1)
    height = goals[~floor, 2] - blocks[~floor, 2]
    return {
        "block x, y range (m)": f"{blocks[:, 0].min():.3f}–{blocks[:, 0].max():.3f}, "
                                f"{blocks[:, 1].min():.3f}–{blocks[:, 1].max():.3f}",
        "block start height (m)": f"{blocks[:, 2].min():.4f}–{blocks[:, 2].max():.4f}",
        "goal x, y range (m)": f"{goals[:, 0].min():.3f}–{goals[:, 0].max():.3f}, "
                               f"{goals[:, 1].min():.3f}–{goals[:, 1].max():.3f}",
        "goals on the floor": f"{100 * floor.mean():.1f} %",
        "other goals' height above the block (m)": (f"{height.min():.3f}–{height.max():.3f}"
                                                    if height.size else "–"),
        "start-to-goal distance (m), 5/50/95 %": "/".join(
            f"{q:.3f}" for q in np.percentile(distance, [5, 50, 95])),
        "episodes solved at reset (< 5 cm)": f"{100 * np.mean(distance < 0.05):.1f} %",
    }


def tables(results: dict[str, dict]) -> str:
    draws = {suite: (np.array(result["blocks"]), np.array(result["goals"]))
             for suite, result in results.items()}
    titles = [random_exploration.SUITES[suite][1] for suite in draws]
    described = {suite: describe(*pair) for suite, pair in draws.items()}
    rows = list(next(iter(described.values())))
    lines = ["| | " + " | ".join(titles) + " |", "|---|" + "---|" * len(titles)]
    lines += [f"| {row} | " + " | ".join(described[suite][row] for suite in draws) + " |"
              for row in rows]
    if len(draws) == 2:
        (ours_block, ours_goal), (ref_block, ref_goal) = draws.values()
        critical = ks_critical(len(ours_block), len(ref_block))
        lines += ["", "| quantity | Kolmogorov-Smirnov statistic | 1 % critical value |",
                  "|---|---|---|"]
        for name, quantity in QUANTITIES.items():
            statistic = ks_statistic(quantity(ours_block, ours_goal),
                                     quantity(ref_block, ref_goal))
            lines.append(f"| {name} | {statistic:.4f} | {critical:.4f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = random_exploration.comparison_parser(__doc__, SUITES, episodes=10000)
    parser.add_argument("--task", choices=tuple(random_exploration.peer_worker.TASK_NAMES),
                        default="pick_and_place")
    args = parser.parse_args(argv)
    random_exploration.check_arguments(parser, args)
    if args.suite:
        return worker(args.suite, args.task, args.episodes, args.seed, args.reference_path)
    results = random_exploration.run_suites(
        __file__, SUITES, ["--task", args.task, "--episodes", str(args.episodes), "--seed",
                           str(args.seed)], args.reference_path)
    print(f"{args.task}, {args.episodes} resets, seeds {args.seed}–"
          f"{args.seed + args.episodes - 1}\n")
    print(tables(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
