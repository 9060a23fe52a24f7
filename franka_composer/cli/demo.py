"""`franka-composer demo`: the scripted experts solving every task, with videos and a table.

Steps per second count only the time inside `env.reset` and `env.step` (no rendering, no
policy), so the figure is the simulator's speed whether or not videos are written.
"""

from __future__ import annotations

import argparse
import pathlib

import gymnasium as gym

import franka_composer
from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import positive_int
from franka_composer.policies import make_expert, rollout

DEFAULT_OUT = "demo_output"
TABLE_HEADER = ("task", "episodes", "success rate", "mean episode length", "env steps/s")


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo", help="run the scripted expert on every task; write videos and a table",
        description="Runs the scripted expert of each task headless through gym.make (sparse "
                    "reward), prints a table of success rate, mean episode length and "
                    "simulator speed, and writes <task>.mp4 and <task>.png (its first frame) "
                    "per task into the output folder.",
    )
    parser.add_argument("--tasks", type=parse_tasks, default=franka_composer.ALL_TASKS,
                        help="comma-separated tasks to run (default: all of "
                             f"{','.join(franka_composer.ALL_TASKS)})")
    parser.add_argument("--episodes", type=positive_int, default=10,
                        help="episodes per task (default: 10)")
    parser.add_argument("--control", choices=("mocap", "osc"), default="mocap",
                        help="controller the experts act through (they act on dx, dy, dz, "
                             "so not joints; default: mocap)")
    parser.add_argument("--seed", type=int, default=0,
                        help="episode i of each task is reset with seed + i (default: 0)")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path(DEFAULT_OUT),
                        help=f"folder for the videos and first frames (default: {DEFAULT_OUT}/)")
    parser.add_argument("--no-video", action="store_true",
                        help="do not render: write no MP4 or PNG files, print only the table")
    parser.add_argument("--video-episodes", type=positive_int, default=3,
                        help="how many of the first episodes each task's video shows "
                             "(default: 3)")
    parser.add_argument("--width", type=positive_int, default=480,
                        help="frame width in pixels, at most 1024 (default: 480)")
    parser.add_argument("--height", type=positive_int, default=480,
                        help="frame height in pixels, at most 1024 (default: 480)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    if not args.no_video:
        args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tqdm(total=len(args.tasks) * args.episodes, desc="demo", unit="episode") as bar:
        for task in args.tasks:
            bar.set_postfix_str(task)
            rows.append(_run_task(task, args, lambda _: bar.update()))
    print(format_table(rows))
    if not args.no_video:
        print(f"Videos (<task>.mp4) and first frames (<task>.png): {args.out.resolve()}")
    return 0


def _run_task(task: str, args: argparse.Namespace, on_episode_end) -> tuple:
    """Runs the expert on `task`; writes its video and first frame; returns a table row."""
    render_mode = None if args.no_video else "rgb_array"
    env = gym.make(env_id(task, "sparse", args.control), render_mode=render_mode,
                   width=args.width, height=args.height)
    frames: list = []

    def record(environment, episode: int) -> None:
        if episode < args.video_episodes:
            frames.append(environment.render())

    trajectories = rollout(env, make_expert(env), args.episodes, seed=args.seed,
                           on_step=None if args.no_video else record,
                           on_episode_end=on_episode_end)
    fps = env.metadata["render_fps"]
    env.close()
    if frames:
        import imageio

        imageio.imwrite(args.out / f"{task}.png", frames[0])
        imageio.mimwrite(args.out / f"{task}.mp4", frames, fps=fps, macro_block_size=1)
    steps = int(trajectories.lengths.sum())
    return (task, len(trajectories), trajectories.success_rate,
            float(trajectories.lengths.mean()), steps / trajectories.env_seconds)


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


def parse_tasks(text: str) -> tuple[str, ...]:
    """Comma-separated task names, checked against `franka_composer.ALL_TASKS`."""
    tasks = tuple(name.strip() for name in text.split(",") if name.strip())
    unknown = [name for name in tasks if name not in franka_composer.ALL_TASKS]
    if unknown or not tasks:
        raise argparse.ArgumentTypeError(
            f"unknown task(s) {', '.join(unknown) or '(none given)'}; valid tasks: "
            f"{', '.join(franka_composer.ALL_TASKS)}")
    return tasks
