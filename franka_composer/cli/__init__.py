"""The `franka-composer` command line: one module per subcommand.

Each module in `SUBCOMMANDS` defines `add_parser(subparsers)` that registers its parser and
sets `func` (a callable taking the parsed arguments and returning an exit code).
"""

from __future__ import annotations

import argparse
import importlib
import os
import pathlib
import signal
import sys
import warnings

from franka_composer import __version__
from franka_composer.assets import MenagerieUnavailableError
from franka_composer.cli.extras import missing_extra
from franka_composer.headless_gl import HeadlessGLError
from franka_composer.signals import exit_status, interrupt_on, stop_signals

#: Subcommand modules, in the order `--help` lists them.
SUBCOMMANDS = ("demo", "rollout", "bench", "train", "sweep", "keep", "evaluate", "plot",
               "report")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="franka-composer",
        description="Goal-conditioned Franka Panda manipulation (dm_control Composer suite).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        importlib.import_module(f"franka_composer.cli.{name}").add_parser(subparsers)
    return parser


def command_parser(name: str) -> argparse.ArgumentParser:
    """The parser of the subcommand `name` alone: its options as `franka-composer NAME`
    takes them."""
    subparsers = argparse.ArgumentParser(prog="franka-composer").add_subparsers()
    importlib.import_module(f"franka_composer.cli.{name}").add_parser(subparsers)
    return subparsers.choices[name]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


def console(argv: list[str] | None = None) -> int:
    """`main` for a terminal: a refused value (ValueError) is one line on stderr and exit
    status 2, as argparse reports its own errors, not a traceback, and so are a Panda that
    cannot be found, a process that cannot render (`HeadlessGLError`), a model too large
    for the memory (MemoryError), a package of an extra not installed (naming the extra)
    and a file that cannot be written or read after all (OSError: a full disk, a folder
    removed meanwhile; status 1); a reader that has gone
    (`franka-composer evaluate ... | head`) ends the command quietly, with the status a
    shell gives a command SIGPIPE ends; Ctrl-C and SIGTERM end it in one line where the
    command has nothing of its own to say (train and sweep say what they kept), with the
    status a shell gives a command that signal ends (`exit_status`: 130, 143)."""
    warnings.formatwarning = _format_warning
    try:
        try:
            # `kill` (SIGTERM: schedulers, `timeout`) stops any command as Ctrl-C does, so
            # what it was writing is taken away whole (a rollout's half-written RLDS or
            # Minari dataset was left); train and sweep stop at their checkpoints. Ctrl-C
            # through the same handler: one Python dropped is raised again.
            with interrupt_on(*stop_signals()):
                return main(argv)
        finally:
            sys.stdout.flush()  # What is still buffered meets a gone reader here.
    except (ValueError, MenagerieUnavailableError, HeadlessGLError, MemoryError) as error:
        print(f"franka-composer: error: {error}", file=sys.stderr)
        return 2 if isinstance(error, ValueError) else 1
    except ImportError as error:
        install = missing_extra(error)
        if install is None:
            raise  # Not an extra's: a broken installation, whose traceback says where.
        print(f"franka-composer: error: {install}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        # The interpreter flushes stdout again on exit: let that write go nowhere.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except OSError as error:  # After BrokenPipeError, one of its kind.
        print(f"franka-composer: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as interrupt:
        print("franka-composer: interrupted", file=sys.stderr)
        return exit_status(interrupt)


_PACKAGE = pathlib.Path(__file__).resolve().parents[1]
_default_format_warning = warnings.formatwarning


def _format_warning(message, category, filename, lineno, line=None) -> str:
    """This package's warnings to a terminal as one line, as its errors are, not Python's
    file, line and source; other libraries' as Python writes them."""
    if pathlib.Path(filename).resolve().is_relative_to(_PACKAGE):
        return f"franka-composer: warning: {message}\n"
    return _default_format_warning(message, category, filename, lineno, line)

