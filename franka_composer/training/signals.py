"""Signals that stop a training process the way Ctrl-C does, so what is running checkpoints.

`kill PID` (SIGTERM) is how schedulers, `timeout` and Ray stop a process, and a job started
in the background ignores SIGINT (the shell sets it to SIG_IGN), so neither would otherwise
reach the KeyboardInterrupt path that saves a checkpoint.
"""

from __future__ import annotations

import contextlib
import signal


@contextlib.contextmanager
def interrupt_on(*signums: int):
    """Inside the block each of `signums` raises KeyboardInterrupt; restored after."""
    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    previous = {signum: signal.signal(signum, handler) for signum in signums}
    try:
        yield
    finally:
        for signum, action in previous.items():
            signal.signal(signum, action)
