"""A file written whole or not at all: beside its place, then moved there in one step."""

from __future__ import annotations

import os
import pathlib


def replace_atomically(path: pathlib.Path, write) -> None:
    """`write(partial)` writes the file beside `path` (the same suffix), which then takes
    `path`'s place in one step: a run killed while writing leaves the file it had whole,
    or none, never half of one; a write that fails takes its partial file with it."""
    partial = path.with_name(f"{path.stem}.partial{path.suffix}")
    try:
        write(partial)
        with open(partial, "rb+") as written:
            os.fsync(written.fileno())
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    os.replace(partial, path)
