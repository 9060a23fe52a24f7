"""Minari datasets (Gymnasium's offline-RL format), written through `minari.DataCollector`.

Each episode holds the full goal-dict observations, actions, rewards, terminations,
truncations and the `is_success` infos, with its reset seed and a SHA-256 of its arrays
(`add_digests`: Minari's HDF5 keeps no checksum) in the episode metadata; the
dataset holds the env spec with the options it was made with, so
`minari.load_dataset(id).recover_environment()` gives back the same env.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import json
import math
import os
import pathlib
import warnings

import numpy as np

from franka_composer.datasets.folders import removed_if_it_fails
from franka_composer.episodes import check_not_diverged
from franka_composer.signals import jax_imported

#: Where Minari keeps datasets (its own variable): `--out` sets it while writing.
DATASETS_PATH_VARIABLE = "MINARI_DATASETS_PATH"


@contextlib.contextmanager
def datasets_root(root: pathlib.Path):
    """Minari reads and writes datasets under `root` inside the block."""
    previous = os.environ.get(DATASETS_PATH_VARIABLE)
    os.environ[DATASETS_PATH_VARIABLE] = str(pathlib.Path(root).resolve())
    try:
        yield
    finally:
        if previous is None:
            del os.environ[DATASETS_PATH_VARIABLE]
        else:
            os.environ[DATASETS_PATH_VARIABLE] = previous


def write(env, policy, episodes: int, seed: int, root: pathlib.Path, dataset_id: str,
          description: str) -> dict:
    """Records `episodes` episodes of `policy` in `env` (episode i reset with seed + i) as
    the Minari dataset `dataset_id` under `root`; returns its size and success rate.

    Minari's collector keeps the episodes in a temporary folder under its datasets root
    until `create_dataset`, and joins that root to itself if it is relative: the collector
    is made with `root` (absolute) as its root, and closed (its temporary folder removed)
    whatever happens; what a dataset that was not finished made is removed
    (`removed_if_it_fails`)."""
    import minari
    from minari.data_collector.callbacks import StepDataCallback

    recording = {"episode": 0}

    class RefusingDivergence(StepDataCallback):
        """Minari's step data, for a step the physics did not diverge on (`info`
        without "diverged"): one that did is refused (`check_not_diverged`) before
        Minari's buffer meets the key it adds, which it failed on as a "pytree structure
        error"."""

        def __call__(self, env, **step):
            if step["info"].get("diverged"):
                check_not_diverged([recording["episode"]])
            return super().__call__(env, **step)

    jax_imported()  # Minari's first step imports it.
    collector, successes = None, 0
    with removed_if_it_fails(root):
        try:
            with datasets_root(root):
                # Images stored as they were observed: Minari's default JPEG changed 99.9 %
                # of their pixels (up to 138 levels) and lost a 32 x 48 image's block and
                # goal marker.
                collector = minari.DataCollector(env, step_data_callback=RefusingDivergence,
                                                 record_infos=True, jpeg_encoding=False)
            for index in range(episodes):
                recording["episode"] = index
                if hasattr(policy, "reset"):
                    policy.reset()
                obs, _ = collector.reset(seed=seed + index)
                done, info = False, {"is_success": False}
                while not done:
                    obs, _, terminated, truncated, info = collector.step(policy(obs))
                    done = terminated or truncated
                successes += bool(info["is_success"])
            with datasets_root(root), warnings.catch_warnings():
                # Minari recommends a contact e-mail and a link to versioned code; a dataset
                # made on a user's machine has neither, and says which package version made
                # it.
                warnings.filterwarnings("ignore",
                                        message="`(author_email|code_permalink)` is set",
                                        category=UserWarning)
                dataset = collector.create_dataset(
                    dataset_id=dataset_id, eval_env=env.spec, algorithm_name=description,
                    description=f"{description}; made by franka_composer {_version()}",
                    author="franka_composer")
        finally:
            if collector is not None:
                collector.close()
        add_digests(pathlib.Path(root) / dataset_id / "data")
    return {"episodes": dataset.total_episodes, "steps": dataset.total_steps,
            "success_rate": successes / episodes}


#: The attribute of each episode's HDF5 group that `add_digests` sets: a SHA-256 of its
#: arrays. Minari's HDF5 files keep no checksum, and a changed byte in an array read as
#: another number, where npz files (zip's CRC-32) and RLDS files (riegeli's) fail to read.
DIGEST_ATTRIBUTE = "franka_composer_sha256"
#: The HDF5 file of a Minari dataset's data folder (its default storage; the arrow
#: storage writes folders of its own).
HDF5_FILE = "main_data.hdf5"


def add_digests(data: pathlib.Path) -> None:
    """Gives each episode of the Minari dataset whose data folder is `data` its digest
    (`DIGEST_ATTRIBUTE`, which Minari reads as one more key of its episode metadata)."""
    import h5py

    with h5py.File(data / HDF5_FILE, "r+") as file:
        for name in episode_groups(file):
            file[name].attrs[DIGEST_ATTRIBUTE] = _digest(file[name])


#: The bytes one chunk of an HDF5 array may take in any file: h5py's largest automatic chunk
#: (`h5py.filters.CHUNK_MAX`), which a small file's arrays may declare and never fill.
CHUNK_BYTES_ALLOWED = 1024 * 1024


def check_declared_sizes(path, data: pathlib.Path) -> None:
    """A ValueError naming `path` and the first array whose header declares more than its
    HDF5 file holds, read from the headers alone: reading it made h5py allocate what it
    declared (one flipped bit in a dimension asked for 3 GB, and the process ran out of
    memory before any other check).

    An array stored without filters (Minari's and `write`'s) keeps every byte of its shape
    on disk, so its shape, or one chunk of it, may not declare more bytes than the file
    holds. A compressed one (`h5repack -f GZIP=6`) stores every chunk its shape spans, each
    of fewer bytes than it declares, so it may not span more chunks than its file stores,
    nor declare a chunk larger than both its shape and h5py's largest automatic chunk."""
    if not (data / HDF5_FILE).is_file():
        return
    import h5py

    size = (data / HDF5_FILE).stat().st_size
    damaged = None
    try:
        with h5py.File(data / HDF5_FILE, "r") as file:
            arrays: list = []
            file.visititems(lambda name, item: arrays.append(item)
                            if isinstance(item, h5py.Dataset) else None)
            for array in arrays:
                damaged = _more_than_stored(array, size)
                if damaged is not None:
                    break
    except Exception as error:  # h5py raises what it meets in a damaged file.
        raise unreadable(path, error, HDF5_FILE) from None
    if damaged is not None:
        raise ValueError(f"{path}: the array {damaged[0]} of its {HDF5_FILE} declares shape "
                         f"{damaged[1]} (chunks {damaged[2]}), {damaged[3]}: its header is "
                         "damaged; record it again")


def _more_than_stored(array, size: int) -> tuple | None:
    """(name, shape, chunks, what it declares beyond what is stored) for an HDF5 array of a
    file of `size` bytes whose header declares more than the file stores (as
    `check_declared_sizes` says); None where it does not."""
    itemsize = array.dtype.itemsize
    declared = math.prod(array.shape) * itemsize  # Python's ints: any size.
    chunk = math.prod(array.chunks) * itemsize if array.chunks else 0
    if not array.id.get_create_plist().get_nfilters():
        if declared > size or chunk > max(size, CHUNK_BYTES_ALLOWED):
            return (array.name, array.shape, array.chunks,
                    f"{max(declared, chunk):,} bytes, and the file holds {size:,}")
        return None
    spanned = math.prod(-(-length // side) for length, side in zip(array.shape, array.chunks))
    stored = array.id.get_num_chunks()
    if chunk > max(declared, CHUNK_BYTES_ALLOWED):
        return (array.name, array.shape, array.chunks,
                f"chunks of {chunk:,} bytes, more than the {declared:,} of its shape")
    if spanned > stored:
        return (array.name, array.shape, array.chunks,
                f"{spanned:,} compressed chunks, and the file stores {stored:,}")
    return None


def check_digests(path, data: pathlib.Path) -> None:
    """A ValueError naming `path` and the episodes whose arrays are not those `write`
    recorded (their digest differs). Episodes without one pass: added by Minari itself,
    or by a version that wrote none; so does a dataset in Minari's arrow storage."""
    if not (data / HDF5_FILE).is_file():
        return
    import h5py

    try:
        with h5py.File(data / HDF5_FILE, "r") as file:
            changed = [name.removeprefix("episode_") for name in episode_groups(file)
                       if DIGEST_ATTRIBUTE in file[name].attrs
                       and file[name].attrs[DIGEST_ATTRIBUTE] != _digest(file[name])]
    except Exception as error:  # h5py raises what it meets in a damaged file.
        raise unreadable(path, error, HDF5_FILE) from None
    if changed:
        raise ValueError(f"{path}: the data of episode{'s' if len(changed) > 1 else ''} "
                         f"{', '.join(changed)} is not what was recorded (its SHA-256 "
                         f"differs from the one recorded in its {HDF5_FILE}): damaged or "
                         "edited since; record it again")


def check_files(path, data: pathlib.Path) -> None:
    """A ValueError naming the file a Minari dataset at `path` (its files in `data`) lacks:
    its metadata.json, or the main_data.hdf5 that metadata says it stores its episodes in.
    Minari's own "No data found in data path" names neither."""
    metadata_file = data / "metadata.json"
    if not metadata_file.is_file():
        raise ValueError(f"{path} is not a Minari dataset: {metadata_file} is missing "
                         "(where Minari keeps what the dataset holds and how it is stored)")
    try:
        storage = json.loads(metadata_file.read_text()).get("data_format", "hdf5")
    except (ValueError, AttributeError, UnicodeDecodeError) as error:
        raise unreadable(path, error, "metadata.json") from None
    if storage == "hdf5" and not (data / HDF5_FILE).is_file():
        raise ValueError(f"{path} is not a readable Minari dataset: {data / HDF5_FILE}, which "
                         f"its metadata.json says holds the episodes, is missing")


def unreadable(path, error: Exception, file: str | None = None) -> ValueError:
    """The error for a Minari dataset at `path` that h5py, json or Minari failed to read
    (in its `file`, where known), with the first line of what they said."""
    first_line = (str(error).splitlines() or [""])[0]
    inside = f"its {file}: " if file else ""
    return ValueError(f"{path} is not a readable Minari dataset (damaged?): {inside}"
                      f"{type(error).__name__}: {first_line}")


def episode_groups(file) -> list[str]:
    """The names of a Minari HDF5 file's episode groups (episode_0, ...), in episode
    order."""
    return sorted((name for name in file if name.startswith("episode_")),
                  key=lambda name: (len(name), name))


def _digest(group) -> str:
    """A SHA-256 of every array under an episode's HDF5 group: each one's path, dtype,
    shape and bytes, in path order."""
    import h5py

    names = []
    group.visititems(lambda name, item: names.append(name)
                     if isinstance(item, h5py.Dataset) else None)
    digest = hashlib.sha256()
    for name in sorted(names):
        array = np.ascontiguousarray(group[name][()])
        digest.update(f"{name} {array.dtype.str} {array.shape}\n".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def _version() -> str:
    try:
        return importlib.metadata.version("franka_composer")
    except importlib.metadata.PackageNotFoundError:
        return "(not installed)"


def episode_seeds(dataset) -> list[int]:
    """Each episode's reset seed, in episode order."""
    ids = list(range(dataset.total_episodes))
    return [int(meta["seed"]) for meta in dataset.storage.get_episode_metadata(ids)]
