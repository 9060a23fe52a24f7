"""Running a policy for whole episodes and keeping what happened, for demos and datasets."""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Callable

import numpy as np

#: Keys of the Gymnasium goal observation dict in the state modes (the pixel modes add
#: "<camera>_pixels" images, and "pixels" alone has no "observation").
OBSERVATION_KEYS = ("observation", "achieved_goal", "desired_goal")
#: Per-step arrays (one entry per action taken).
STEP_KEYS = ("action", "reward", "is_success", "terminated", "truncated")


@dataclasses.dataclass
class Trajectories:
    """Episodes of one policy in one environment, each a dict of arrays.

    Each episode of T steps has the env's observation keys (`OBSERVATION_KEYS`, images in
    the pixel modes) with T + 1 rows (the reset observation first), and `action`, `reward`, `is_success` (the step's
    `info["is_success"]`), `terminated`, `truncated` with T rows.
    `env_seconds` is the wall time spent inside `env.reset` and `env.step` only;
    `metadata`, what a loaded file says they were recorded with ({} if it says nothing).
    """

    episodes: list[dict[str, np.ndarray]]
    env_seconds: float = 0.0
    metadata: dict = dataclasses.field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.episodes)

    @property
    def lengths(self) -> np.ndarray:
        """Steps per episode."""
        return np.array([len(e["action"]) for e in self.episodes], dtype=np.int64)

    @property
    def successes(self) -> np.ndarray:
        """Whether each episode ended in success (`is_success` of its last step)."""
        return np.array([bool(e["is_success"][-1]) if len(e["is_success"]) else False
                         for e in self.episodes])

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes)) if self.episodes else 0.0

    def save(self, path: str | os.PathLike, metadata: dict | None = None) -> None:
        """Writes every episode to a `.npz` file, with `metadata` (what they were recorded
        with; `franka_composer.datasets.npz_format`)."""
        from franka_composer.datasets import npz_format

        npz_format.write(self, path, metadata)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Trajectories":
        """Reads what `save` wrote, checked whole: a damaged file is a ValueError naming it."""
        from franka_composer.datasets import npz_format

        return npz_format.read(path)


def check_episodes_end(env) -> None:
    """A ValueError if episodes of the Gymnasium `env` end only on success (no `TimeLimit`:
    gym.make(id, max_episode_steps=-1), and no time limit of its own: time_limit=None):
    running one to its end could then never return."""
    spec = getattr(env, "spec", None)
    composer_env = getattr(getattr(env, "unwrapped", env), "composer_env", None)
    if ((spec is None or spec.max_episode_steps is None)
            and (composer_env is None or composer_env.episode_steps is None)):
        raise ValueError("episodes of this env end only on success (no max_episode_steps and "
                         "time_limit=None): give gym.make a max_episode_steps to run whole "
                         "episodes")


def rollout(env, policy, episodes: int, seed: int | None = None,
            on_step: Callable[[object, int], None] | None = None,
            on_episode_end: Callable[[int], None] | None = None) -> Trajectories:
    """Runs `policy` (obs -> action; its `reset()` is called at each episode start if it has
    one) for `episodes` episodes of `env`, each until terminated or truncated.

    Episode i is reset with `seed + i` when `seed` is given. `on_step(env, i)` is called after
    every reset and step of episode i (e.g. to render a frame) and `on_episode_end(i)` when it
    ends (e.g. to advance a progress bar); neither counts in `env_seconds`.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    check_episodes_end(env)
    collected, env_seconds = [], 0.0
    for index in range(episodes):
        if hasattr(policy, "reset"):
            policy.reset()
        start = time.perf_counter()
        obs, _ = env.reset(seed=None if seed is None else seed + index)
        env_seconds += time.perf_counter() - start
        if on_step is not None:
            on_step(env, index)
        observations, steps = [obs], {key: [] for key in STEP_KEYS}
        done = False
        while not done:
            action = policy(obs)
            start = time.perf_counter()
            obs, reward, terminated, truncated, info = env.step(action)
            env_seconds += time.perf_counter() - start
            if on_step is not None:
                on_step(env, index)
            observations.append(obs)
            for key, value in zip(STEP_KEYS, (action, reward, info["is_success"],
                                              terminated, truncated)):
                steps[key].append(value)
            done = terminated or truncated
        episode = {key: np.array([o[key] for o in observations]) for key in observations[0]}
        episode.update({key: np.array(values) for key, values in steps.items()})
        episode["action"] = episode["action"].astype(np.float32)
        episode["reward"] = episode["reward"].astype(np.float64)
        for key in ("is_success", "terminated", "truncated"):
            episode[key] = episode[key].astype(bool)
        collected.append(episode)
        if on_episode_end is not None:
            on_episode_end(index)
    return Trajectories(collected, env_seconds)
