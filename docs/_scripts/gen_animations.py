"""Renders each task's scripted expert for one episode as the animation on its docs page.

Writes `docs/_static/tasks/<task>.gif` (one frame per control step, 10 fps, the last frame
held a second) and `docs/_static/tasks/<task>.png` (the first frame, for the README's task
table). Rendering needs OpenGL (MUJOCO_GL=egl or osmesa headless); the docs build does not,
so the files are committed: run this again when a task's scene or expert changes.

    MENAGERIE_ROOT=... python docs/_scripts/gen_animations.py [--tasks push slide]
"""

from __future__ import annotations

import argparse
import pathlib

import gymnasium as gym
import numpy as np
from PIL import Image

import franka_composer
from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import add_tasks_argument
from franka_composer.policies import make_expert, rollout

#: Where the docs pages (and the README) find the files.
OUT = pathlib.Path(__file__).resolve().parents[1] / "_static" / "tasks"
#: Frame size (pixels), frames per second and colours: small enough for a page (and a README).
SIZE, FPS, COLOURS = 240, 10, 128
#: How long the last frame stays before the animation loops (ms).
HOLD_LAST_MS = 1000
#: The episode shown: the first seed of SEEDS whose episode lasts MIN_STEPS steps or more
#: (one whose goal starts next to the object ends at once and shows nothing), else the
#: longest.
SEEDS, MIN_STEPS = range(20), 20


def episode_frames(task: str) -> tuple[list[np.ndarray], int, bool]:
    """The frames of one episode of `task`'s expert (the reset frame first), its seed, and
    whether it succeeded."""
    env = gym.make(env_id(task, "sparse"), render_mode="rgb_array", width=SIZE, height=SIZE)
    longest: tuple[list[np.ndarray], int, bool] = ([], -1, False)
    for seed in SEEDS:
        frames: list[np.ndarray] = []
        trajectories = rollout(env, make_expert(env), 1, seed=seed,
                               on_step=lambda environment, _: frames.append(environment.render()))
        if len(frames) > len(longest[0]):
            longest = (frames, seed, bool(trajectories.successes[0]))
        if len(frames) > MIN_STEPS:
            break
    env.close()
    return longest


def write_animation(frames: list[np.ndarray], gif: pathlib.Path) -> None:
    """`frames` as a looping GIF with one palette (from the first frame, which shows every
    colour of the scene), and the first frame as a PNG beside it."""
    gif.parent.mkdir(parents=True, exist_ok=True)
    first = Image.fromarray(frames[0])
    first.save(gif.with_suffix(".png"), optimize=True)
    palette = first.quantize(COLOURS, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(frame).quantize(palette=palette, dither=Image.Dither.NONE)
              for frame in frames]
    durations = [1000 // FPS] * (len(images) - 1) + [HOLD_LAST_MS]
    images[0].save(gif, save_all=True, append_images=images[1:], duration=durations,
                   loop=0, optimize=True, disposal=1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_tasks_argument(parser, franka_composer.ALL_TASKS, "tasks to animate (default: all)")
    args = parser.parse_args(argv)
    for task in args.tasks:
        frames, seed, success = episode_frames(task)
        gif = OUT / f"{task}.gif"
        write_animation(frames, gif)
        print(f"{gif}: seed {seed}, {len(frames)} frames, {gif.stat().st_size / 1024:.0f} KiB, "
              f"{'success' if success else 'FAILED'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
