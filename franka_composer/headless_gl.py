"""Headless OpenGL by default: `MUJOCO_GL=egl` where there is no display.

dm_control picks its GL backend from `MUJOCO_GL` once, when it is first imported, and without
a display its default (GLFW) cannot render. So importing franka_composer, which imports
dm_control, first sets `MUJOCO_GL=egl` (a GPU's EGL, or Mesa's software EGL) when neither the
user nor a display has chosen: frames render headless out of the box. A `MUJOCO_GL`,
`DISPLAY` or `WAYLAND_DISPLAY` the user set is left alone (`osmesa` with Debian's
`libosmesa6` where EGL is missing). dm_control's EGL backend opens its display at import,
~55 MB in every process (docs/guide/benchmarks.md); a process that never renders can avoid
it with `MUJOCO_GL=disable`. Where dm_control was imported first (shimmy imports it), or
the user chose GLFW, without a display or with one GLFW cannot open, the first render
raises `HeadlessGLError` saying so (`check_can_render`), rather than failing inside
dm_control's GL calls.
"""

from __future__ import annotations

import os
import sys


def choose_headless_backend() -> None:
    """Sets `MUJOCO_GL=egl` without a display or a user's choice; call before dm_control is
    imported (it reads `MUJOCO_GL` once)."""
    if "MUJOCO_GL" in os.environ or "dm_control._render" in sys.modules:
        return  # The user chose, or dm_control already has.
    if has_display():
        return
    os.environ["MUJOCO_GL"] = "egl"


#: The MUJOCO_GL values with which dm_control renders nothing
#: (`dm_control._render.constants.NO_RENDERER`, read here without importing dm_control's
#: renderer, which would open its display).
NO_RENDERER = ("off", "disable", "disabled", "false", "0")


class HeadlessGLError(RuntimeError):
    """dm_control renders through GLFW in a process without a display."""


def check_can_render() -> None:
    """A `HeadlessGLError` where rendering is off (`MUJOCO_GL=disable` or another of
    `NO_RENDERER`: dm_control's "No OpenGL rendering backend is available" from deep
    inside), or dm_control renders through GLFW and there is no display, or one GLFW could
    not open (its GL calls would fail inside: MjrContext has no _ptr, or MuJoCo's "an
    OpenGL platform library has not been loaded")."""
    chosen = os.environ.get("MUJOCO_GL", "")
    if chosen.lower() in NO_RENDERER:
        raise HeadlessGLError(
            f"this process cannot render: MUJOCO_GL={chosen} turns rendering off. Unset it "
            "(or set egl or osmesa) before Python starts, or do not render: "
            "render_mode=None, observation_mode='state', demo --no-video")
    render = sys.modules.get("dm_control._render")
    if getattr(render, "BACKEND", None) != "glfw":
        return
    if has_display():
        if glfw_opens_the_display():
            return
        raise HeadlessGLError(
            f"this process cannot render: dm_control renders through GLFW here, and GLFW "
            f"{display_not_opened()}. Unset it, or set MUJOCO_GL=egl (or osmesa) before "
            "Python starts for headless frames")
    if os.environ.get("MUJOCO_GL") == "glfw":
        why = "MUJOCO_GL=glfw, which needs a display"
    else:
        why = ("dm_control was imported before franka_composer (shimmy imports it, for one) "
               "with MUJOCO_GL unset, so it took GLFW, which needs a display")
    raise HeadlessGLError(
        f"this process cannot render: {why}, and it has none (no DISPLAY or "
        "WAYLAND_DISPLAY). Import franka_composer before dm_control and shimmy, or set "
        "MUJOCO_GL=egl (or osmesa) before Python starts")


#: Where X and Wayland clients find their display.
DISPLAY_VARIABLES = ("DISPLAY", "WAYLAND_DISPLAY")


def has_display() -> bool:
    """Whether an X or Wayland display is set for this process."""
    return any(os.environ.get(name) for name in DISPLAY_VARIABLES)


def display_not_opened() -> str:
    """What a GLFW that could not open the display set for this process says of it."""
    named = " and ".join(f"{name}={os.environ[name]}" for name in DISPLAY_VARIABLES
                         if os.environ.get(name))
    wayland_only = not os.environ.get("DISPLAY")
    return (f"cannot open the display {named} (none there, or not this user's"
            + ("; pyglfw speaks Wayland only with PYGLFW_LIBRARY_VARIANT=wayland or "
               "XDG_SESSION_TYPE=wayland" if wayland_only else "") + ")")


def glfw_opens_the_display() -> bool:
    """Whether GLFW is initialised: dm_control initialises it on import, and where the
    display cannot be opened that failed with only a warning, and every GL call after it
    fails inside MuJoCo ("an OpenGL platform library has not been loaded")."""
    import warnings

    import glfw

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # The failure's warning, printed once already.
        try:
            return bool(glfw.init())  # At once where initialised; else tries again.
        except glfw.GLFWError:  # Where the user set glfw.ERROR_REPORTING to raise.
            return False
