"""A run's files, written so that a kill never leaves half of one, and read so that a
damaged one is named with what is wrong rather than met as a traceback from the library
that reads it."""

from __future__ import annotations

import contextlib
import json
import pathlib
import pickle
import zipfile
import zlib

from franka_composer.atomic_files import sha256


def model_damage(path: pathlib.Path) -> str | None:
    """What is wrong with the SB3 (or sbx) model file at `path`, or None if it is a whole
    archive with its "data" (what SB3's load asserts) and every member's checksum right."""
    try:
        with zipfile.ZipFile(path) as archive:
            if "data" not in archive.namelist():
                return "no data in the archive"
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError, zlib.error) as error:
        return f"not a readable zip archive: {error}"
    return None if bad is None else f"{bad} fails its checksum"


def saved_policy_module(path: pathlib.Path) -> str | None:
    """The module of the policy class the SB3 (or sbx) model at `path` was saved with
    ("stable_baselines3.sac.policies"), as its "data" records it; None where it does not
    say (a damaged file is `model_damage`'s to name)."""
    try:
        return _saved_data(path)["policy_class"]["__module__"]
    except (KeyError, TypeError):
        return None


def saved_steps(path: pathlib.Path) -> int | None:
    """The steps the SB3 (or sbx) model at `path` had trained when it was saved (its
    "data"'s num_timesteps); None where it does not say."""
    steps = _saved_data(path).get("num_timesteps")
    return steps if isinstance(steps, int) and not isinstance(steps, bool) else None


def _saved_data(path: pathlib.Path) -> dict:
    """The "data" JSON object of the SB3 (or sbx) model at `path`; {} where it has none that
    reads."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, OSError, EOFError, zlib.error, KeyError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def checked_model(path: pathlib.Path) -> pathlib.Path:
    """`path`, if `model_damage` finds nothing wrong; else a ValueError naming it (a
    missing one as missing, as `unpickling` names a missing replay buffer)."""
    if not path.exists():
        raise ValueError(f"{path} is missing: a checkpoint cannot be resumed without it")
    damage = model_damage(path)
    if damage is not None:
        raise ValueError(f"{path} is damaged ({damage})")
    return path


def read_json(path: pathlib.Path, what: str) -> dict:
    """The JSON object in `path`; a ValueError naming it if it is not one (`what` says what
    it should be)."""
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as error:  # JSONDecodeError and UnicodeDecodeError are ValueErrors.
        raise ValueError(f"{path} is not {what}: {error}") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path} is not {what}: it holds {type(value).__name__}, not an "
                         "object")
    return value


def steps_of(state_path: pathlib.Path) -> int | None:
    """The steps of the checkpoint whose state file is `state_path`, or None if it has no
    whole one (a checkpoint not finished)."""
    try:
        steps = json.loads(state_path.read_text(encoding="utf-8")).get("steps")
    except (OSError, ValueError, AttributeError):
        return None
    return steps if isinstance(steps, int) else None


def file_digests(folder: pathlib.Path) -> dict[str, str]:
    """A SHA-256 of each file in `folder`, by name: what a checkpoint's state.json records
    of the files beside it (`check_file_digests`)."""
    return {path.name: sha256(path) for path in sorted(folder.iterdir())}


def check_file_digests(folder: pathlib.Path, digests: dict[str, str] | None) -> None:
    """A ValueError naming the first file in `folder` that is missing or whose SHA-256 is
    not the one in `digests` (a checkpoint's state.json's; None: written before they were
    recorded, and unchecked). Pickles keep no checksum: a changed byte unpickled as other
    weights or buffer contents, without a word, or a length field asked for 64 GiB."""
    for name, digest in sorted((digests or {}).items()):
        path = folder / name
        if not path.is_file():
            raise ValueError(f"{path} is missing: a checkpoint cannot be resumed without it")
        if sha256(path) != digest:
            raise ValueError(f"{path} is not the file its checkpoint wrote (its SHA-256 "
                             "differs from the one in state.json): damaged since")


@contextlib.contextmanager
def unpickling(path: pathlib.Path):
    """Reading the pickle at `path` (a replay buffer, the generators' states) inside the
    block: one that is missing, truncated, garbage or of something else is a ValueError
    naming it (SB3 names a missing buffer as its path with another .pkl added). A
    checkpoint's digests (`check_file_digests`) find a damaged one first; these are what
    a pickle without one raises (a length field past what memory holds: MemoryError or
    OverflowError)."""
    if not path.is_file():
        raise ValueError(f"{path} is missing: a checkpoint cannot be resumed without it")
    try:
        yield
    except (pickle.UnpicklingError, EOFError, AssertionError, KeyError, TypeError, ValueError,
            AttributeError, RuntimeError, OverflowError, MemoryError, SystemError) as error:
        raise ValueError(f"{path} is damaged (truncated or not what a checkpoint writes): "
                         f"{type(error).__name__}: {error}") from None
