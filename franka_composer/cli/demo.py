"""`franka-composer demo`: the scripted experts solving every task, with videos and a table;
with `--policy`, a trained run's policy on its task instead.

Steps per second count only the time inside `env.reset` and `env.step` (no rendering, no
policy). An env that writes videos carries the Panda's visual meshes, whose poses every
step computes, so the figure is lower with videos than with --no-video (0.71-0.76x on push
on this project's 2-vCPU machine: `demo --tasks push --episodes 6` against the same with
--no-video, three pairs in turn, 2026-11-29): --no-video gives the simulator's speed as
training sees it.
"""

from __future__ import annotations

import argparse
import pathlib
from typing import Any, Callable

import gymnasium as gym

import franka_composer
from franka_composer import headless_gl
from franka_composer.adapters.registration import env_id
from franka_composer.atomic_files import folders_made_for, replace_together
from franka_composer.controllers.settings import DEFAULT_CONTROL, TCP_CONTROLS
from franka_composer.cli.options import (add_tasks_argument, add_timing, as_flags, episode_seed,
                                         frame_size, given_timing, output_folder,
                                         positive_int, the_runs_control)
from franka_composer.policies import make_expert, rollout
from franka_composer.signals import held
from franka_composer.tasks import task_config
from franka_composer.validation import check_writable

DEFAULT_OUT = "demo_output"
#: Episodes each task's video shows where --video-episodes is not given (or every episode,
#: if there are fewer).
DEFAULT_VIDEO_EPISODES = 3
TABLE_HEADER = ("task", "episodes", "success rate", "mean episode length", "env steps/s")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo", help="run the scripted expert on every task; write videos and a table",
        description="Runs the scripted expert of each task headless through gym.make (sparse "
                    "reward), prints a table of success rate, mean episode length and "
                    "simulator speed, and writes <task>.mp4 and <task>.png (its first frame) "
                    "per task into the output folder. With --policy RUN_DIR, the policy "
                    "trained in RUN_DIR plays instead, on that run's task, controller and "
                    "environment options.",
    )
    add_tasks_argument(parser, franka_composer.ALL_TASKS,
                       f"tasks to run (default: all of {','.join(franka_composer.ALL_TASKS)})")
    parser.add_argument("--episodes", type=positive_int, default=10,
                        help="episodes per task (default: 10)")
    parser.add_argument("--control", choices=TCP_CONTROLS, default=None,
                        help="controller the experts act through (they act on dx, dy, dz, "
                             f"so not joints; default: {DEFAULT_CONTROL}, or the --policy "
                             "run's)")
    add_timing(parser, "physics seconds per step (default: the task's, 0.05; with --policy, "
                       "the timing the run trained at, and another is refused)")
    parser.add_argument("--policy", type=pathlib.Path, default=None, metavar="RUN_DIR",
                        help="play the policy trained in RUN_DIR (a `train` run, or one as "
                             "committed with config.json and policy.pt) instead of the experts")
    parser.add_argument("--seed", type=episode_seed, default=0,
                        help="episode i of each task is reset with seed + i (default: 0)")
    parser.add_argument("--out", type=output_folder, default=pathlib.Path(DEFAULT_OUT),
                        help=f"folder for the videos and first frames (default: {DEFAULT_OUT}/)")
    parser.add_argument("--no-video", action="store_true",
                        help="do not render: write no MP4 or PNG files, print only the table")
    parser.add_argument("--video-episodes", type=positive_int, default=None,
                        help="how many of the first episodes each task's video shows, at "
                             f"most --episodes (default: {DEFAULT_VIDEO_EPISODES}, or every "
                             "episode if fewer)")
    parser.add_argument("--width", type=frame_size, default=480,
                        help="frame width in pixels, at most 1024 (default: 480)")
    parser.add_argument("--height", type=frame_size, default=480,
                        help="frame height in pixels, at most 1024 (default: 480)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    if args.video_episodes is not None and args.no_video:
        raise ValueError("--video-episodes sets what the videos show, and --no-video writes "
                         "none: give one of them")
    if args.video_episodes is not None and args.video_episodes > args.episodes:
        raise ValueError(f"--video-episodes {args.video_episodes} is more than --episodes "
                         f"{args.episodes}: each task's video shows its first episodes")
    if not args.no_video:
        from franka_composer.training.runs import check_not_inside_a_run

        check_writable(args.out, folder=True)  # Also the default, which the parser passes.
        check_not_inside_a_run(args.out)  # (A checkpoint folder: the next one replaces it.)
        odd = [f"--{name} {getattr(args, name)}" for name in ("width", "height")
               if getattr(args, name) % 2]
        if odd:  # ffmpeg writes an empty file, and the demo said it wrote the videos.
            raise ValueError(f"{' and '.join(odd)}: the videos are H.264 (yuv420p), whose "
                             "frames have even sizes; give an even size, or --no-video")
        headless_gl.check_can_render()  # MUJOCO_GL=disable: before the first episode.
    trained = None if args.policy is None else _adopt_the_runs_task(args)
    with as_flags("demo"):  # A bad timing is refused before the first episode.
        for task in args.tasks:
            task_config(task, **given_timing(args))
    rows = []
    # On a terminal only (disable=None): in a log, each update was a line of its own.
    with tqdm(total=len(args.tasks) * args.episodes, desc="demo", unit="episode",
              disable=None) as bar:
        for task in args.tasks:
            bar.set_postfix_str(task)
            rows.append(_run_task(task, args, trained, lambda _: bar.update()))
    print(format_table(rows))
    if not args.no_video:
        print(f"Videos (<task>.mp4) and first frames (<task>.png): {args.out.resolve()}")
    return 0


def _adopt_the_runs_task(args: argparse.Namespace):
    """The --policy run's config, with `args` set to its task and controller; a --tasks or
    --control that names others, a policy that cannot be read, or a timing or environment
    it did not learn in is an error (before anything is built)."""
    from franka_composer.datasets.sources import check_acts_in
    from franka_composer.training.models import env_task_config
    from franka_composer.training.policy_file import check_trained
    from franka_composer.training.runs import RunDir

    policy_run = RunDir(args.policy)
    config = policy_run.read_config()
    check_trained(policy_run)
    if args.tasks not in (franka_composer.ALL_TASKS, (config.task,)):
        raise ValueError(f"--policy {args.policy} was trained on {config.task}; --tasks "
                         f"{','.join(args.tasks)} asks for others")
    args.tasks = (config.task,)
    args.control = the_runs_control(args.policy, config, args.control)
    # A timing given that is not the run's, refused before its env is made.
    options = {**config.env_options, **given_timing(args)}
    del options["environment"]  # This suite's env: a run trained in another's is refused.
    check_acts_in(args.policy, config, env_task_config(config.task, **options))
    return config


def _run_task(task: str, args: argparse.Namespace, trained, on_episode_end) -> tuple:
    """Runs the expert (or, given the --policy run's config `trained`, its policy, in that
    run's environment) on `task`; writes its video and first frame; returns a table row."""
    render = {} if args.no_video else dict(render_mode="rgb_array", width=args.width,
                                           height=args.height)
    timing = given_timing(args)
    policy: Callable[[Any], Any]
    if trained is None:
        env = gym.make(env_id(task, "sparse", args.control or DEFAULT_CONTROL), **render,
                       **timing)
        policy = make_expert(env)
    else:
        from franka_composer.datasets.sources import TrainedPolicy
        from franka_composer.training.models import make_env

        env = make_env(task, **{**trained.env_options, **timing}, **render)
        policy = TrainedPolicy(args.policy, env)
    frames: list = []

    def record(environment, episode: int) -> None:
        if episode < (args.video_episodes or DEFAULT_VIDEO_EPISODES):
            frames.append(environment.render())

    trajectories = rollout(env, policy, args.episodes, seed=args.seed,
                           on_step=None if args.no_video else record,
                           on_episode_end=on_episode_end)
    fps = env.metadata["render_fps"]
    env.close()
    if frames:
        import imageio

        # Whole or not at all, the video and its first frame together (a video interrupted
        # while ffmpeg wrote it was 48 bytes no player reads; a demo stopped between the two
        # left a frame without its video), in a folder made here: a demo that fails leaves
        # none.
        with folders_made_for(args.out / f"{task}.png"):
            replace_together({
                args.out / f"{task}.png": lambda partial: imageio.imwrite(partial, frames[0]),
                args.out / f"{task}.mp4": lambda partial: _write_video(partial, frames, fps)})
    steps = int(trajectories.lengths.sum())
    return (task, len(trajectories), trajectories.success_rate,
            float(trajectories.lengths.mean()), steps / trajectories.env_seconds)


def _write_video(path, frames: list, fps: float) -> None:
    """`frames` as an H.264 video at `path`. ffmpeg starts with the first frame, with Ctrl-C
    and SIGTERM held (`held`): stopped as imageio started it, before imageio could stop it
    again, it ran on unseen and wrote its file after the demo had cleaned up."""
    import imageio

    writer = imageio.get_writer(path, fps=fps, macro_block_size=1)
    try:
        with held():
            writer.append_data(frames[0])
        for frame in frames[1:]:
            writer.append_data(frame)
    finally:
        writer.close()  # Its `with` would not on an exception: ffmpeg would write on.


def format_table(rows: list[tuple]) -> str:
    """A plain-text table of (task, episodes, success rate, mean length, steps/s) rows."""
    cells = [TABLE_HEADER] + [(task, str(episodes), f"{success:.0%}", f"{length:.1f}",
                               f"{speed:.0f}")
                              for task, episodes, success, length, speed in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(TABLE_HEADER))]
    lines = ["  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip()
             for row in cells]
    lines.insert(1, "  ".join("-" * width for width in widths))
    return "\n".join(lines)

