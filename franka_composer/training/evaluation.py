"""Success rate of a policy over seeded episodes: the paper's final test (`evaluate`).

An episode succeeds when the last step reports `is_success`: with the paper's
terminate-on-success ids that is "the object reached the goal within the episode's steps"
(50, or 100 for stack and flip); without termination it is the Fetch convention (the
object is at the goal when time runs out).
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np


@dataclasses.dataclass(frozen=True)
class EvalResult:
    """Outcome of `episodes` deterministic episodes."""

    episodes: int
    success_rate: float  # fraction in [0, 1]
    mean_reward: float  # mean undiscounted episode return


def measure_success(model, env: gym.Env, episodes: int, *, seed: int | None = None,
                    deterministic: bool = True) -> EvalResult:
    """Runs `episodes` episodes of `model` on `env`; `seed` seeds the first reset only, so
    repeated calls on one env see fresh episodes."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    successes, returns = [], []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed if episode == 0 else None)
        done, total = False, 0.0
        info: dict = {}
        while not done:
            action, _ = model.predict(obs, deterministic=deterministic)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            done = terminated or truncated
        successes.append(bool(info.get("is_success", False)))
        returns.append(total)
    return EvalResult(episodes, float(np.mean(successes)), float(np.mean(returns)))
