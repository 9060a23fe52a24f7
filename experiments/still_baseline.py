"""The success rate a policy that does nothing gets on a run's evaluations: the floor a
learning curve must rise above.

    python experiments/still_baseline.py --task push [--control osc] [--seed 0] [--evaluations 50]
    python experiments/still_baseline.py --run RUN_DIR [RUN_DIR ...] [--plot IMAGE]
        [--final-test EPISODES SEED ...]   # e.g. --final-test 20 2024 --final-test 200 100

`train` evaluates 15 episodes every 2000 steps on an env seeded from the run's seed, and
which episodes an evaluation sees does not depend on the policy (goals and objects are
drawn at reset), so an untrained policy scores exactly the episodes that start solved and
stay so (push: the block already within 5 cm of the goal). This replays those evaluations
with a zero action, in the order `train` runs them from its start (a resumed run goes on
with the episodes an uninterrupted one would see; on trees before commit 6cabf21 its eval
env started its stream again: compare such a run's evaluations after a resume with this
list from its beginning, computed with that tree on PYTHONPATH). The same seed draws the
same episodes with domain randomisation (`randomization`) as without, so this is also the
floor of a randomised run. Prints one JSON list, a rate per evaluation; with `--run`, the
floor of that run's own evaluations (its task, env options, seed and cadence) beside them,
per 5e4 steps: whether a curve has left its floor, evaluation by evaluation (with a sign
test's p: how likely as many evaluations above it were, were the run no better); `--plot`
draws each run's evaluations and both trailing means over 5e4 steps; `--final-test`
gives the still policy's success on `franka-composer evaluate`'s episodes, the floor of a
final test.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int
from franka_composer.controllers import CONTROLS
from franka_composer.tasks import ALL_TASKS


class StillPolicy:
    """SB3's `predict` interface, always the zero action."""

    def __init__(self, action_size: int) -> None:
        self._size = action_size

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        goals = np.asarray(observation["desired_goal"])
        shape = (self._size,) if goals.ndim == 1 else (len(goals), self._size)  # One env or a
        return np.zeros(shape, np.float32), None                               # vector of them.


def still_rates(task: str, control: str = "mocap", seed: int = 0, evaluations: int = 50,
                episodes: int = 15, **env_options) -> list[float]:
    """`evaluations` rates of `episodes` each; `env_options` as `make_env` takes them."""
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import DummyVecEnv

    from franka_composer.training.loop import EVAL_SEED_OFFSET
    from franka_composer.training.models import make_env

    env = DummyVecEnv([lambda: make_env(task, control=control, **env_options)])
    env.seed(seed + EVAL_SEED_OFFSET)  # As `train` seeds its evaluation env.
    policy = StillPolicy(env.action_space.shape[0])
    rates = []
    for _ in range(evaluations):
        successes = []

        def record(local, _globals, successes=successes):
            if local["done"]:
                successes.append(bool(local["info"].get("is_success", False)))

        evaluate_policy(policy, env, n_eval_episodes=episodes, deterministic=True,
                        callback=record, warn=False)
        rates.append(float(np.mean(successes)))
    env.close()
    return rates


def still_on_final_test(config, episodes: int, seed: int) -> float:
    """The still policy's success on the episodes `franka-composer evaluate RUN_DIR
    --episodes N --seed S` plays (the task and env options of the run's `config`): its final
    test's floor."""
    from franka_composer.training.evaluation import measure_success
    from franka_composer.training.models import make_env

    env = make_env(config.task, **config.env_options)
    try:
        policy = StillPolicy(env.action_space.shape[0])
        return measure_success(policy, env, episodes, seed=seed).success_rate
    finally:
        env.close()


def run_and_floor(run_dir: pathlib.Path):
    """(config, steps, rates, still policy's rates): `run_dir`'s evaluations and the still
    policy's on the same episodes."""
    from franka_composer.training.runs import RunDir, read_eval_rows

    run = RunDir(run_dir)
    try:
        config = run.read_config()
        rows = read_eval_rows(run.eval_csv)
    except ValueError as error:  # Named, with the file: not a run, or a damaged one.
        raise SystemExit(str(error)) from None
    if not rows:
        raise SystemExit(f"{run.eval_csv}: no evaluations yet")
    every = config.hyperparameters.eval_every
    steps = np.array([row["steps"] for row in rows])
    if not np.array_equal(steps, every * np.arange(len(rows))):
        raise SystemExit(f"{run.eval_csv}: evaluations are not every {every} steps from 0")
    rates = np.array([row["success_rate"] for row in rows])
    try:
        still = np.array(still_rates(config.task, seed=config.seed, evaluations=len(rows),
                                     episodes=config.hyperparameters.eval_episodes,
                                     **config.env_options))  # Its control among them.
    except ValueError as error:  # An env only its own script builds, named.
        raise SystemExit(f"{run_dir}: {error}") from None
    return config, steps, rates, still


def floor_table(steps: np.ndarray, rates: np.ndarray, still: np.ndarray,
                window: int = 50_000) -> str:
    """A markdown table of evaluations beside the still policy's on the same episodes, per
    `window` steps (evaluations in (a, a + window]), and over all of them."""
    lines = ["| steps | evaluations | run | still policy | above / equal / below it | "
             "sign test p |", "|---|---|---|---|---|---|"]

    def line(label: str, chosen: np.ndarray) -> str:
        run_rates, floor = rates[chosen], still[chosen]
        above, below = int((run_rates > floor).sum()), int((run_rates < floor).sum())
        p = sign_test(above, below)
        return (f"| {label} | {chosen.sum()} | {100 * run_rates.mean():.1f} % | "
                f"{100 * floor.mean():.1f} % | {above} / {(run_rates == floor).sum()} / "
                f"{below} | {'–' if p is None else f'{p:.2g}'} |")

    for start in range(0, int(steps[-1]), window):
        chosen = (steps > start) & (steps <= start + window)
        lines.append(line(f"{start:,}–{min(start + window, int(steps[-1])):,}", chosen))
    lines.append(line(f"0–{int(steps[-1]):,}", steps >= 0))
    return "\n".join(lines)


def sign_test(above: int, below: int) -> float | None:
    """The chance of `above` or more of the `above + below` evaluations that differ from
    the floor being above it, were each as likely above as below (a one-sided sign test;
    ties drop out); None where none differ."""
    differ = above + below
    if differ == 0:
        return None
    return sum(math.comb(differ, k) for k in range(above, differ + 1)) / 2 ** differ


def run_beside_floor(run_dir: pathlib.Path, window: int = 50_000) -> str:
    """`floor_table` of `run_dir`'s evaluations."""
    return floor_table(*run_and_floor(run_dir)[1:], window)


def trailing_mean(values: np.ndarray, count: int) -> np.ndarray:
    """The mean of each value and the `count` - 1 before it (fewer at the start)."""
    return np.array([values[max(0, end - count):end].mean()
                     for end in range(1, len(values) + 1)])


def draw_beside_floor(runs: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
                      path: pathlib.Path, window: int = 50_000) -> None:
    """One panel per (label, steps, rates, still rates): each evaluation as a dot, the run's
    and the still policy's trailing means over `window` steps as lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(runs), figsize=(5.5 * len(runs), 4), squeeze=False)
    for ax, (label, steps, rates, still) in zip(axes[0], runs):
        count = max(1, window // int(steps[1] - steps[0])) if len(steps) > 1 else 1
        ax.plot(steps, 100 * rates, ".", color="tab:blue", alpha=0.3, markersize=3)
        ax.plot(steps, 100 * trailing_mean(rates, count), color="tab:blue",
                label=f"run, mean of {count} evaluations")
        ax.plot(steps, 100 * trailing_mean(still, count), "--", color="0.3",
                label="still policy, same episodes")
        ax.set(title=label, xlabel="steps", ylabel="success (%)", ylim=(-2, 102))
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="push", choices=ALL_TASKS)
    parser.add_argument("--control", default="mocap", choices=CONTROLS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--evaluations", type=positive_int, default=50)
    parser.add_argument("--run", type=pathlib.Path, nargs="+", metavar="RUN_DIR",
                        help="run directories: each one's evaluations beside its own floor, "
                             "per 5e4 steps (the other options are the run's)")
    parser.add_argument("--plot", type=pathlib.Path, metavar="IMAGE",
                        help="with --run: also draw each run beside its floor, one panel each")
    parser.add_argument("--final-test", nargs=2, action="append", metavar=("EPISODES", "SEED"),
                        help="with --run: also the still policy's success on the episodes "
                             "`franka-composer evaluate RUN_DIR --episodes EPISODES --seed "
                             "SEED` plays (repeatable)")
    args = parser.parse_args(argv)
    if args.final_test and not args.run:
        parser.error("--final-test reads runs: give them with --run")

    def final_test_value(name: str, text: str, check) -> int:
        try:
            return check(text)
        except argparse.ArgumentTypeError as error:
            parser.error(f"--final-test {name}: {error}")

    final_tests = [(final_test_value("EPISODES", episodes, positive_int),
                    final_test_value("SEED", seed, episode_seed))
                   for episodes, seed in args.final_test or ()]
    if args.plot and not args.run:
        parser.error("--plot draws runs: give them with --run")
    if args.plot and args.plot.suffix.lower() not in (".png", ".pdf", ".svg"):
        parser.error(f"--plot: a .png, .pdf or .svg file, not {args.plot.name}")
    if args.run:
        drawn = []
        for run_dir in args.run:
            config, steps, rates, still = run_and_floor(run_dir)
            print(f"{run_dir} ({config.task} {config.algo} seed {config.seed})\n")
            print(floor_table(steps, rates, still) + "\n")
            for episodes, seed in final_tests:
                rate = still_on_final_test(config, episodes, seed)
                print(f"still policy on evaluate's {episodes} episodes from seed {seed}: "
                      f"{100 * rate:.1f} %\n")
            drawn.append((f"{config.task} {config.algo} seed {config.seed}", steps, rates,
                          still))
        if args.plot:
            draw_beside_floor(drawn, args.plot)
            print(f"wrote {args.plot}")
        return 0
    print(json.dumps(still_rates(args.task, args.control, args.seed, args.evaluations)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
