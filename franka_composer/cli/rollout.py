"""`franka-composer rollout`: record demonstrations of a task, by its scripted expert or a
trained policy, as `.npz`, a Minari dataset or an RLDS dataset (`franka_composer.datasets`).

The `.npz` file holds every episode concatenated (`observation`, `achieved_goal`,
`desired_goal` with one more row per episode than `action`, `reward`, `is_success`,
`terminated`, `truncated`), `episode_length` and `metadata` (what it was recorded with: task,
control, reward type, options); `franka_composer.policies.Trajectories.load` checks and
splits it (`franka_composer.episodes.npz_file`). Minari and RLDS need the `[data]` extra
(docs/guide/datasets.md).
"""

from __future__ import annotations

import argparse
import pathlib

import franka_composer
from franka_composer.cli.options import (add_object_damping, add_timing, as_flags, episode_seed,
                                         given_timing, normal_path, positive_int,
                                         standard_deviation, the_runs_control)
from franka_composer.controllers import CONTROLS, DEFAULT_CONTROL
from franka_composer.tasks.rewards import REWARD_TYPES
from franka_composer.wording import counted


def add_parser(subparsers) -> None:
    from franka_composer.datasets import FORMATS

    parser = subparsers.add_parser(
        "rollout", help="record demonstrations of one task (npz, Minari or RLDS)",
        description="Runs a task's scripted expert (or a trained policy) through gym.make and "
                    "records every episode: observations, actions, rewards, terminations, "
                    "truncations and success flags, with each episode's reset seed.",
    )
    parser.add_argument("--task", choices=franka_composer.ALL_TASKS, default=None,
                        help="the task to demonstrate (with --policy, the run's)")
    parser.add_argument("--episodes", type=positive_int, default=100,
                        help="number of episodes (default: 100)")
    parser.add_argument("--seed", type=episode_seed, default=0,
                        help="episode i is reset with seed + i (default: 0)")
    parser.add_argument("--format", choices=FORMATS, default="npz",
                        help="npz (default), minari or rlds")
    parser.add_argument("--control", choices=CONTROLS, default=None,
                        help=f"the controller (default: {DEFAULT_CONTROL}, or the --policy "
                             "run's; the experts take mocap and osc)")
    add_timing(parser, "physics seconds per step (default: the task's, 0.05; with --policy, "
                       "the timing the run trained at, and another is refused)")
    add_object_damping(parser, "0, undamped; with --policy, as the run trained")
    parser.add_argument("--policy", type=pathlib.Path, default=None, metavar="RUN_DIR",
                        help="act with the policy trained in this run directory instead of "
                             "the scripted expert, in episodes as it trained: their "
                             "termination on success and randomisation its own")
    parser.add_argument("--action-noise", type=standard_deviation, default=0.0, metavar="STD",
                        help="Gaussian noise added to each action component (default: 0)")
    parser.add_argument("--reward-type", choices=REWARD_TYPES, default="sparse",
                        help="reward stored with each step (default: sparse)")
    parser.add_argument("--dataset-id", default=None,
                        help="Minari dataset id (default: franka_composer/<task>[-<control>]/"
                             "<expert|policy>[-noisy]-v0, the control named unless mocap, "
                             "-noisy with --action-noise)")
    parser.add_argument("--out", type=normal_path, required=True,
                        help="the .npz file (one there is replaced once the episodes are "
                             "recorded), or the folder of a Minari dataset (not one holding "
                             "its --dataset-id already) or of an RLDS dataset (empty or new)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.datasets import record
    from franka_composer.training.runs import RunDir, check_out_apart

    run_timing, damping, episodes_as = None, args.object_damping, {}
    # Not over a run's own files: its expert-demos.npz, say, or another run's config.json.
    check_out_apart(args.out, [args.policy] if args.policy is not None else [])
    if args.policy is None:
        if args.task is None:
            raise ValueError("rollout needs --task (or --policy RUN_DIR: its run's task)")
        args.control = args.control or DEFAULT_CONTROL
    else:  # In the run's env unless told otherwise.
        from franka_composer.training.policy_file import check_trained

        policy_run = RunDir(args.policy)
        trained = policy_run.read_config()
        check_trained(policy_run)  # Before a dataset is begun.
        if args.task not in (None, trained.task):
            raise ValueError(f"--policy {args.policy} was trained on {trained.task}, not "
                             f"--task {args.task}")
        args.task = trained.task
        args.control = the_runs_control(args.policy, trained, args.control)
        run_timing = trained.timing_options
        damping = trained.object_damping if damping is None else damping
        # Its episodes as it trained: their ends and randomisation (a dataset of them fills
        # its buffer), and its guard (a stack run from before v1).
        episodes_as = {name: value for name, value in trained.env_options.items()
                       if name in ("terminate_on_success", "randomization",
                                   "guard_ignores_carried") and value is not None}
    task_options = {**given_timing(args, run_timing),
                    **({"object_damping": damping} if damping else {}), **episodes_as}
    from franka_composer.tasks import task_config

    with as_flags("rollout"):  # A bad timing or damping named by its flag, before anything.
        config = task_config(args.task, control=args.control, **task_options)
    if args.policy is not None:  # Acts there as it learned: found before a dataset is begun.
        from franka_composer.datasets.sources import check_acts_in

        check_acts_in(args.policy, trained, config)
    summary = record(args.task, args.episodes, args.out, format=args.format, seed=args.seed,
                     control=args.control, reward_type=args.reward_type,
                     policy_dir=args.policy, action_noise=args.action_noise,
                     dataset_id=args.dataset_id, **task_options)
    name = f" ({summary['dataset_id']})" if "dataset_id" in summary else ""
    print(f"{args.task}: {counted(summary['episodes'], 'episode')}, "
          f"{counted(summary['steps'], 'step')}, "
          f"success rate {summary['success_rate']:.0%} -> {summary['path']}{name}")
    return 0
