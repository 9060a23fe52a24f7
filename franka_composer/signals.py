"""Signals that stop a command the way Ctrl-C does, so that what is running cleans up or
checkpoints: at once (`interrupt_on`), or where it is ready to (`stop_requests`, a training
run at its episode's end); held over code they would break (`held`); and the exit status
of a command they stopped (`exit_status`).

`kill PID` (SIGTERM) is how schedulers, `timeout` and Ray stop a process, and a job started
in the background ignores SIGINT (the shell sets it to SIG_IGN), so neither would otherwise
reach the KeyboardInterrupt path that saves a checkpoint.
"""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import threading

#: How often an interrupt not yet seen on its way out is raised again.
_AGAIN_S = 0.05
#: What `held` holds: the stop signals and an interrupt's repeat.
_HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)


class _Handled:
    """Inside the block `handler` receives each of `signums`; their handlers restored after.

    Python drops an exception raised where it cannot pass it on: in a garbage collector's
    callback (jax adds one) or a finalizer it prints "Exception ignored", and C code that
    looks a value up can clear it unseen; a stopped rollout recorded on. So once `handler`
    has raised KeyboardInterrupt it is raised again every `_AGAIN_S` (SIGALRM, taken only
    then, and given back with its timer as the block ends) until a repeat finds it on its
    way out or being handled, or the block ends (a block that handles it faster and runs
    on gets it again); one Python dropped (its message left out) and not yet raised again
    is raised as the block ends. C code that catches it and raises a bare KeyboardInterrupt
    of its own instead (Ray's wait for its tasks) loses the signal it names: an interrupt
    that names none, leaving a block whose `handler` raised one, is given its arguments, so
    that the command exits with that signal's status (`exit_status`)."""

    def __init__(self, handler, signums) -> None:
        self._handler, self._signums = handler, signums
        self._repeat: tuple | None = None  # The arguments of the interrupt to raise again.
        self._raised: tuple | None = None  # Those of the latest `handler` raised.
        # Those of one Python dropped and no repeat has raised yet.
        self._dropped: tuple | None = None
        # SIGALRM's handler, its timer and the hook the repeat took.
        self._alarm: tuple | None = None
        self._ending = False

    def __enter__(self) -> None:
        self._previous = {signum: signal.signal(signum, self._raising)
                          for signum in self._signums}

    def _raising(self, signum, frame) -> None:
        try:
            self._handler(signum, frame)
        except KeyboardInterrupt as interrupt:
            self._repeat = self._raised = interrupt.args
            if self._alarm is None and not self._ending:
                self._alarm = (signal.signal(signal.SIGALRM, self._again),
                               signal.setitimer(signal.ITIMER_REAL, _AGAIN_S, _AGAIN_S),
                               sys.unraisablehook)
                sys.unraisablehook = self._unraisable
            raise

    def _again(self, signum, frame) -> None:
        if self._repeat is None or frame.f_code is _Handled.__exit__.__code__:
            return  # (At the end of the block: its `__exit__` gives everything back.)
        if _interrupt_in_flight():
            self._repeat = None  # Its cleanup, or its handler, runs undisturbed.
            return
        self._dropped = None
        raise KeyboardInterrupt(*self._repeat)

    def _unraisable(self, unraisable) -> None:
        if self._repeat is not None and isinstance(unraisable.exc_value, KeyboardInterrupt):
            self._dropped = self._repeat
        else:
            assert self._alarm is not None  # The hook is this only while the alarm is set.
            self._alarm[2](unraisable)

    def __exit__(self, *exc) -> None:
        leaving = exc[1]
        if (isinstance(leaving, KeyboardInterrupt) and self._raised is not None
                and _signal_named(leaving) is None):
            leaving.args = self._raised
        self._repeat, self._ending = None, True
        dropped = self._dropped  # Python dropped it, and the block ended before a repeat.
        restores = list(self._previous.items())
        alarm = self._alarm
        if alarm is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
            sys.unraisablehook = alarm[2]
            restores.append((signal.SIGALRM, alarm[0]))
        arrived = None  # A signal acted on as its handler is given back.
        for signum, action in restores:
            try:
                signal.signal(signum, action)
            except KeyboardInterrupt as interrupt:
                arrived = arrived or interrupt
        if alarm is not None and alarm[1][0] > 0:  # A timer of the caller's, running on.
            signal.setitimer(signal.ITIMER_REAL, *alarm[1])
        if arrived is None and dropped is not None:
            arrived = KeyboardInterrupt(*dropped)
        if arrived is not None and not _interrupt_in_flight():
            raise arrived


def stop_signals() -> list[int]:
    """SIGTERM, and SIGINT where Ctrl-C reaches the process: Python's own handler, or one of
    these blocks' (`console` takes Ctrl-C so), not a background job's SIG_IGN."""
    handler = signal.getsignal(signal.SIGINT)
    if handler is signal.default_int_handler or isinstance(
            getattr(handler, "__self__", None), _Handled):
        return [signal.SIGTERM, signal.SIGINT]
    return [signal.SIGTERM]


def _interrupt_in_flight() -> bool:
    """Whether a KeyboardInterrupt is on its way out or being handled (what runs is its
    cleanup, or handling another exception inside it)."""
    exception = sys.exc_info()[1]
    while exception is not None:
        if isinstance(exception, KeyboardInterrupt):
            return True
        exception = exception.__context__
    return False


@contextlib.contextmanager
def held():
    """Inside the block Ctrl-C, SIGTERM and an interrupt's repeat are held, and delivered as
    it ends, in the order they came, to the handlers there were: for code that an exception
    raised inside leaves broken (jaxlib's import, interrupted, crashed the interpreter).
    Python runs handlers in its main thread only: in another, nothing to hold."""
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
            if action is not None:  # (None: a handler not set from Python, left as it is.)
                signal.signal(signum, action)
        for signum in received:
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
        raise KeyboardInterrupt(interrupt_message(signum))

    return _Handled(handler, signums)


def stop_requests(request, *signums: int):
    """Inside the block the first of `signums` calls `request(signum)`, so that what runs can
    stop where it is ready to (a training run: at its episode's end, where its checkpoint
    resumes exactly), with that signal's exit status; a second raises KeyboardInterrupt at
    once. Restored after."""
    received: list[int] = []

    def handler(signum, frame):
        if received:
            raise KeyboardInterrupt(interrupt_message(signum, again=True))
        received.append(signum)
        request(signum)

    return _Handled(handler, signums)


def interrupt_message(signum: int, *, again: bool = False) -> str:
    """What the KeyboardInterrupt a stop signal raises says, its one argument ("signal 15",
    "signal 15, again" where it stops at once what a first one asked to stop): it names
    the signal for `exit_status`, and it is what the interrupt is raised again from
    (`_Handled`) and what the stops that end a command pass on (a training run's
    `StoppedAtCheckpoint`, a sweep's `SweepStopped`)."""
    return f"signal {signum}" + (", again" if again else "")


def exit_status(interrupt: KeyboardInterrupt) -> int:
    """The exit status of a command that `interrupt` stopped: 128 + the number of the signal
    that stopped it (named by `interrupt_message`), as a shell gives a command that signal
    ends and as schedulers, `timeout --preserve-status` and CI read it: 130 for Ctrl-C
    (SIGINT), 143 for SIGTERM. An interrupt no handler here raised (Python's own Ctrl-C
    handler's) is Ctrl-C's."""
    signum = _signal_named(interrupt)
    return 128 + (signal.SIGINT if signum is None else signum)


def _signal_named(interrupt: KeyboardInterrupt) -> int | None:
    """The number of the signal `interrupt` names (`interrupt_message`); None: none."""
    named = re.fullmatch(r"signal (\d+)(, again)?", str(interrupt))
    return int(named[1]) if named else None
