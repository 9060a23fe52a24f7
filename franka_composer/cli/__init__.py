"""The `franka-composer` command line: one module per subcommand.

Each module in `SUBCOMMANDS` defines `add_parser(subparsers)` that registers its parser and
sets `func` (a callable taking the parsed arguments and returning an exit code).
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: Subcommand modules, in the order `--help` lists them.
SUBCOMMANDS = ("demo", "rollout", "bench", "train", "sweep", "evaluate", "plot",
               "report")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="franka-composer",
        description="Goal-conditioned Franka Panda manipulation (dm_control Composer suite).",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"franka_composer.cli.{name}")
        except ModuleNotFoundError as error:
            if error.name == f"franka_composer.cli.{name}":
                continue  # Not built yet.
            raise
        module.add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


def console(argv: list[str] | None = None) -> int:
    """`main` for a terminal: a refused value (ValueError) is one line on stderr and exit
    status 2, as argparse reports its own errors, not a traceback."""
    try:
        return main(argv)
    except ValueError as error:
        print(f"franka-composer: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
