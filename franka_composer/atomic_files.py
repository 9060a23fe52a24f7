"""A file written whole or not at all: beside its place, then moved there in one step; and
what is written flushed to the disk."""

from __future__ import annotations

import os
import pathlib
import stat


def replace_atomically(path: pathlib.Path, write) -> None:
    """`write(partial)` writes the file beside `path` (the same suffix), which then takes
    `path`'s place in one step: a run killed while writing leaves the file it had whole,
    or none, never half of one; a write that fails takes its partial file with it. A link
    is written through (the file it points to replaced, the link kept); a device, FIFO or
    socket is refused (`validation.check_writable`), not replaced by a file."""
    problem = irregular_file(path)
    if problem is not None:
        raise ValueError(f"cannot write to {path}: {problem}")
    path = pathlib.Path(os.path.realpath(path))
    # Hidden and named after the whole file name, so that it is no file of the user's
    # (keep.npz's partial file is not keep.partial.npz).
    partial = path.with_name(f".{path.name}.partial{path.suffix}")
    try:
        write(partial)
        sync_to_disk(partial)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    os.replace(partial, path)


def irregular_file(path) -> str | None:
    """What keeps a file from being written whole at `path` (a link followed), or None: a
    device, FIFO or socket there, which the file moved into its place would replace (as
    root, /dev/null), or a link into a folder that does not exist."""
    try:
        mode = os.stat(path).st_mode
    except NotADirectoryError:  # Under a file: `check_writable` says so.
        return None
    except FileNotFoundError:
        if os.path.islink(path) and not os.path.isdir(os.path.dirname(os.path.realpath(path))):
            return f"it is a link to {os.readlink(path)}, in a folder that does not exist"
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return ("it is not a regular file (a device, FIFO or socket), which a file written in "
            "its place would replace; give a file's path")


def sync_to_disk(path: pathlib.Path) -> None:
    """`path` (a file, or a folder's entries) flushed to the disk."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
