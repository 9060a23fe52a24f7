"""The package ships `py.typed`: its hints are what its users' type checkers read. mypy
checks the package and a user's program written against its public interfaces; a hint that
refuses correct code, or that the code does not keep, fails here."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: What a user writes: the Gymnasium ids with an expert, the dm_env suite, recorded
#: rollouts with their callbacks, a policy over any mapping of observations.
USER_PROGRAM = """
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

import franka_composer
from franka_composer.policies import Expert, Trajectories, make_expert, rollout

seen: list[int] = []
ended: list[int] = []


def on_step(env: gym.Env, index: int) -> None:
    seen.append(index)


def still(obs: Mapping[str, Any]) -> np.ndarray:
    return np.zeros(4, dtype=np.float32)


env = gym.make("FrankaPickAndPlaceSparse-v0", max_episode_steps=5)
expert: Expert = make_expert(env)
obs, info = env.reset(seed=0)
action: np.ndarray = expert(obs)
recorded: Trajectories = rollout(env, expert, 2, seed=0, on_step=on_step,
                                 on_episode_end=ended.append)
rollout(env, still, 1)
goal_env = env.unwrapped
assert isinstance(goal_env, franka_composer.FrankaGoalEnv)
rewards = goal_env.compute_reward(np.zeros((2, 3)), np.ones((2, 3)), {})
composer_env = franka_composer.load("push", seed=np.random.RandomState(0), time_limit=None)
timestep = composer_env.reset()
assert composer_env.episode_steps is None and "FrankaPushSparse-v0" in franka_composer.ENV_IDS
assert seen and ended == [0, 1] and list(rewards) == [-1.0, -1.0]
"""


@pytest.mark.slow
def test_mypy_finds_no_error_in_the_package_or_a_users_program(tmp_path):
    program = tmp_path / "users_program.py"
    program.write_text(USER_PROGRAM)
    ran = subprocess.run([sys.executable, str(program)], capture_output=True, text=True,
                         timeout=300)
    assert ran.returncode == 0, ran.stderr  # Correct code, which the check must pass.
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "cache"),
         "franka_composer", str(program)],
        cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.startswith("Success: no issues found in "), result.stdout
