"""Trained pick-and-place policies played in both envs: this suite's at the reference timing
and the paper's reference code's own. Issue 37 asks whether pick-and-place learns slower here
because of the env or because of the training; a policy that succeeds as often in one env as
in the other says the two envs are the same task for what it learnt, one that succeeds more
often in the reference env says the env is easier there. It costs minutes, where training in
the reference env (`experiments/reference_env_runs.py`) costs CPU hours.

    python experiments/cross_play.py --reference-path DIR [RUN_DIR ...] [--expert]
        [--episodes 200] [--seed 100] [--goal-bands] [--object-damping D]

Each RUN_DIR's policy (its model.zip, else its latest checkpoint, else its policy.pt, as
`franka-composer evaluate` takes it) plays `--episodes` deterministic episodes in each env,
the first reset seeded with `--seed` (the two envs draw their episodes from the same
distributions, not the same episodes: `docs/experiments/goal-sampling.md`). Both envs end an
episode on success, as the paper's training and tests do, so a success there is one at any
step of 50. The policy also plays this suite's env without that termination, where the
issue's other metric can be read: success at the episode's last step, against any step.
`--expert` adds this suite's scripted pick-and-place expert, built for the reference timing,
as a policy that succeeds nearly always: what it reads from the observation has the same
layout in both envs. Prints a Markdown table of success rates with their binomial standard
errors; `--goal-bands` adds, for the two envs that end on success, each policy's success
and the episodes in which it raised the block, split by the goal's height
(`pick_and_place_goals.py`'s bands): whether a policy that lifts in one env lifts in the
other. `--object-damping` damps this suite's block so (0.01: as the reference code's is),
to tell what its damping does for a policy from the rest of the two envs' differences.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import add_object_damping, episode_seed, positive_int
from franka_composer.policies import make_expert
from franka_composer.tasks.options import TIMINGS
from franka_composer.training.models import make_env
from franka_composer.training.policy_file import load_trained
from franka_composer.training.runs import RunDir

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import reference_env_runs  # noqa: E402  (experiments/, not a package)
from pick_and_place_goals import GoalBands, band_rows, check_object_damping  # noqa: E402

#: The one task both envs have a policy for here (the reference code's push and slide have no
#: runs at the reference timing).
TASK = "pick_and_place"


class ScriptedPolicy:
    """A scripted expert with a trained policy's `predict`; `reset` at each episode's start."""

    def __init__(self, expert) -> None:
        self.expert = expert

    def reset(self) -> None:
        self.expert.reset()

    def predict(self, obs, deterministic: bool = True):
        return self.expert(obs), None


def play(policy, env, episodes: int, seed: int) -> tuple[float, float]:
    """(success at any step, success at the last step) over `episodes` deterministic
    episodes; `seed` seeds the first reset."""
    anywhere, last = [], []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed if episode == 0 else None)
        if hasattr(policy, "reset"):
            policy.reset()
        done, succeeded = False, False
        while not done:
            action, _ = policy.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            succeeded |= bool(info["is_success"])
            done = terminated or truncated
        anywhere.append(succeeded)
        last.append(bool(info["is_success"]))
    return float(np.mean(anywhere)), float(np.mean(last))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference-path", type=pathlib.Path, required=True, metavar="DIR")
    parser.add_argument("runs", type=pathlib.Path, nargs="*", metavar="RUN_DIR")
    parser.add_argument("--expert", action="store_true",
                        help="also play the scripted expert (at the reference timing)")
    parser.add_argument("--goal-bands", action="store_true",
                        help="also split each policy's episodes by the goal's height")
    add_object_damping(parser, "undamped, as this suite's task")
    parser.add_argument("--episodes", type=positive_int, default=200)
    parser.add_argument("--seed", type=episode_seed, default=100)
    args = parser.parse_args(argv)
    error = reference_env_runs.peer_worker.reference_path_error(args.reference_path)
    if error:
        parser.error(error)
    if not args.runs and not args.expert:
        parser.error("give a RUN_DIR, --expert or both")
    check_object_damping(parser, args.object_damping)
    ours = dict(TIMINGS["reference"])
    if args.object_damping is not None:
        ours["object_damping"] = args.object_damping
    configs = {}
    for root in args.runs:
        try:
            configs[root] = RunDir(root).read_config()
        except (OSError, ValueError) as bad:
            parser.error(str(bad))
        if configs[root].task != TASK:
            parser.error(f"{root} trained {configs[root].task}; this compares {TASK}")
    import gymnasium as gym

    specs = reference_env_runs.reference_specs(args.reference_path)

    def rate(value: float) -> str:
        error = math.sqrt(value * (1 - value) / args.episodes)
        return f"{100 * value:.1f} ± {100 * error:.1f}"

    damped = ("" if args.object_damping is None
              else f"; this suite's block damped by {args.object_damping:g}")
    print(f"{args.episodes} deterministic episodes per env, first reset seed {args.seed}"
          f"{damped}; success rate % ± its standard error\n")
    print("| run | trained in | steps | this suite, reference timing | reference code's env "
          "| reference − this suite | this suite, 50 steps: success at any step | "
          "at the last step |")
    print("|---|---|---|---|---|---|---|---|")
    bands = []
    for root in [*args.runs, *([None] if args.expert else [])]:
        envs = {"ours": GoalBands(make_env(TASK, **ours)),
                # Its checker warns that `terminated` is a float32 (SB3 takes it as it is).
                "reference": GoalBands(gym.make(specs[TASK], disable_env_checker=True)),
                "ours, 50 steps": make_env(TASK, terminate_on_success=False,
                                           **ours)}
        try:
            # Loaded once: the same weights in every env, though the run goes on beside.
            policy = (load_trained(RunDir(root), envs["ours"], device="cpu") if root is not None
                      else ScriptedPolicy(make_expert(envs["ours"])))
            rates = {where: play(policy, env, args.episodes, args.seed)
                     for where, env in envs.items()}
        finally:
            for env in envs.values():
                env.close()
        if root is None:
            name, trained_in, steps = "scripted expert", "–", "–"
        else:
            config = configs[root]
            name, steps = root.name, f"{policy.num_timesteps:,}"
            trained_in = (f"this suite, {config.control_timestep:g} s per step"
                          if config.environment != reference_env_runs.NAME
                          else "the reference code's env")
        difference = 100 * (rates["reference"][0] - rates["ours"][0])
        print(f"| {name} | {trained_in} | {steps} | "
              f"{rate(rates['ours'][0])} | {rate(rates['reference'][0])} | {difference:+.1f} | "
              f"{rate(rates['ours, 50 steps'][0])} | {rate(rates['ours, 50 steps'][1])} |",
              flush=True)
        bands += [(name, steps, where, np.array(envs[key].rows, dtype=float))
                  for key, where in (("ours", "this suite, reference timing"),
                                     ("reference", "reference code's env"))]
    if args.goal_bands:
        print("\n| run | steps | env | goal | episodes | success | block rose > 1 cm |")
        print("|---|---|---|---|---|---|---|")
        for name, steps, where, rows in bands:
            for band, count, success, lifted in band_rows(rows):
                print(f"| {name} | {steps} | {where} | {band} | {count} | {success:.1f} % "
                      f"| {lifted:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
