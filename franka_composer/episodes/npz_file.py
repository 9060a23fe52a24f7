"""This package's own dataset file: every episode concatenated in one `.npz`.

    observation, achieved_goal, desired_goal   one row per step plus the reset's, per episode
    (<camera>_pixels in the pixel modes)       (the env's observation keys)
    action, reward, is_success, terminated,    one row per step
    truncated
    episode_length                             steps of each episode, in order
    metadata                                   JSON: what it was recorded with (id,
                                               task, control, reward_type,
                                               max_episode_steps, source, seed,
                                               action_noise, options); absent in files
                                               written before it was recorded

`read` checks the file whole (a readable archive, every key, one-dimensional episode
lengths that add up to the arrays, each episode ending where its done flags say) and
names the file and what is wrong.
"""

from __future__ import annotations

import json
import os
import pathlib
import stat
import struct
import zipfile

import numpy as np

from franka_composer.atomic_files import replace_atomically
from franka_composer.episodes.record import GOAL_KEYS, STEP_KEYS, check_episodes
from franka_composer.validation import check_path, check_writable

#: The key holding `metadata`, a JSON string.
METADATA_KEY = "metadata"
#: How an npz (a zip archive: a local file header, or an empty archive's end record) and
#: a .npy file begin.
_ZIP_MAGIC, _NPY_MAGIC = (b"PK\x03\x04", b"PK\x05\x06"), b"\x93NUMPY"
#: numpy and zipfile raise what they meet in a damaged archive: BadZipFile, zlib.error,
#: EOFError, OSError, ValueError, and for a changed byte in a header NotImplementedError
#: (an unknown compression method or zip version), RuntimeError (read as encrypted) or
#: tokenize's TokenError (an npy header): reading a file, each is damage.
_DAMAGED = Exception


def write(episodes: list[dict[str, np.ndarray]], path: str | os.PathLike,
          metadata: dict | None = None) -> None:
    """Writes every episode, concatenated, with `episode_length` and `metadata` (JSON), whole
    or not at all: beside the file, which it then replaces in one step (a recording
    interrupted while writing left an archive of some of the arrays in the old one's place,
    read as a foreign file)."""
    if not episodes:
        raise ValueError(f"no episodes to write to {path}: a dataset holds at least one")
    arrays = {key: np.concatenate([e[key] for e in episodes]) for key in episodes[0]}
    if metadata:
        arrays[METADATA_KEY] = np.array(_metadata_json(metadata))
    lengths = np.array([len(e["action"]) for e in episodes], dtype=np.int64)
    target = check_destination(path)
    if not target.parent.is_dir():  # (Else the error names the partial file beside it.)
        raise ValueError(f"cannot write {target}: {target.parent} is not a folder")
    # (No key of `arrays` is allow_pickle, which numpy's hints cannot tell.)
    replace_atomically(target, lambda partial: np.savez_compressed(
        partial, episode_length=lengths, **arrays))  # type: ignore[arg-type]


def check_destination(path) -> pathlib.Path:
    """`path` as a Path if an npz dataset can be written there, found out before the
    episodes are recorded: its name ends in .npz (numpy's savez would add it, and `read`
    would not find the file by the name given), it is no folder, and a file can be made
    there (`check_writable`: the folders above it may be still to make)."""
    path = check_path("an npz dataset's path", path)
    if path.suffix != ".npz":
        raise ValueError(f"an npz dataset's path must end in .npz, got {str(path)!r}")
    if path.is_dir():
        raise ValueError(f"an npz dataset is a file, and {path} is a folder")
    return check_writable(path)


def read(path: str | os.PathLike) -> tuple[list[dict[str, np.ndarray]], dict]:
    """The episodes `write` wrote and their metadata ({} in files from before it was
    recorded); a ValueError naming `path` and what is wrong if the file is not whole."""
    path = check_path("an npz dataset's path", path)
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not an npz file")
    if path.exists() and not stat.S_ISREG(path.stat().st_mode):  # Opening a FIFO waits.
        raise ValueError(f"{path} is not a regular file (a device, FIFO or socket), not an "
                         "npz file")
    try:
        with open(path, "rb") as file:
            magic = file.read(len(_NPY_MAGIC))
        if not magic.startswith(_ZIP_MAGIC) and magic != _NPY_MAGIC:
            # numpy would take it for a pickle, and say to load it unsafely.
            raise ValueError(f"it is not an npz (zip) archive: it begins {magic!r}" if magic
                             else "it is empty")
        data = np.load(path)
        if not isinstance(data, np.lib.npyio.NpzFile):  # A .npy file under an .npz name.
            raise ValueError("it holds one array, not an npz archive")
        with data:
            _check_every_member_listed(data.zip)
            arrays = {key: data[key] for key in data.files}
    except FileNotFoundError:
        raise ValueError(f"{path} does not exist") from None
    except _DAMAGED as error:
        raise ValueError(f"{path} is not a readable npz file (truncated or damaged?): "
                         f"{type(error).__name__}: {error}") from None
    missing = [key for key in ("episode_length",) + GOAL_KEYS + STEP_KEYS
               if key not in arrays]
    if missing:
        raise ValueError(f"{path} is not a franka_composer npz dataset: it has no "
                         f"{', '.join(missing)}")
    lengths = _episode_lengths(path, arrays["episode_length"])
    observation_keys = [key for key in arrays
                        if key not in (*STEP_KEYS, "episode_length", METADATA_KEY)]
    for keys, rows in ((observation_keys, int((lengths + 1).sum())),
                       (STEP_KEYS, int(lengths.sum()))):
        for key in keys:
            if arrays[key].ndim == 0 or len(arrays[key]) != rows:
                raise ValueError(f"{path}: its episode_length adds up to {rows} rows of "
                                 f"{key}, and it holds {len(np.atleast_1d(arrays[key]))}: "
                                 "its episode boundaries do not match its arrays")
    split = {key: np.split(arrays[key], np.cumsum(lengths + 1)[:-1])
             for key in observation_keys}
    split.update({key: np.split(arrays[key], np.cumsum(lengths)[:-1]) for key in STEP_KEYS})
    episodes = [{key: split[key][i] for key in split} for i in range(len(lengths))]
    check_episodes(path, episodes)
    return episodes, _metadata(path, arrays.get(METADATA_KEY))


def _check_every_member_listed(archive: zipfile.ZipFile | None) -> None:
    """A BadZipFile (a damaged file, to `read`) unless zipfile read as many members as the
    archive's end record counts: a changed byte in a member's entry of the central
    directory (a name or comment length) makes zipfile stop early, and the members after
    it (`metadata` is the last) would be read as never written. zipfile keeps no count of
    its own."""
    assert archive is not None and archive.fp is not None  # (Open: np.load's.)
    file = archive.fp
    file.seek(0, os.SEEK_END)
    size = file.tell()
    tail_size = min(size, 22 + 0xFFFF)  # The end record, and a comment of at most 64 KiB.
    file.seek(size - tail_size)
    tail = file.read(tail_size)
    end = tail.rfind(b"PK\x05\x06")
    if end < 0:
        raise zipfile.BadZipFile("no end of central directory record")
    (counted,) = struct.unpack_from("<H", tail, end + 10)
    # (0xFFFF: 65,535 members or more, counted in a zip64 record; a dataset holds a dozen.)
    if counted != 0xFFFF and counted != len(archive.infolist()):
        raise zipfile.BadZipFile(f"its end record counts {counted} members, and its central "
                                 f"directory lists {len(archive.infolist())}")


def _episode_lengths(path, lengths: np.ndarray) -> np.ndarray:
    if lengths.ndim != 1 or not np.issubdtype(lengths.dtype, np.integer):
        raise ValueError(f"{path}: episode_length must be a list of whole step counts, got "
                         f"{lengths.dtype} of shape {lengths.shape}")
    if len(lengths) == 0:
        raise ValueError(f"{path} holds no episodes (an empty episode_length)")
    if lengths.min() < 1:
        raise ValueError(f"{path}: episode {int(np.argmin(lengths))} has "
                         f"{int(lengths.min())} steps by its episode_length")
    return lengths.astype(np.int64)


def _metadata_json(metadata) -> str:
    """`metadata` as JSON, if it is a mapping of names to what JSON holds (else `read`
    would refuse the file, or give back another key: 1 as "1")."""
    if not isinstance(metadata, dict):
        raise ValueError(f"metadata must be a dict of names to values, got {metadata!r}")
    for key, value in metadata.items():
        if not isinstance(key, str):
            raise ValueError(f"metadata's keys must be strings, got {key!r}")
        try:
            json.dumps(value)
        except (TypeError, ValueError):
            raise ValueError(f"metadata[{key!r}] = {value!r} is not JSON (give str, int, "
                             "float, bool, None, and lists and dicts of them; numpy's "
                             "scalars as Python's: .item())") from None
    return json.dumps(metadata)


def _metadata(path, stored) -> dict:
    if stored is None:
        return {}
    try:
        metadata = json.loads(str(stored))
    except ValueError:
        metadata = None
    if not isinstance(metadata, dict):
        raise ValueError(f"{path}: its metadata is not a JSON object: {str(stored)[:80]!r}")
    return metadata
