"""The success rate a policy that does nothing gets on a run's evaluations: the floor a
learning curve must rise above.

    python experiments/still_baseline.py --task push [--control osc] [--seed 0] [--evaluations 50]

`train` evaluates 15 episodes every 2000 steps on an env seeded from the run's seed, and
which episodes an evaluation sees does not depend on the policy (goals and objects are
drawn at reset), so an untrained policy scores exactly the episodes that start solved and
stay so (push: the block already within 5 cm of the goal). This replays those evaluations
with a zero action, in the order `train` runs them from its start (a resumed run goes on
with the episodes an uninterrupted one would see; on trees before commit 6cabf21 its eval
env started its stream again: compare such a run's evaluations after a resume with this
list from its beginning, computed with that tree on PYTHONPATH). The same seed draws the
same episodes with domain randomisation (`randomization`) as without, so this is also the
floor of a randomised run. Prints one JSON list, a rate per evaluation.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from franka_composer.cli.options import positive_int
from franka_composer.controllers import CONTROLS
from franka_composer.tasks import ALL_TASKS


class StillPolicy:
    """SB3's `predict` interface, always the zero action."""

    def __init__(self, action_size: int) -> None:
        self._size = action_size

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros((len(observation["desired_goal"]), self._size), np.float32), None


def still_rates(task: str, control: str, seed: int, evaluations: int,
                episodes: int = 15) -> list[float]:
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import DummyVecEnv

    from franka_composer.training.loop import EVAL_SEED_OFFSET
    from franka_composer.training.models import make_env

    env = DummyVecEnv([lambda: make_env(task, control=control)])
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="push", choices=ALL_TASKS)
    parser.add_argument("--control", default="mocap", choices=CONTROLS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--evaluations", type=positive_int, default=50)
    args = parser.parse_args(argv)
    print(json.dumps(still_rates(args.task, args.control, args.seed, args.evaluations)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
