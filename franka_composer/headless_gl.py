"""Headless OpenGL by default: `MUJOCO_GL=egl` where there is no display.

dm_control picks its GL backend from `MUJOCO_GL` once, when it is first imported, and without
a display its default (GLFW) cannot render. So importing franka_composer, which imports
dm_control, first sets `MUJOCO_GL=egl` (a GPU's EGL, or Mesa's software EGL) when neither the
user nor a display has chosen: frames render headless out of the box. A `MUJOCO_GL`,
`DISPLAY` or `WAYLAND_DISPLAY` the user set is left alone (`osmesa` with Debian's
`libosmesa6` where EGL is missing). dm_control's EGL backend opens its display at import,
~55 MB in every process (docs/guide/benchmarks.md); a process that never renders can avoid
it with `MUJOCO_GL=disable`.
"""

from __future__ import annotations

import os
import sys


def choose_headless_backend() -> None:
    """Sets `MUJOCO_GL=egl` without a display or a user's choice; call before dm_control is
    imported (it reads `MUJOCO_GL` once)."""
    if "MUJOCO_GL" in os.environ or "dm_control._render" in sys.modules:
        return  # The user chose, or dm_control already has.
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    os.environ["MUJOCO_GL"] = "egl"
