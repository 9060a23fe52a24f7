"""Argument types shared by the subcommands, so a bad value is one clear argparse error."""

from __future__ import annotations

import argparse


def positive_int(text: str) -> int:
    """An integer >= 1; a whole number in scientific notation (5e5) is accepted too."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value >= 1 and value.is_integer()):
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return int(value)
