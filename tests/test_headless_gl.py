"""Headless GL: EGL is chosen at import and loaded at the first frame, unless the user chose."""

from __future__ import annotations

import json
import os
import subprocess
import sys


_PROBE = """
import json, os, sys
import gymnasium as gym
import franka_composer
EGL = "dm_control._render.pyopengl.egl_renderer"
env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array", width=64, height=64)
env.reset(seed=0)
env.step(env.action_space.sample())
before = EGL in sys.modules
frame = env.render()
dm_env = franka_composer.load("slide")
dm_env.reset()
dm_env_frame = dm_env.physics.render(32, 32)
print(json.dumps({"loaded_before_render": before, "loaded_after_render": EGL in sys.modules,
                  "mujoco_gl": os.environ.get("MUJOCO_GL"), "frame_std": float(frame.std()),
                  "dm_env_frame_shape": list(dm_env_frame.shape)}))
"""


def _probe(**environment: str) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "DISPLAY", "FRANKA_COMPOSER_CHOSE_MUJOCO_GL")}
    env.update(environment)
    result = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                            text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_without_a_display_egl_is_chosen_and_loaded_only_at_the_first_frame():
    probe = _probe()
    assert probe["mujoco_gl"] == "egl"
    assert not probe["loaded_before_render"]
    assert probe["loaded_after_render"] and probe["frame_std"] > 1.0
    assert probe["dm_env_frame_shape"] == [32, 32, 3]


def test_a_child_of_a_deferring_process_defers_too():
    # What a vector-env worker inherits from a parent that imported franka_composer.
    probe = _probe(MUJOCO_GL="egl", FRANKA_COMPOSER_CHOSE_MUJOCO_GL="1")
    assert not probe["loaded_before_render"] and probe["loaded_after_render"]


def test_a_backend_the_user_chose_is_loaded_as_dm_control_does():
    probe = _probe(MUJOCO_GL="egl")
    assert probe["loaded_before_render"] and probe["frame_std"] > 1.0

