"""Measures how the slide expert's kick moves the puck under one controller and timing, and
prints the `StrikeCalibration` that `franka_composer/policies/slide.py` holds for them.

    python tools/slide_calibration.py --control mocap --timing reference [--seeds 3]

Each strike is one episode through Gymnasium (made with `terminate_on_success=False`): the
expert lines a finger corner up behind the puck wherever `reset(seed=i)` put it and kicks
once, at an angle and size set here instead of aimed at the goal; the puck's displacement
from the kick until it rests is its glide (length and direction). Two sweeps, each over
seeds 0 to N-1:

- kicks `KICKS` straight along +x: sqrt(glide) = gain * (kick - dead kick), fitted by least
  squares, gives `glide_gain` and `dead_kick`;
- strike angles `ANGLES` at one kick (`--sweep-kick`): the path's turn from the strike
  direction, and the glide relative to the +x strike's. Angles whose seeds disagree by more
  than `SPREAD` degrees (a finger corner change: the strike goes either way) are left out,
  and the turns are cut into pieces where neighbours differ by more than `JUMP` degrees.

Prints both sweeps as Markdown tables, then the calibration as Python.
"""

from __future__ import annotations

import argparse
import dataclasses

import gymnasium as gym
import numpy as np

from franka_composer.adapters.registration import env_id
from franka_composer.policies import make_expert
from franka_composer.tasks.options import TIMINGS

KICKS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
ANGLES = tuple(np.round(np.arange(-75.0, 75.01, 2.5), 1))
SPREAD = 5.5  # deg: seeds of one strike angle further apart go either way (a corner change).
JUMP = 3.0  # deg: neighbouring strike angles further apart meet different corners.
THIN = 0.3  # deg: a piece's points that its neighbours interpolate this well are dropped.
THIN_GLIDE = 0.03  # Glide factors that their neighbours interpolate this well are dropped.
MAX_STEPS = 200  # A puck glides 1.3 m in ~50 steps of 0.05 s.


@dataclasses.dataclass(frozen=True)
class FixedStrike:
    """Stands in for a `StrikeCalibration`: every strike at `angle` (deg) with `size`."""

    angle: float
    size: float
    overshoot: float = 0.0

    def strike_angle(self, path_angle: float) -> float:
        return self.angle

    def kick(self, distance: float, strike_angle: float) -> float:
        return self.size


def glide(env, expert, seed: int, angle: float, size: float) -> np.ndarray:
    """The puck's displacement (m, x-y) from one kick at `angle` (deg) of `size` until it
    rests; NaN if the episode ended first."""
    expert.reset()
    expert._calibration = FixedStrike(angle, size)
    obs, _ = env.reset(seed=seed)
    before = None
    for _ in range(MAX_STEPS):
        was_waiting = expert._waiting
        action = expert(obs)
        if expert._waiting and not was_waiting:
            before = obs["achieved_goal"][:2].copy()
        elif was_waiting and not expert._waiting:
            return obs["achieved_goal"][:2] - before
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    return np.full(2, np.nan)


def fit_glide(kicks: np.ndarray, distances: np.ndarray) -> tuple[float, float]:
    """(gain, dead kick) of sqrt(distance) = gain * (kick - dead kick), least squares."""
    gain, intercept = np.polyfit(kicks, np.sqrt(distances), 1)
    return float(gain), float(-intercept / gain)


def thin(angles, values, tolerance: float, digits: int) -> tuple[tuple, tuple]:
    """The fewest of the points (Douglas-Peucker) whose straight pieces pass within
    `tolerance` of every one left out."""
    angles, values = np.asarray(angles, dtype=float), np.asarray(values, dtype=float)
    keep = {0, len(angles) - 1}
    spans = [(0, len(angles) - 1)]
    while spans:
        first, last = spans.pop()
        if last - first < 2:
            continue
        inner = np.arange(first + 1, last)
        errors = np.abs(values[inner] - np.interp(angles[inner], angles[[first, last]],
                                                  values[[first, last]]))
        if errors.max() > tolerance:
            worst = int(inner[np.argmax(errors)])
            keep.add(worst)
            spans += [(first, worst), (worst, last)]
    kept = sorted(keep)
    return (tuple(float(angles[i]) for i in kept),
            tuple(round(float(values[i]), digits) for i in kept))


def pieces(angles, turns: np.ndarray) -> list[tuple[tuple, tuple]]:
    """Per-angle turns (seeds in columns) cut into the calibration's pieces."""
    cut, current = [], ([], [])
    for angle, row in zip(angles, turns):
        if np.isnan(row).any() or np.ptp(row) > SPREAD:
            if current[0]:
                cut.append(current)
            current = ([], [])
            continue
        if current[1] and abs(row.mean() - current[1][-1]) > JUMP:
            cut.append(current)
            current = ([], [])
        current[0].append(float(angle))
        current[1].append(float(row.mean()))
    if current[0]:
        cut.append(current)
    return [thin(*piece, THIN, 1) for piece in cut]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--control", choices=("mocap", "osc"), default="mocap")
    parser.add_argument("--timing", choices=tuple(TIMINGS), default="default")
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0 to N-1 per strike")
    parser.add_argument("--sweep-kick", type=float, default=0.5,
                        help="the kick of the angle sweep (fraction of a full step)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    if not 0.0 < args.sweep_kick <= 1.0:
        parser.error(f"--sweep-kick must be in (0, 1], got {args.sweep_kick}")
    env = gym.make(env_id("slide", "sparse"), control=args.control, timing=args.timing,
                   terminate_on_success=False, max_episode_steps=MAX_STEPS)
    expert = make_expert(env)
    seeds = range(args.seeds)

    straight = np.array([[np.linalg.norm(glide(env, expert, seed, 0.0, kick))
                          for seed in seeds] for kick in KICKS])
    print(f"## {args.control}, {args.timing} timing: glide (m) of a kick along +x\n")
    print("| kick | " + " | ".join(f"seed {seed}" for seed in seeds) + " |")
    print("|---|" + "---|" * len(seeds))
    for kick, row in zip(KICKS, straight):
        print(f"| {kick} | " + " | ".join(f"{value:.3f}" for value in row) + " |")
    valid = ~np.isnan(straight)
    gain, dead_kick = fit_glide(np.repeat(KICKS, args.seeds)[valid.ravel()], straight[valid])

    displacements = np.array([[glide(env, expert, seed, angle, args.sweep_kick)
                               for seed in seeds] for angle in ANGLES])
    paths = np.degrees(np.arctan2(displacements[..., 1], displacements[..., 0]))
    turns = paths - np.asarray(ANGLES)[:, None]
    lengths = np.linalg.norm(displacements, axis=-1)
    along_x = np.nanmean(lengths[list(ANGLES).index(0.0)])
    print(f"\n## strike angles at kick {args.sweep_kick}: the path's turn (deg) and glide "
          "relative to +x's\n")
    print("| strike | turn per seed | glide factor |")
    print("|---|---|---|")
    for angle, row, length in zip(ANGLES, turns, lengths):
        print(f"| {angle} | " + ", ".join(f"{value:+.1f}" for value in row)
              + f" | {np.nanmean(length) / along_x:.2f} |")

    factors = np.nanmean(lengths, axis=1) / along_x
    print("\n```python")
    print(f"StrikeCalibration({gain:.2f}, {dead_kick:.3f}, (")
    for angles, piece_turns in pieces(ANGLES, turns):
        print(f"    ({angles}, {piece_turns}),")
    print(f"), {thin(ANGLES, factors, THIN_GLIDE, 2)})\n```")


if __name__ == "__main__":
    main()
