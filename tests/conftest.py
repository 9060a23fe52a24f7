"""Test set-up: Menagerie from ../shared/menagerie when offline, one thread. Headless GL is
left to the package (EGL, loaded at the first frame), so the tests run the users' default."""

from __future__ import annotations

import os
import pathlib

_REPO = pathlib.Path(__file__).resolve().parents[1]
_SHARED_MENAGERIE = _REPO.parent / "shared" / "menagerie"
if "MENAGERIE_ROOT" not in os.environ and _SHARED_MENAGERIE.is_dir():
    os.environ["MENAGERIE_ROOT"] = str(_SHARED_MENAGERIE)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import franka_composer  # noqa: E402
from franka_composer import fast_path  # noqa: E402


@pytest.fixture(params=franka_composer.ALL_TASKS)
def task_name(request) -> str:
    """Every registered task: a new task is tested the day it is added."""
    return request.param


@pytest.fixture(params=["fast", "stock"])
def composer_path(request, monkeypatch) -> str:
    """Runs a test on the fast path and on Composer's stock stepping (modules that use it:
    `pytestmark = pytest.mark.usefixtures("composer_path")`)."""
    monkeypatch.setenv(fast_path.ENV_VARIABLE, "1" if request.param == "fast" else "0")
    return request.param


def move_tcp_to(env, timestep, target, gripper=None, max_steps=30, tolerance=0.004):
    """Drives the tool centre point to `target` with proportional actions; returns the last
    timestep. Used by physical tests that need the hand somewhere first."""
    size = env.action_spec().shape[0]
    control = env.task.config.control
    for _ in range(max_steps):
        tcp = timestep.observation["panda/tcp_position"]
        if np.linalg.norm(np.asarray(target) - tcp) < tolerance:
            break
        action = np.zeros(size, np.float32)
        action[:3] = np.clip(control.tcp_action(tcp, target, max_speed=np.inf), -1, 1)
        if gripper is not None:
            action[3] = gripper
        timestep = env.step(action)
    return timestep


def grasp_block(env):
    """Resets `env` (pick and place) and grasps its block; returns the last timestep."""
    timestep = env.reset()
    block = timestep.observation["block/position"].copy()
    timestep = move_tcp_to(env, timestep, block + [0, 0, 0.08], gripper=1)
    timestep = move_tcp_to(env, timestep, block, gripper=1)
    for _ in range(4):
        timestep = env.step(np.array([0, 0, 0, -1], np.float32))
    return timestep
