"""Saves a fixed rollout of every task, to check that a speed change changes no behaviour.

    python benchmarks/rollout_fingerprint.py after.npz
    PYTHONPATH=/tmp/prev python benchmarks/rollout_fingerprint.py before.npz   # older tree
    python benchmarks/rollout_fingerprint.py --compare before.npz after.npz

400 seeded random steps per task (sparse and dense ids), with the resets they need: each
row is the observation, both goals, reward, terminated, truncated and is_success, plus a
small rendered frame every 50 steps. `--compare` reports, per array, whether the two files
are bit-identical.
"""

from __future__ import annotations

import sys

import gymnasium as gym
import numpy as np

import franka_composer  # noqa: F401  # Registers the ids.

IDS = ("FrankaPushSparse-v0", "FrankaSlideDense-v0", "FrankaPickAndPlaceSparse-v0")


def _row(obs: dict, reward, terminated, truncated, success) -> np.ndarray:
    return np.concatenate([obs["observation"], obs["achieved_goal"], obs["desired_goal"],
                           [reward, terminated, truncated, success]])


def record(path: str, steps: int = 400) -> None:
    arrays = {}
    for env_id in IDS:
        env = gym.make(env_id, render_mode="rgb_array", width=96, height=96)
        rng = np.random.default_rng(0)
        obs, info = env.reset(seed=3)
        rows, frames = [_row(obs, 0, 0, 0, info["is_success"])], []
        for step in range(steps):
            action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            rows.append(_row(obs, reward, terminated, truncated, info["is_success"]))
            if step % 50 == 0:
                frames.append(env.render())
            if terminated or truncated:
                obs, info = env.reset()
                rows.append(_row(obs, 0, 0, 0, info["is_success"]))
        env.close()
        arrays[env_id], arrays[f"{env_id}/frames"] = np.array(rows), np.array(frames)
    np.savez(path, **arrays)


def compare(before: str, after: str) -> int:
    a, b = np.load(before), np.load(after)
    same = True
    for key in a.files:
        equal = key in b.files and np.array_equal(a[key], b[key])
        same &= equal
        print(f"{key}: {'identical' if equal else 'DIFFERENT'}")
    return 0 if same else 1


if __name__ == "__main__":
    if sys.argv[1:2] == ["--compare"]:
        sys.exit(compare(*sys.argv[2:4]))
    record(sys.argv[1])
