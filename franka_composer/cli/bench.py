"""`franka-composer bench`: a quick check of how fast this install runs each task.

Env steps per second through `gym.make` (its default wrappers) under seeded random actions,
resets included, and the median time of a reset, each task in this process. The full
benchmark behind docs/guide/benchmarks.md (the bare-MuJoCo baseline, scripted experts, cold start,
rendering, vector envs, memory per env) is `python benchmarks/bench.py` in a source
checkout.
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym

from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import add_tasks_argument, positive_int
from franka_composer.controllers import CONTROLS, DEFAULT_CONTROL
from franka_composer.cli.speed import WARMUP_STEPS, random_steps_per_second
from franka_composer.tasks import ALL_TASKS


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "bench", help="a quick speed check of this install: env steps/s and reset time",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, ALL_TASKS,
                       f"tasks to time (default: all of {','.join(ALL_TASKS)})")
    parser.add_argument("--control", choices=CONTROLS, default=DEFAULT_CONTROL,
                        help=f"controller to time (default: {DEFAULT_CONTROL})")
    parser.add_argument("--steps", type=positive_int, default=2000,
                        help=f"env steps timed per task, after {WARMUP_STEPS} warm-up "
                             "steps (default: 2000)")
    parser.set_defaults(func=run)


def measure(task: str, steps: int, control: str = DEFAULT_CONTROL, **options) -> dict:
    """Steps/s under random actions (resets included) and the median reset (ms), through
    `gym.make` with the task `options`."""
    env = gym.make(env_id(task, "sparse", control), **options)
    steps_per_s = random_steps_per_second(env, steps)
    resets = []
    for _ in range(20):
        start = time.perf_counter()
        env.reset()
        resets.append(time.perf_counter() - start)
    env.close()
    return {"steps_per_s": steps_per_s, "reset_ms": statistics.median(resets) * 1e3}


def best_of_rounds(tasks, settings: dict[str, dict], steps: int, rounds: int) -> dict:
    """{(task, setting name): `measure`'s result} for each task under each setting (keyword
    arguments of `measure`), the fastest of `rounds` rounds; every round measures every
    pair once, so a burst of load on a shared machine spoils one round, not a ratio."""
    best: dict[tuple[str, str], dict] = {}
    for _ in range(rounds):
        for task in tasks:
            for name, options in settings.items():
                result = measure(task, steps, **options)
                if (task, name) not in best or (
                        result["steps_per_s"] > best[task, name]["steps_per_s"]):
                    best[task, name] = result
    return best


def rounds_parser(description: str, tasks: tuple[str, ...], tasks_help: str, *,
                  steps: int, rounds: int,
                  steps_per: str = "round and setting") -> argparse.ArgumentParser:
    """The parser of a benchmark script that times settings in rounds (`best_of_rounds`):
    --tasks, --steps (env steps per `steps_per`) and --rounds, with these defaults."""
    parser = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, tasks, tasks_help)
    parser.add_argument("--steps", type=positive_int, default=steps,
                        help=f"env steps per {steps_per} (default: {steps})")
    parser.add_argument("--rounds", type=positive_int, default=rounds,
                        help=f"rounds, the best of which is reported (default: {rounds})")
    return parser


def run(args: argparse.Namespace) -> int:
    print(f"{args.control} control")
    print("| task | env steps/s (random actions, resets included) | reset ms |")
    print("|---|---|---|")
    for task in args.tasks:
        result = measure(task, args.steps, args.control)
        print(f"| {task} | {result['steps_per_s']:.0f} | {result['reset_ms']:.2f} |")
    return 0
