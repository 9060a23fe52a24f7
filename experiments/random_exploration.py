"""What uniformly random actions do to the block, in this suite at either timing and in the
paper's reference code: how often the block moves and rises, and how many of an
episode's steps have the block 5 cm or more from where it started (the steps whose achieved
goal HER relabels into a goal that differs from the start). Before it learns to grasp, an
off-policy learner with HER trains on such episodes; a suite whose random episodes move the
block more gives it more to learn from.

    python experiments/random_exploration.py --reference-path DIR [--task pick_and_place]
        [--episodes 200] [--seed 0]

Further rows play this suite at 0.5 s per step with the default's stiff weld (the reference
timing before it took the reference code's weld), and at the reference timing with one
thing as the reference code has it: the fingers closed at reset, the surface guard let go
(it has none), the block's free joint damped, or every difference `env_differences.py`
undoes (`SUITES`; `--only` plays some).
DIR is a checkout of the reference code's repository (`panda_mujoco_gym`, not on PyPI;
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

#: The suites compared, by name: this suite's task options (None: the reference code), and
#: the title of its row. "stiff_weld" is the reference timing as it was before 2026-11-26
#: (0.5 s per step, velocities per 0.05 s, the default's 0.01 s weld); "closed" starts with
#: the fingers closed, as the reference code's do (this suite's start open); "no_guard" lets
#: the hand's target go as deep as the action sends it (`let_guard_go`); "damped" damps the
#: block's free joint as the reference code's (`object_damping`, `REFERENCE_OBJECT_DAMPING`:
#: not imported here, where a process may hold the reference code's ids).
SUITES = {
    "ours": ({}, "this suite"),
    "stiff_weld": ({"control_timestep": 0.5, "velocity_timestep": 0.05,
                    "weld_time_constant": 0.01},
                   "this suite, 0.5 s per step with the default's stiff weld (0.01 s)"),
    "ours_reference_timing": ({"timing": "reference"}, 'this suite, timing="reference"'),
    "closed": ({"timing": "reference"},
               'this suite, timing="reference", fingers closed at reset'),
    "no_guard": ({"timing": "reference"},
                 'this suite, timing="reference", the surface guard let go'),
    "damped": ({"timing": "reference", "object_damping": 0.01},
               'this suite, timing="reference", object_damping=0.01'),
    "reference_physics": ({"timing": "reference", "object_damping": 0.01},
                          'this suite, timing="reference", the reference code\'s physics '
                          "(env_differences.py's six differences undone)"),
    "reference": (None, "reference code"),
}
RESULT_PREFIX = peer_worker.RESULT_PREFIX
#: The sparse reward's success distance (m), the same in both suites.
THRESHOLD = 0.05
MOVED, RAISED = 0.01, 0.01


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


def let_guard_go() -> None:
    """The hand's target as deep as the action sends it, down to z = 0, in this process, as
    the reference code's (it keeps only z >= 0). Replaces the guard's method on its class,
    never the package's file."""
    from franka_composer.surface_guard import BoundSurfaceGuard

    BoundSurfaceGuard.guard = lambda self, tcp, target, stiffness: max(target[2], 0.0)


def make_env(suite: str, task: str, reference_path: pathlib.Path | None = None,
             **options):
    """`task`'s sparse env in `suite` (imported here: one suite per process), with `options`
    beside the suite's own where it is this suite."""
    import gymnasium as gym

    suite_options = SUITES[suite][0]
    ids, _ = peer_worker.prepare("reference" if suite_options is None else "ours",
                                 reference_path)
    env = gym.make(ids[task], **({} if suite_options is None
                                 else {**suite_options, **options}))
    if suite in ("closed", "reference_physics"):  # Imported here: it imports this module.
        sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
        import env_differences

        env_differences.undo_on_env(env, {"closed_fingers"} if suite == "closed"
                                    else set(env_differences.DIFFERENCES))
    if suite in ("no_guard", "reference_physics"):  # Its own process: the guard's class.
        let_guard_go()
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
            "raised 1 cm": np.mean(highest >= RAISED), "raised 5 cm": np.mean(highest >= 0.05),
            "steps 5 cm away": far, "steps": np.mean([row["steps"] for row in rows])}


def table(results: dict[str, list[dict]]) -> str:
    columns = list(summary(next(iter(results.values()))))
    lines = ["| suite | episodes | " + " | ".join(
                 f"episodes: block {c}" if c[0] in "mr" else
                 ("steps with the block ≥ 5 cm from its start" if c.startswith("steps ")
                  else "mean steps") for c in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    for suite, rows in results.items():
        values = summary(rows)
        cells = [f"{values[c]:.1f}" if c == "steps" else f"{100 * values[c]:.1f} %"
                 for c in columns]
        lines.append(f"| {SUITES[suite][1]} | {len(rows)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def comparison_parser(doc: str, suites, episodes: int) -> argparse.ArgumentParser:
    """The arguments of every comparison with the reference code: --episodes (default
    `episodes`), --seed, --reference-path, and a worker's hidden --suite (one of `suites`)."""
    parser = argparse.ArgumentParser(description=doc,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=episodes)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--reference-path", type=pathlib.Path, metavar="DIR")
    parser.add_argument("--suite", choices=tuple(suites), help=argparse.SUPPRESS)  # A worker's.
    return parser


def check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """--episodes at least 1, --reference-path a checkout of the reference code."""
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: give at least 1")
    error = peer_worker.reference_path_error(args.reference_path)
    if error:
        parser.error(error)


def run_suites(script: str, suites, arguments: list[str],
               reference_path: pathlib.Path | None) -> dict:
    """Runs `script --suite S ARGUMENTS` for each of `suites` (the reference code's only with
    `reference_path`), each in a process of its own; {suite: its RESULT}."""
    if reference_path:
        arguments = [*arguments, "--reference-path", str(reference_path)]
    else:
        print("reference code left out: no --reference-path given", file=sys.stderr)
    results = {}
    for suite in suites:
        if suite == "reference" and not reference_path:
            continue
        command = [sys.executable, script, "--suite", suite, *arguments]
        out = subprocess.run(command, stdout=subprocess.PIPE, text=True, check=True).stdout
        line = next(line for line in out.splitlines() if line.startswith(RESULT_PREFIX))
        results[suite] = json.loads(line[len(RESULT_PREFIX):])
    return results


def comparison_main(argv, doc: str, script: str, variants, play, report,
                    episodes: int = 20) -> int:
    """The command line of a comparison that plays each of `variants` in a process of its
    own (`script --suite NAME`): a worker prints `play(name, episodes, seed,
    reference_path)` as its RESULT line; the parent prints `report(results, episodes,
    seed)`, results being {name: its RESULT}."""
    parser = comparison_parser(doc, variants, episodes=episodes)
    args = parser.parse_args(argv)
    check_arguments(parser, args)
    if args.suite:
        answers, sys.stdout = sys.stdout, sys.stderr
        rows = play(args.suite, args.episodes, args.seed, args.reference_path)
        print(RESULT_PREFIX + json.dumps(rows), file=answers, flush=True)
        return 0
    results = run_suites(script, variants, ["--episodes", str(args.episodes), "--seed",
                                            str(args.seed)], args.reference_path)
    print(report(results, args.episodes, args.seed))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = comparison_parser(__doc__, SUITES, episodes=200)
    parser.add_argument("--task", choices=tuple(peer_worker.TASK_NAMES), default="pick_and_place")
    parser.add_argument("--only", nargs="+", choices=tuple(SUITES), metavar="SUITE",
                        help=f"play only these rows (of {', '.join(SUITES)})")
    args = parser.parse_args(argv)
    check_arguments(parser, args)
    if args.suite:
        return worker(args.suite, args.task, args.episodes, args.seed, args.reference_path)
    results = run_suites(__file__, args.only or SUITES, ["--task", args.task, "--episodes",
                                            str(args.episodes), "--seed", str(args.seed)],
                         args.reference_path)
    print(f"{args.task}, {args.episodes} episodes of uniform random actions, seed {args.seed}\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
