"""Signals that stop a training process the way Ctrl-C does, so what is running checkpoints:
at once (`interrupt_on`), or where it is ready to (`stop_requests`).

`kill PID` (SIGTERM) is how schedulers, `timeout` and Ray stop a process, and a job started
in the background ignores SIGINT (the shell sets it to SIG_IGN), so neither would otherwise
reach the KeyboardInterrupt path that saves a checkpoint.
"""

from __future__ import annotations

import contextlib
import signal


@contextlib.contextmanager
def _handled(handler, signums):
    """Inside the block `handler` receives each of `signums`; their handlers restored after."""
    previous = {signum: signal.signal(signum, handler) for signum in signums}
    try:
        yield
    finally:
        for signum, action in previous.items():
            signal.signal(signum, action)


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
