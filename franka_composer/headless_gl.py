"""Headless OpenGL: chosen when the package is imported, loaded at the first frame.

Without a display, dm_control needs `MUJOCO_GL` set before it is imported (else it tries
GLFW and warns), so importing franka_composer sets it to `egl` when the user has not. But
dm_control also loads its backend at import, and its EGL backend opens an EGL display right
then: Mesa's drivers, ~55 MB resident in every process (every vector-env worker), whether
it ever renders or not. So when franka_composer is the one choosing, dm_control's renderer
module is imported with rendering disabled and the EGL backend is loaded by `Physics`
when it makes its first rendering context. MuJoCo itself and child processes see
`MUJOCO_GL=egl` as usual (children that import franka_composer defer again).

A `MUJOCO_GL` or `DISPLAY` the user set is left alone: dm_control then loads what it says,
as usual.
"""

from __future__ import annotations

import os
import sys

#: Marks a `MUJOCO_GL=egl` that franka_composer chose (so child processes defer too).
_CHOSEN_HERE = "FRANKA_COMPOSER_CHOSE_MUJOCO_GL"
_deferred = False


def choose_headless_backend() -> None:
    """Sets `MUJOCO_GL=egl` without a display, deferring dm_control's EGL backend; call
    before dm_control's renderer is imported (it reads `MUJOCO_GL` once)."""
    global _deferred
    ours = os.environ.get(_CHOSEN_HERE) == "1" and os.environ.get("MUJOCO_GL") == "egl"
    if not ours and ("MUJOCO_GL" in os.environ or os.environ.get("DISPLAY")):
        return
    os.environ["MUJOCO_GL"], os.environ[_CHOSEN_HERE] = "egl", "1"
    if "dm_control._render" in sys.modules:
        return  # Imported before us with its own choice: nothing to defer.
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import dm_control._render  # noqa: F401  # pylint: disable=unused-import
    finally:
        os.environ["MUJOCO_GL"] = "egl"
    _deferred = True


def load_deferred_backend() -> None:
    """Loads dm_control's EGL backend if `choose_headless_backend` deferred it."""
    global _deferred
    if not _deferred:
        return
    from dm_control import _render  # pylint: disable=g-import-not-at-top

    _render.Renderer = _render._import_egl()  # pylint: disable=protected-access
    _render.BACKEND, _render.USING_GPU = "egl", True
    _deferred = False

