"""The folder a recording writes into, made for it and removed with it if it fails."""

from __future__ import annotations

import contextlib
import pathlib
import shutil

from franka_composer.atomic_files import missing_folders
from franka_composer.signals import held


@contextlib.contextmanager
def removed_if_it_fails(root: pathlib.Path):
    """Makes `root` for a recording, with the folders above it that are missing
    (`missing_folders`); if the block raises, removes what the recording made: the folders
    made for it, or, in a `root` that was there, each file and folder that was not (Minari
    writes its namespaces' metadata beside the dataset), with Ctrl-C and SIGTERM held
    meanwhile: a second one left half a dataset."""
    made = missing_folders(root)
    before = set() if made else set(root.rglob("*"))
    try:
        if made:
            made[0].mkdir(parents=True, exist_ok=True)
        yield
    except BaseException:
        with held():
            if made:
                shutil.rmtree(made[-1], ignore_errors=True)
            else:
                for path in sorted(set(root.rglob("*")) - before, key=lambda p: len(p.parts)):
                    if path.is_dir() and not path.is_symlink():
                        shutil.rmtree(path, ignore_errors=True)
                    elif path.exists() or path.is_symlink():
                        path.unlink()
        raise
