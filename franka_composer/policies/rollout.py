"""Running a policy for whole episodes and keeping what happened, for demos and datasets."""

from __future__ import annotations

import time
from typing import Any, Callable

import dm_env
import numpy as np

from franka_composer.episodes import STEP_KEYS, Trajectories
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.tasks.options import OPTIONS, readable_options
from franka_composer.validation import check_number


def check_episodes_end(env) -> None:
    """A ValueError if episodes of the Gymnasium `env` end only on success (no `TimeLimit`:
    gym.make(id, max_episode_steps=-1), and no time limit of its own: time_limit=None):
    running one to its end could then never return."""
    if episode_limit(env) is None:
        raise ValueError("episodes of this env end only on success (no max_episode_steps and "
                         "time_limit=None): give gym.make a max_episode_steps to run whole "
                         "episodes")


def rollout(env, policy, episodes: int, seed: int | None = None,
            on_step: Callable[[Any, int], None] | None = None,
            on_episode_end: Callable[[int], None] | None = None) -> Trajectories:
    """Runs `policy` (obs -> action; its `reset()` is called at each episode start if it has
    one) for `episodes` episodes of the Gymnasium `env`, each until terminated or truncated.

    Episode i is reset with `seed + i` when `seed` is given. `on_step(env, i)` is called after
    every reset and step of episode i (e.g. to render a frame) and `on_episode_end(i)` when it
    ends (e.g. to advance a progress bar); neither counts in `env_seconds`. Episodes that
    end where the physics diverged are kept, and named in the result's `diverged`.
    """
    check_number("episodes", episodes, minimum=1, integer=True)
    if not callable(policy):
        raise ValueError(f"policy must be a callable from an observation to an action "
                         f"(make_expert(env), a trained policy), got {policy!r}")
    if isinstance(env, dm_env.Environment):
        raise ValueError("rollout runs a Gymnasium env (gym.make(id), or Shimmy's "
                         "DmControlCompatibilityV0 around a dm_env); a dm_env steps with "
                         "timesteps, not (obs, reward, terminated, truncated, info)")
    check_episodes_end(env)
    collected, diverged, env_seconds = [], [], 0.0
    for index in range(episodes):
        if hasattr(policy, "reset"):
            policy.reset()
        start = time.perf_counter()
        obs, _ = env.reset(seed=None if seed is None else seed + index)
        env_seconds += time.perf_counter() - start
        if on_step is not None:
            on_step(env, index)
        observations = [obs]
        steps: dict[str, list] = {key: [] for key in STEP_KEYS}
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
        if info.get("diverged"):
            diverged.append(index)
        if on_episode_end is not None:
            on_episode_end(index)
    return Trajectories(collected, env_seconds, metadata=recorded_with(env), diverged=diverged)


def recorded_with(env) -> dict:
    """What episodes of the Gymnasium `env` were recorded with, as a dataset says it
    (`episodes.npz_file`): the id of its task, controller and reward (whose version says
    which dynamics), them, the steps at which an episode is cut (`max_episode_steps`, as a
    Minari env spec keeps it) and the task options whose values differ from the task's own;
    {} for an env of another package."""
    from franka_composer.adapters.registration import env_id

    task = getattr(getattr(env, "unwrapped", env), "task", None)
    if task is None or getattr(task, "config", None) is None:
        return {}
    config, own = task.config, TASK_CONFIGS[task.config.name]
    options = {name: value for name, value in config.options.items()
               if name not in ("control", "reward_type") and value != OPTIONS[name].get(own)}
    return {"id": env_id(config.name, config.reward_type, config.control.kind),
            "task": config.name, "control": config.control.kind,
            "reward_type": config.reward_type, "max_episode_steps": episode_limit(env),
            "options": readable_options(options)}


def episode_limit(env) -> int | None:
    """The steps after which an episode of the Gymnasium `env` is cut (truncated): its
    `TimeLimit`'s or its own time limit's, the fewer; None where it has neither."""
    spec = getattr(env, "spec", None)
    composer_env = getattr(getattr(env, "unwrapped", env), "composer_env", None)
    limits = [limit for limit in (getattr(spec, "max_episode_steps", None),
                                  getattr(composer_env, "episode_steps", None))
              if limit is not None]
    return min(limits, default=None)
