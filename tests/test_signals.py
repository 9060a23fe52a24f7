"""Signals that stop a command (`franka_composer.training.signals`): raised once, raised
again where Python dropped them, held where an exception would break what runs."""

from __future__ import annotations

import gc
import signal
import sys
import time

import pytest

from franka_composer.training.signals import interrupt_on, stop_requests


def test_a_first_stop_signal_asks_and_a_second_interrupts():
    asked = []
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt, match="signal 15, again"):
        with stop_requests(lambda: asked.append(True), signal.SIGTERM):
            signal.raise_signal(signal.SIGTERM)
            assert asked == [True]  # Asked; nothing raised.
            signal.raise_signal(signal.SIGTERM)
    assert asked == [True] and signal.getsignal(signal.SIGTERM) is before


def _signalled_in_a_gc_callback(signum):
    """A gc callback (as jax adds one) in which `signum` arrives, once: Python drops what
    its handler raises there."""
    def callback(phase, info):
        if phase == "start" and callback in gc.callbacks:
            gc.callbacks.remove(callback)
            signal.raise_signal(signum)

    gc.callbacks.append(callback)
    return callback


def test_an_interrupt_python_dropped_is_raised_again_and_not_reported(monkeypatch):
    """SIGTERM's KeyboardInterrupt raised in jax's gc callback was dropped ("Exception
    ignored") and a rollout recorded on: CI's rollout, stopped, ran past its test's 60 s."""
    reported = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    before = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGALRM)}
    callback = _signalled_in_a_gc_callback(signal.SIGTERM)
    try:
        with pytest.raises(KeyboardInterrupt, match="^signal 15$"):
            begun = time.monotonic()
            with interrupt_on(signal.SIGTERM):
                gc.collect()  # The interrupt is raised, and dropped, in here.
                while time.monotonic() - begun < 10:
                    sum(range(1000))
                pytest.fail("the interrupt dropped in the gc callback was not raised again")
    finally:
        if callback in gc.callbacks:
            gc.callbacks.remove(callback)
    assert time.monotonic() - begun < 2  # A collection, and a repeat's 50 ms.
    assert reported == []  # Python's "Exception ignored" for it, left out.
    assert {signum: signal.getsignal(signum) for signum in before} == before
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


def test_an_interrupt_on_its_way_out_is_not_raised_again_in_its_cleanup():
    cleaned = []
    with pytest.raises(KeyboardInterrupt) as raised:
        with interrupt_on(signal.SIGTERM):
            try:
                signal.raise_signal(signal.SIGTERM)
            finally:
                time.sleep(0.3)  # Six of the repeat's periods.
                cleaned.append(True)
    assert cleaned == [True] and raised.value.__context__ is None


def test_a_held_signal_is_delivered_as_the_block_ends():
    """Held where an exception breaks what runs (jaxlib's import, interrupted, crashed the
    interpreter), and then acted on."""
    from franka_composer.training.signals import held

    went_on = []
    with pytest.raises(KeyboardInterrupt, match="^signal 15$"):
        with interrupt_on(signal.SIGTERM):
            with held():
                signal.raise_signal(signal.SIGTERM)
                went_on.append(True)
            went_on.append(False)
    assert went_on == [True]


def test_jax_is_imported_whole_with_a_stop_signal_held_over_it():
    """SIGTERM inside jaxlib's import crashed the interpreter or failed it as an ImportError
    (a new process each: jax is imported once). Here it arrives as jaxlib's extension is
    looked for, and stops the process once jax is imported."""
    import subprocess
    import textwrap

    script = textwrap.dedent("""
        import signal, sys
        from franka_composer.training.signals import interrupt_on, jax_imported

        class SignalledOnLookup:
            def find_spec(self, name, path=None, target=None):
                if name == "jaxlib._jax":
                    signal.raise_signal(signal.SIGTERM)
                return None

        sys.meta_path.insert(0, SignalledOnLookup())
        try:
            with interrupt_on(signal.SIGTERM):
                jax_imported()
        except KeyboardInterrupt as interrupt:
            print(interrupt, "jax" in sys.modules, "jaxlib._jax" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert (done.returncode, done.stdout) == (0, "signal 15 True True\n"), done.stderr
