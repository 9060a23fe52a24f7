"""A trained run's policy played on the episodes `franka-composer evaluate --episodes N
--seed S` plays, through a recorder that keeps one row per episode: the loop the scripts
that split a policy's success by what its episodes asked and did have in common.

Imported by those scripts (experiments/ is not a package; they put it on sys.path).
"""

from __future__ import annotations

import contextlib
import pathlib

import gymnasium as gym
import numpy as np


class EpisodeRecorder(gym.Wrapper):
    """Keeps `row(info)` for each episode played through it, having shown it the reset's
    observation (`begin`) and each step's (`watch`), so that `measure_success` (evaluate's
    own loop) plays the episodes. Subclasses say what to watch."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.rows: list[tuple] = []

    def begin(self, obs: dict) -> None:
        raise NotImplementedError

    def watch(self, obs: dict, action: np.ndarray) -> None:
        raise NotImplementedError

    def row(self, info: dict) -> tuple:
        raise NotImplementedError

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.begin(obs)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.watch(obs, action)
        if terminated or truncated:
            self.rows.append(self.row(info))
        return obs, reward, terminated, truncated, info


def play_recorded(run_root: pathlib.Path, task: str, recorder: type[EpisodeRecorder],
                  episodes: int, seed: int, **options):
    """(the run's config, steps it trained, its recorder's rows as an array) for `episodes`
    deterministic episodes from reset seed `seed`, on the run's env (less what `options`
    give instead); refuses, by name, a run that is not of `task`."""
    from franka_composer.training.evaluation import measure_success
    from franka_composer.training.policy_file import trained_on_its_task
    from franka_composer.training.runs import RunDir

    try:
        config = RunDir(run_root).read_config()
    except ValueError as error:
        raise SystemExit(str(error)) from None
    if config.task != task:
        raise SystemExit(f"{run_root}: a {config.task} run; this reads {task} runs")
    with contextlib.ExitStack() as stack:
        try:  # A run this process cannot build or load is named, not a traceback.
            _, env, model = stack.enter_context(
                trained_on_its_task(run_root, device="cpu", wrap=recorder, **options))
        except ValueError as error:
            raise SystemExit(f"{run_root}: {error}") from None
        measure_success(model, env, episodes, seed=seed)
        return config, int(model.num_timesteps), np.array(env.rows, dtype=float)
