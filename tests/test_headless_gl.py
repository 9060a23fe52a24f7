"""Headless GL: `MUJOCO_GL=egl` without a display, and a backend the user chose is kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow  # Fresh processes.

_PROBE = """
import json, os
import gymnasium as gym
import franka_composer
size = {{}} if {render_mode!r} is None else {{"width": 64, "height": 64}}
env = gym.make("FrankaPushSparse-v0", render_mode={render_mode!r}, **size)
env.reset(seed=0)
env.step(env.action_space.sample())
frame = env.render()
print(json.dumps({{"mujoco_gl": os.environ.get("MUJOCO_GL"),
                  "frame_std": None if frame is None else float(frame.std())}}))
"""


def _probe(render_mode, **environment: str) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    env.update(environment)
    result = subprocess.run([sys.executable, "-c", _PROBE.format(render_mode=render_mode)],
                            env=env, capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_without_a_display_frames_render_headless_through_egl():
    probe = _probe("rgb_array")
    assert probe["mujoco_gl"] == "egl" and probe["frame_std"] > 1.0


def test_a_backend_the_user_chose_is_kept():
    """`MUJOCO_GL=disable` spares a process that never renders dm_control's EGL backend."""
    probe = _probe(None, MUJOCO_GL="disable")
    assert probe == {"mujoco_gl": "disable", "frame_std": None}


#: A render, then a pixel env's reset, each printing the HeadlessGLError it raises.
_RENDER_TWICE = """
import gymnasium as gym
import franka_composer
from franka_composer.headless_gl import HeadlessGLError
for options in ({"render_mode": "rgb_array", "width": 64, "height": 64},
                {"observation_mode": "pixels"}):
    env = gym.make("FrankaPushSparse-v0", **options)
    try:
        env.reset(seed=0)
        env.render()
    except HeadlessGLError as error:
        print(error)
    env.close()
"""
_GLFW_WITHOUT_A_DISPLAY = ("import dm_control.composer  # Before franka_composer, as shimmy "
                           "does, with MUJOCO_GL unset." + _RENDER_TWICE)


def _printed_errors(script: str, env: dict) -> list[str]:
    """The lines `script` printed, run in a fresh Python with `env`, which must succeed."""
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout.splitlines()


@pytest.mark.parametrize("mujoco_gl, why", [
    (None, "dm_control was imported before franka_composer (shimmy imports it, for one) "
           "with MUJOCO_GL unset, so it took GLFW, which needs a display"),
    ("glfw", "MUJOCO_GL=glfw, which needs a display")])
def test_glfw_without_a_display_is_refused_at_the_first_render_saying_why(mujoco_gl, why):
    """Not an AttributeError from inside dm_control's GL calls."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    if mujoco_gl:
        env["MUJOCO_GL"] = mujoco_gl
    message = (f"this process cannot render: {why}, and it has none (no DISPLAY or "
               "WAYLAND_DISPLAY). Import franka_composer before dm_control and shimmy, or set "
               "MUJOCO_GL=egl (or osmesa) before Python starts")
    # A render; a pixel reset.
    assert _printed_errors(_GLFW_WITHOUT_A_DISPLAY, env) == [message, message]


@pytest.mark.parametrize("mujoco_gl", [None, "glfw"])
def test_a_display_glfw_cannot_open_is_refused_at_the_first_render_naming_it(mujoco_gl):
    """A DISPLAY left over (ssh, a container) with no X server behind it: dm_control's GLFW
    failed to initialise with a warning, and the render with MuJoCo's FatalError."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")}
    env["DISPLAY"] = ":987"  # No X server's socket there.
    if mujoco_gl:
        env["MUJOCO_GL"] = mujoco_gl
    message = ("this process cannot render: dm_control renders through GLFW here, and GLFW "
               "cannot open the display DISPLAY=:987 (none there, or not this user's). Unset "
               "it, or set MUJOCO_GL=egl (or osmesa) before Python starts for headless frames")
    assert _printed_errors(_RENDER_TWICE, env) == [message, message]


_HUMAN_VIEWER = """
import gymnasium as gym
import franka_composer
from franka_composer.headless_gl import HeadlessGLError
try:
    gym.make("FrankaPushSparse-v0", render_mode="human")
except HeadlessGLError as error:
    print(error)
"""


@pytest.mark.parametrize("mujoco_gl", ["egl", "osmesa"])
def test_a_human_viewer_on_a_display_glfw_cannot_open_is_refused_at_make_naming_it(mujoco_gl):
    """Gymnasium's viewer asked GLFW for the monitor's video mode and C's assertion aborted
    the process (SIGABRT, no Python exception) at the first reset."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "PYOPENGL_PLATFORM")}
    env.update(DISPLAY=":987", MUJOCO_GL=mujoco_gl)  # No X server's socket there.
    assert _printed_errors(_HUMAN_VIEWER, env) == [
        "render_mode='human' opens a window, and GLFW cannot open the display DISPLAY=:987 "
        "(none there, or not this user's): use render_mode='rgb_array' for headless frames, "
        "or set DISPLAY to a display you can open"]


@pytest.mark.parametrize("off", ["disable", "off"])  # Two of dm_control's spellings.
def test_rendering_with_rendering_turned_off_is_refused_saying_so(off, tmp_path):
    """dm_control's "No OpenGL rendering backend is available" came from deep inside, and
    demo printed it as a traceback after making its folder."""
    env = {**os.environ, "MUJOCO_GL": off}
    message = (f"this process cannot render: MUJOCO_GL={off} turns rendering off. Unset it "
               "(or set egl or osmesa) before Python starts, or do not render: "
               "render_mode=None, observation_mode='state', demo --no-video")
    assert _printed_errors(_RENDER_TWICE, env) == [message, message]
    demo = subprocess.run([sys.executable, "-m", "franka_composer", "demo", "--tasks", "reach",
                           "--episodes", "1", "--out", "never-made"], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=120, check=False)
    assert (demo.returncode, demo.stderr) == (1, f"franka-composer: error: {message}\n")
    assert not (tmp_path / "never-made").exists()
