"""The folder a recording writes into, made for it and removed with it if it fails."""

from __future__ import annotations

import pathlib


def make_folder(root: pathlib.Path) -> pathlib.Path | None:
    """Makes `root` and the folders above it that are missing; the topmost of those it made
    (what a failed recording removes to leave nothing behind), or None if `root` was there."""
    missing = [folder for folder in (root, *root.parents) if not folder.exists()]
    root.mkdir(parents=True, exist_ok=True)
    return missing[-1] if missing else None
