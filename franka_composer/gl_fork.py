"""GL state of its own in every process, so that forked workers render instead of hanging.

Mesa's software GL (llvmpipe, behind both EGL and OSMesa here) starts its render threads
at the first GL context of a process. A forked child inherits the driver's state but not
those threads, and its first render waits for them forever (Gymnasium's async vector env
forks by default on Linux; SB3's `SubprocVecEnv` with `start_method="fork"`). Three cases:

- EGL: the driver's state belongs to an EGL display, so a child whose parent made contexts
  on dm_control's display opens a display of its own (same device) when it first makes a
  context. Processes that never render open nothing.
- OSMesa has one state per process and no way to start another: a child of a process that
  made an OSMesa context raises `ForkedGLError` at its first render, saying what to do.
- A GPU's own EGL (NVIDIA's) cannot make contexts in any forked child of a process that
  initialised it, and dm_control initialises it on import: measured on an H100 and an H200,
  the child's `eglCreateContext` fails with EGL_BAD_ALLOC, and a Gymnasium fork worker never
  answers. Every forked child on an EGL other than Mesa's raises `ForkedGLError` at its
  first render, before any EGL call.

In every case a forked child never frees what it inherited (dm_control would, in garbage
collection and at exit, and wait for the parent's threads): an at-fork hook disowns the
inherited contexts, without a GL call.

With OSMesa, whose calls go to a thread of a `concurrent.futures` pool, a process frees its
own contexts at exit before Python stops its thread pools: dm_control frees them in an
`atexit` callback, which runs after that, and every script that rendered printed three
tracebacks as it ended ("cannot schedule new futures after shutdown"). (A thread still
rendering under OSMesa as the main thread ends could not render on either way: its calls
go to the pool Python stops.) EGL calls on the calling thread, and is left as it was.

`install()` puts these contexts in the place of dm_control's (`dm_control._render.Renderer`,
which `Physics` makes its contexts from) and registers the hook; other backends (GLFW with
a display) are left as they are.
"""

from __future__ import annotations

import atexit
import ctypes
import os
import threading
import weakref

#: EGL_PLATFORM_SURFACELESS_MESA: a display of Mesa's without any device or window system.
_PLATFORM_SURFACELESS = 0x31DD


class ForkedGLError(RuntimeError):
    """A forked process cannot render: its parent's GL driver state cannot be replaced."""


_SPAWN_ADVICE = ("start the workers with spawn or forkserver (gym.make_vec(..., "
                 "vectorization_mode='async', vector_kwargs={'context': 'spawn'}); "
                 "SubprocVecEnv(..., start_method='spawn'))")


def install() -> None:
    """Puts the process-aware contexts in the place of dm_control's; harmless to repeat."""
    from dm_control import _render

    if getattr(_render.Renderer, "process_aware", False):
        return
    if _render.BACKEND == "egl":
        global _egl_driver
        _egl_driver = (os.getpid(), _egl_vendor())
        _render.Renderer = _process_egl_context(_render.Renderer)
    elif _render.BACKEND == "osmesa":
        _render.Renderer = _process_osmesa_context(_render.Renderer)
        # Threading's exit hooks run in the reverse order of registration, atexit's after
        # them: the thread pools' hook (registered on the pools' module's first import,
        # which dm_control leaves to its first context) goes first, to run after this one.
        import concurrent.futures.thread  # pylint: disable=unused-import,import-outside-toplevel

        # (Threading's private hook: no public one runs before the pools'.)
        getattr(threading, "_register_atexit")(_free_contexts_at_exit)
    else:
        return
    os.register_at_fork(after_in_child=_forget_inherited_gl)


def _free_contexts_at_exit() -> None:
    """What dm_control's atexit callback does for each context, while the pool thread its
    calls run on still takes work."""
    for context in list(_CONTEXTS):
        try:
            context._free_unconditionally()  # pylint: disable=protected-access
        except Exception:  # pylint: disable=broad-except
            pass  # Left to dm_control's own atexit, as before; the others are still freed.


# The process-aware contexts alive in this process (a forked child's are its parent's).
_CONTEXTS: weakref.WeakSet = weakref.WeakSet()


def _forget_inherited_gl() -> None:
    """In a forked child, before anything else runs: the inherited contexts and displays
    hold the parent's driver state, so the child must never free them (dm_control would, in
    garbage collection and at exit, and wait forever for the parent's render threads)."""
    for context in list(_CONTEXTS):
        # A terminated executor makes dm_control skip every GL call for the context. The
        # flag is set, not `terminate()` called: that takes the executor's lock, which a
        # thread of the parent may have held at the fork.
        context._render_executor._terminated = True  # pylint: disable=protected-access
    _CONTEXTS.clear()
    if _DISPLAY_USERS:  # An ancestor rendered with EGL: its display's threads are gone.
        egl, _ = _egl()
        atexit.unregister(egl.eglTerminate)  # dm_control's, for its display, at exit.


#: The EGL whose forked children can render, with displays of their own (`EGL_VENDOR`).
FORK_SAFE_EGL_VENDOR = "Mesa Project"

# (id of the process that initialised dm_control's EGL display, the driver's EGL_VENDOR); a
# forked child inherits it, and with it which driver its ancestor started.
_egl_driver: tuple[int, str] | None = None


def _egl_vendor() -> str:
    egl, renderer = _egl()
    return (egl.eglQueryString(renderer.EGL_DISPLAY, egl.EGL_VENDOR) or b"").decode()


def forked_children_render() -> bool:
    """False where this process runs a GPU's own EGL, whose forked children are refused.
    (With OSMesa, children of a process that rendered are refused; GLFW on a display is left
    as dm_control has it.)"""
    return _egl_driver is None or _egl_driver[1] == FORK_SAFE_EGL_VENDOR


def _refuse_an_inherited_gpu_driver() -> None:
    assert _egl_driver is not None  # Registered where `install` set it.
    parent, vendor = _egl_driver
    if parent != os.getpid() and vendor != FORK_SAFE_EGL_VENDOR:
        raise ForkedGLError(
            f"this process ({os.getpid()}) was forked from process {parent}, where the EGL "
            f"driver of {vendor!r} had been initialised (dm_control opens its display on "
            "import), and that driver cannot make GL contexts in a forked child (its "
            f"eglCreateContext fails, or the render never returns): {_SPAWN_ADVICE}")


def _process_egl_context(egl_context):
    class ProcessEGLContext(egl_context):
        """dm_control's EGL context, made on an EGL display of this process."""

        process_aware = True

        def __init__(self, *args, **kwargs):
            _refuse_an_inherited_gpu_driver()
            super().__init__(*args, **kwargs)
            _CONTEXTS.add(self)

        def _platform_init(self, max_width, max_height):
            _display_for_this_process()
            super()._platform_init(max_width, max_height)

        def _free_unconditionally(self):
            if _was_made(self):
                super()._free_unconditionally()

    return ProcessEGLContext


# Id of the first process that made an OSMesa context; a forked child inherits it.
_osmesa_process: int | None = None


def _process_osmesa_context(osmesa_context):
    class ProcessOSMesaContext(osmesa_context):
        """dm_control's OSMesa context, refused in a child of a process that rendered."""

        process_aware = True

        def __init__(self, *args, **kwargs):
            global _osmesa_process
            if _osmesa_process not in (None, os.getpid()):
                raise ForkedGLError(
                    f"MUJOCO_GL=osmesa cannot render in this process ({os.getpid()}): it was "
                    f"forked from process {_osmesa_process}, which had already rendered, and "
                    "OSMesa's render threads stayed there (the render would wait for them "
                    f"forever). Use MUJOCO_GL=egl (a forked child opens its own display), or "
                    f"{_SPAWN_ADVICE}")
            _osmesa_process = os.getpid()
            super().__init__(*args, **kwargs)
            _CONTEXTS.add(self)

        def _free_unconditionally(self):
            if _was_made(self):
                super()._free_unconditionally()

    return ProcessOSMesaContext


def _was_made(context) -> bool:
    """Whether dm_control made `context`: one refused (`ForkedGLError`) holds nothing to
    free, and its `__del__` found no executor."""
    return "_render_executor" in vars(context)


def _egl():
    from dm_control._render.pyopengl import egl_ext, egl_renderer

    return egl_ext, egl_renderer


def _address(handle) -> int:
    return ctypes.cast(handle, ctypes.c_void_p).value or 0


# EGL display address -> id of the first process that made a context on it. A forked child
# inherits this record, and with it which displays hold its ancestors' render threads.
_DISPLAY_USERS: dict[int, int] = {}


def _display_for_this_process():
    """An initialised EGL display on which no other process made contexts: dm_control's
    where possible, else a fresh one of the same device (or Mesa's surfaceless platform),
    which becomes dm_control's for every later context of this process."""
    egl, renderer = _egl()
    pid = os.getpid()
    current = renderer.EGL_DISPLAY
    if _DISPLAY_USERS.setdefault(_address(current), pid) == pid:
        return current
    for display in _fresh_displays(egl, current):
        if not _address(display) or _address(display) in _DISPLAY_USERS:
            continue
        if _initialize(egl, display):
            _DISPLAY_USERS[_address(display)] = pid
            renderer.EGL_DISPLAY = display  # Where dm_control's EGL contexts look it up.
            return display
    raise ForkedGLError(
        f"this process ({pid}) was forked from one that had rendered with EGL, and no EGL "
        "display of its own is left to open (each forked generation that renders takes "
        f"one, and Mesa offers four): {_SPAWN_ADVICE}")


def _initialize(egl, display) -> bool:
    from OpenGL import error

    try:
        return bool(egl.eglInitialize(display, None, None))
    except error.GLError:  # PyOpenGL may raise where EGL returns EGL_FALSE.
        return False


def _fresh_displays(egl, current):
    """Candidate displays besides `current`: its device's with an explicit empty attribute
    list (Mesa keeps one display per attribute list), then Mesa's surfaceless ones."""
    from OpenGL import error

    no_attributes = (ctypes.c_int * 1)(egl.EGL_NONE)
    candidates = [(_PLATFORM_SURFACELESS, None, None),
                  (_PLATFORM_SURFACELESS, None, no_attributes)]
    for device in egl.eglQueryDevicesEXT():
        display = egl.eglGetPlatformDisplayEXT(egl.EGL_PLATFORM_DEVICE_EXT, device, None)
        if _address(display) == _address(current):
            candidates.insert(0, (egl.EGL_PLATFORM_DEVICE_EXT, device, no_attributes))
    for platform, native, attributes in candidates:
        try:
            yield egl.eglGetPlatformDisplayEXT(platform, native, attributes)
        except error.GLError:  # A platform this EGL lacks.
            continue
