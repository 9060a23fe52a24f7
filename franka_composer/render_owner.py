"""Which thread renders an environment, so that rendering from another one fails clearly.

dm_control keeps an environment's GL context current on the thread that first rendered
with it (EGL's executor renders on the calling thread), and a context current on one thread
cannot be made current on another: a render, or a step of a pixel environment, from a
second thread fails deep inside dm_control or EGL. `claim` raises `RenderThreadError`
instead, before anything is stepped; `release` lets `close()` run on any thread. An
environment inherited over a fork makes new GL contexts in the child (`gl_fork`).
"""

from __future__ import annotations

import os
import threading
import weakref

from franka_composer import headless_gl
from franka_composer.signals import held

# environment -> (process id, thread) of the thread that renders it.
_OWNERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
# environment -> what sets its contexts aside if it is collected unclosed.
_FINALIZERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class RenderThreadError(RuntimeError):
    """A render or pixel step from a thread other than the one that renders the env."""


def claim(environment) -> None:
    """Makes this thread the one that renders `environment`, or raises `RenderThreadError` if
    another thread of this process already does (`HeadlessGLError` if it cannot render at
    all). A forked child starts afresh: the GL state it inherited is its parent's
    (`gl_fork`)."""
    here = threading.current_thread()
    owner = _OWNERS.get(environment)
    if owner is None or owner[0] != os.getpid():
        headless_gl.check_can_render()  # Before its first render in this process.
        if owner is not None:  # Rendered before this process was forked from its parent.
            _abandon_contexts(environment.physics)
        _OWNERS[environment] = (os.getpid(), here)
        # Dropped without close(), it is freed wherever the collector or the interpreter's
        # exit runs: there its contexts are set aside as `release` sets them aside (freed
        # from another thread, dm_control printed EGL errors, in collection and at exit).
        _FINALIZERS[environment] = weakref.finalize(
            environment, _set_aside_elsewhere, environment.physics, os.getpid(), here)
        # Made whole or not begun: Ctrl-C while dm_control made them left a context without
        # its pointer, and a stopped demo printed "Exception ignored in MjrContext.__del__"
        # after its own message.
        with held():
            environment.physics.contexts  # noqa: B018 (Makes them.)
    elif owner[1] is not here:
        raise RenderThreadError(
            f"this environment renders on thread {owner[1].name!r}, which rendered it first "
            f"(its GL context is current there), and cannot render or step its camera "
            f"observations on thread {here.name!r}: call render(), reset() and step() from "
            "that thread, or make one environment per thread (close() works from any thread)")


def release(environment, physics) -> None:
    """Prepares freeing `environment`'s `physics` on the calling thread: a GL context
    current on another thread (or the parent's, after a fork) cannot be made current here to
    be freed, so it is set aside until the process exits; the physics itself is freed."""
    owner = _OWNERS.pop(environment, None)
    finalizer = _FINALIZERS.pop(environment, None)
    if finalizer is not None:
        finalizer.detach()  # Closed: nothing is left to set aside when it is collected.
    if owner is None or (owner[0] == os.getpid() and owner[1] is threading.current_thread()):
        return
    _abandon_contexts(physics)


def _set_aside_elsewhere(physics, process: int, thread: threading.Thread) -> None:
    """Sets aside `physics`'s GL contexts unless this is the `thread` of `process` that
    made them current: the finalizer of an environment `claim` saw render."""
    if process != os.getpid() or threading.current_thread() is not thread:
        _abandon_contexts(physics)


# GL contexts this process must not free: current on another thread, or inherited over a
# fork (their driver state is the parent's). Kept, untouched, until the process exits:
# freeing them would run GL calls on whatever context is current on the freeing thread.
_ABANDONED: list = []


def _abandon_contexts(physics) -> None:
    """Detaches `physics`'s GL contexts, if it made any, so that it makes new ones."""
    contexts = getattr(physics, "_contexts", None)  # Never `physics.contexts`: it makes them.
    if contexts is not None:
        # A terminated executor makes dm_control skip every GL call of freeing them (in
        # garbage collection and at exit too).
        contexts.gl._render_executor.terminate()  # pylint: disable=protected-access
        _ABANDONED.append(contexts)
        physics._contexts = None  # pylint: disable=protected-access
