"""Signals that stop a training process the way Ctrl-C does, so what is running checkpoints:
at once (`interrupt_on`), or where it is ready to (`stop_requests`).

`kill PID` (SIGTERM) is how schedulers, `timeout` and Ray stop a process, and a job started
in the background ignores SIGINT (the shell sets it to SIG_IGN), so neither would otherwise
reach the KeyboardInterrupt path that saves a checkpoint.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

#: How often an interrupt not seen on its way out is raised again.
_AGAIN_S = 0.05
#: What `held` holds: the stop signals and the interrupt's repeat.
_HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)


@contextlib.contextmanager
def _handled(handler, signums):
    """Inside the block `handler` receives each of `signums`; their handlers restored after.

    Python drops an exception raised where it cannot pass it on: in a garbage collector's
    callback (jax adds one) or a finalizer it prints "Exception ignored", and C code that
    looks a value up (a dict, an attribute) can clear it unseen. A stopped rollout recorded
    on. So once `handler` has raised KeyboardInterrupt, it is raised again every `_AGAIN_S`
    (SIGALRM) wherever none is on its way out (its cleanup runs undisturbed), until the
    block ends; Python's message for one it dropped is left out."""
    raised = []
    previous_hook = sys.unraisablehook

    def raising(signum, frame):
        try:
            handler(signum, frame)
        except KeyboardInterrupt as interrupt:
            if not raised:
                raised.append(interrupt)
                signal.setitimer(signal.ITIMER_REAL, _AGAIN_S, _AGAIN_S)
            raise

    def again(signum, frame):
        if raised and not _interrupt_in_flight():
            raise raised[0].with_traceback(None)

    def hook(unraisable):
        if not (raised and isinstance(unraisable.exc_value, KeyboardInterrupt)):
            previous_hook(unraisable)

    # SIGALRM restored last: restoring the others first acts on a repeat still pending.
    previous = {signum: signal.signal(signum, raising) for signum in signums}
    previous[signal.SIGALRM] = signal.signal(signal.SIGALRM, again)
    sys.unraisablehook = hook
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        sys.unraisablehook = previous_hook
        for signum, action in previous.items():
            signal.signal(signum, action)


def _interrupt_in_flight() -> bool:
    """Whether a KeyboardInterrupt is on its way out (what runs is its cleanup)."""
    return isinstance(sys.exc_info()[1], KeyboardInterrupt)


@contextlib.contextmanager
def held():
    """Inside the block Ctrl-C, SIGTERM and an interrupt's repeat are held, and delivered as
    it ends to the handlers there were: for code that an exception raised inside leaves
    broken (jaxlib's import, interrupted, crashed the interpreter). Python runs handlers in
    its main thread only: in another, nothing to hold."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    previous = {signum: signal.signal(signum, lambda signum, frame: received.append(signum))
                for signum in _HELD}
    try:
        yield
    finally:
        for signum, action in previous.items():
            signal.signal(signum, action)
        for signum in dict.fromkeys(received):
            signal.raise_signal(signum)


def jax_imported() -> None:
    """Imports jax with the stop signals held (`held`), where it is not imported yet: jaxlib's
    import, interrupted inside its extension, crashed the interpreter or failed as an
    ImportError. A missing jax is left to the import that needs it to say."""
    if "jax" in sys.modules:
        return
    with held():
        try:
            import jax  # noqa: F401
        except ImportError:
            pass


def interrupt_on(*signums: int):
    """Inside the block each of `signums` raises KeyboardInterrupt; restored after."""
    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    return _handled(handler, signums)


def stop_requests(request, *signums: int):
    """Inside the block the first of `signums` calls `request()`, so that what runs can stop
    where it is ready to (a training run: at its episode's end, where its checkpoint
    resumes exactly); a second raises KeyboardInterrupt at once. Restored after."""
    received = []

    def handler(signum, frame):
        if received:
            raise KeyboardInterrupt(f"signal {signum}, again")
        received.append(signum)
        request()

    return _handled(handler, signums)
