"""`franka-composer rollout`: record a task's scripted expert as demonstrations in `.npz`.

The file holds every episode concatenated (`observation`, `achieved_goal`, `desired_goal`
with one more row per episode than `action`, `reward`, `is_success`, `terminated`,
`truncated`) and `episode_length`; `franka_composer.policies.Trajectories.load` splits it.
"""

from __future__ import annotations

import argparse
import pathlib

import gymnasium as gym

import franka_composer
from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import positive_int
from franka_composer.policies import make_expert, rollout


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "rollout", help="save scripted-expert demonstrations of one task to a .npz file",
        description="Runs the scripted expert of a task through gym.make and saves every "
                    "episode's observations, actions, rewards and success flags to .npz.",
    )
    parser.add_argument("--task", required=True, choices=franka_composer.ALL_TASKS,
                        help="the task to demonstrate")
    parser.add_argument("--episodes", type=positive_int, default=100,
                        help="number of episodes (default: 100)")
    parser.add_argument("--seed", type=int, default=0,
                        help="episode i is reset with seed + i (default: 0)")
    parser.add_argument("--reward-type", choices=("sparse", "dense"), default="sparse",
                        help="reward stored with each step (default: sparse)")
    parser.add_argument("--out", type=pathlib.Path, required=True,
                        help="the .npz file to write (its folder is created)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    env = gym.make(env_id(args.task, args.reward_type))
    trajectories = rollout(env, make_expert(env), args.episodes, seed=args.seed)
    env.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    trajectories.save(args.out)
    print(f"{args.task}: {len(trajectories)} episodes, {int(trajectories.lengths.sum())} steps, "
          f"success rate {trajectories.success_rate:.0%} -> {args.out}")
    return 0
