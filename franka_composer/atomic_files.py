"""A file written whole or not at all: beside its place, then moved there in one step; what
is written flushed to the disk; and the folders made for it removed again if it is not.
`sha256` is how a reader checks later that a file is still the one written."""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import os
import pathlib
import stat
from typing import Callable

from franka_composer.signals import held


def replace_atomically(path: pathlib.Path, write) -> None:
    """`write(partial)` writes the file beside `path` (the same suffix), which then takes
    `path`'s place in one step: a run killed while writing leaves the file it had whole,
    or none, never half of one; a write that fails takes its partial file with it. A link
    is written through (the file it points to replaced, the link kept); a device, FIFO or
    socket is refused (`validation.check_writable`), not replaced by a file."""
    replace_together({path: write})


def replace_together(writes: dict) -> None:
    """`replace_atomically` for files that go together (a video and its first frame): each
    `write(partial)` of `writes` ({path: write}) writes its file beside its path, and only
    once all are written do they take their places, one rename each, with Ctrl-C and
    SIGTERM held meanwhile (`held`): a command stopped or failing leaves the files it had,
    or all the new ones, never one without the others (short of the process being killed
    outright, or the machine stopping, between two renames). Two paths that are one file,
    or a folder where a file is to go, are refused before anything is written."""
    places: list[tuple[pathlib.Path, pathlib.Path, Callable]] = []
    for path, write in writes.items():
        problem = irregular_file(path)
        if problem is not None:
            raise ValueError(f"cannot write to {path}: {problem}")
        real = pathlib.Path(os.path.realpath(path))
        if real.is_dir():
            raise ValueError(f"cannot write to {path}: it is a folder")
        if real in (place for _, place, _ in places):
            raise ValueError(f"cannot write to {path} twice at once: it is {real}, given "
                             "already")
        # Hidden and named after the whole file name, so that it is no file of the user's
        # (keep.npz's partial file is not keep.partial.npz).
        places.append((real.with_name(f".{real.name}.partial{real.suffix}"), real, write))
    try:
        for partial, _, write in places:
            write(partial)
            sync_to_disk(partial)
        with held():
            for partial, place, _ in places:
                os.replace(partial, place)
    except BaseException:
        with held():
            for partial, _, _ in places:
                partial.unlink(missing_ok=True)
        raise


def missing_folders(folder) -> list[pathlib.Path]:
    """`folder` and the folders above it that are not there, nearest first, as the file
    system finds them (`os.path.realpath`: links followed, `..` taken out): what a command
    that makes them removes again if it fails, to leave nothing behind."""
    folder = pathlib.Path(os.path.realpath(folder))
    return list(itertools.takewhile(lambda f: not f.exists(), (folder, *folder.parents)))


def remove_empty(folders) -> None:
    """Removes each of `folders` (`missing_folders`' list: nearest first) that is empty, with
    Ctrl-C and SIGTERM held (`held`): what a command that made them leaves when it fails.
    One not empty by then is left as it is, and so are those above it."""
    with held():
        for folder in folders:
            with contextlib.suppress(OSError):
                folder.rmdir()


@contextlib.contextmanager
def folders_made_for(path):
    """Makes the folders above the file `path` that are missing (`missing_folders`), and
    removes them again if the block raises (`remove_empty`): a command stopped or failing
    before its file lands leaves no empty folder it made."""
    made = missing_folders(pathlib.Path(os.path.realpath(path)).parent)
    try:
        if made:
            made[0].mkdir(parents=True, exist_ok=True)
        yield
    except BaseException:
        remove_empty(made)
        raise


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


def sha256(path: pathlib.Path) -> str:
    """The SHA-256 of the file at `path`, in hex: what a checkpoint's state.json and an RLDS
    dataset's digests file record of the files beside them."""
    with open(path, "rb") as file:
        return hashlib.file_digest(file, "sha256").hexdigest()


def sync_to_disk(path: pathlib.Path) -> None:
    """`path` (a file, or a folder's entries) flushed to the disk."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
