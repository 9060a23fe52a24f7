"""Compiled models saved on disk, so a new process skips compiling Menagerie's Panda.

Compiling the Panda (400k visual mesh vertices) takes ~1 s and ~250 MB at peak. The compiled
model is saved as an MJB file and later loads read it instead. The folder is
`$FRANKA_COMPOSER_CACHE`, else `$XDG_CACHE_HOME/franka_composer` (default
`~/.cache/franka_composer`); `FRANKA_COMPOSER_CACHE=off` disables it.

A file is named `KEY.DIGEST.mjb`: KEY hashes what the model is compiled from (the MuJoCo
version, the generated XML, every asset's bytes), DIGEST the file's own bytes. A file whose
bytes no longer match its DIGEST (changed on disk, even if it still loads: a timestep edited
from 0.002 to 0.0025 would silently change the simulation) is deleted and the model rebuilt.
A readable file is used even where it cannot be touched (a read-only or shared cache): its
timestamp, refreshed for least-recently-used eviction, is only a hint. Files are written to a
unique temporary name (per process and thread) and renamed into place, so parallel workers
never read half a file; temporary files older than an hour, left by killed processes, are
swept when a model is saved.
"""

from __future__ import annotations

import hashlib
import os
import pathlib
import tempfile
import time

import mujoco
import numpy as np
from absl import logging
from dm_control import mjcf
from dm_control.mujoco import wrapper

#: Compiled models kept (each ~35 MB with the Panda's visual meshes, ~6 MB without); the
#: least recently used beyond this are deleted.
MAX_CACHED_MODELS = 8
#: Age (s) past which a temporary file is taken to be a killed writer's and deleted.
STALE_PARTIAL_SECONDS = 3600.0
_DIGEST_CHARS = 32
#: Cache folders this process could not write to, already warned of.
_UNWRITABLE: set[pathlib.Path] = set()


def model_cache_dir() -> pathlib.Path | None:
    """Where compiled models are kept, or None when caching is off."""
    configured = os.environ.get("FRANKA_COMPOSER_CACHE")
    if configured is not None:
        return None if configured.lower() in ("", "0", "off", "false") else pathlib.Path(configured)
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "franka_composer"


def compile_physics(mjcf_model) -> mjcf.Physics:
    """`mjcf.Physics.from_mjcf_model` (with dm_control's readable compile errors), through the
    compiled-model cache when it is on."""
    directory = model_cache_dir()
    if directory is None:
        return mjcf.Physics.from_mjcf_model(mjcf_model)
    key = model_key(mjcf_model)
    for path in sorted(directory.glob(f"{key}.*.mjb")):
        physics = _load_verified(path)
        if physics is not None:
            return physics
    physics = mjcf.Physics.from_mjcf_model(mjcf_model)
    _save(physics, directory, key)
    return physics


def model_key(mjcf_model) -> str:
    """Hash of everything the compiled model depends on."""
    digest = hashlib.blake2b(mujoco.__version__.encode() + b"\0"
                             + mjcf_model.to_xml_string().encode())
    assets = mjcf_model.get_assets()
    for name in sorted(assets):
        contents = assets[name]
        digest.update(b"\0" + name.encode() + b"\0")
        digest.update(contents.encode() if isinstance(contents, str) else contents)
    return digest.hexdigest()[:_DIGEST_CHARS]


def _content_digest(data: bytes) -> str:
    return hashlib.blake2b(data).hexdigest()[:_DIGEST_CHARS]


def _load_verified(path: pathlib.Path) -> mjcf.Physics | None:
    """The model in `path` if its bytes match the digest in its name; else None (and the
    file deleted, where it can be)."""
    try:
        data = path.read_bytes()
    except OSError as error:
        logging.warning("cannot read compiled model %s (%s): compiling instead", path, error)
        return None
    if _content_digest(data) != path.name.split(".")[1]:
        logging.warning("compiled model %s was changed on disk: rebuilding it", path)
        _remove(path)
        return None
    try:
        model = mujoco.MjModel.from_binary_path(path.name, {path.name: data})
    except Exception as error:  # pylint: disable=broad-except  # A file MuJoCo refuses.
        logging.warning("compiled model %s does not load (%s): rebuilding it", path, error)
        _remove(path)
        return None
    try:
        os.utime(path)  # Recently used: evicted last. A hint only (read-only caches).
    except OSError:
        pass
    return mjcf.Physics.from_model(wrapper.MjModel(model))


def _save(physics: mjcf.Physics, directory: pathlib.Path, key: str) -> None:
    model = physics.model.ptr
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    data = buffer.tobytes()
    path = directory / f"{key}.{_content_digest(data)}.mjb"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        handle, partial = tempfile.mkstemp(dir=directory, prefix=f"{key}.", suffix=".partial")
        try:
            with os.fdopen(handle, "wb") as file:
                file.write(data)
            os.replace(partial, path)  # Atomic: readers see the whole file or none.
        except BaseException:
            _remove(pathlib.Path(partial))
            raise
        for other in directory.glob(f"{key}.*.mjb"):
            if other != path:
                _remove(other)
        _sweep(directory)
    except OSError as error:
        if directory not in _UNWRITABLE:  # Once: every env made would say it again.
            _UNWRITABLE.add(directory)
            logging.warning("could not cache compiled models in %s (%s): each new env "
                            "compiles its model (~1 s); said once", directory,
                            "it is a file, not a folder" if directory.is_file() else error)


def _sweep(directory: pathlib.Path) -> None:
    """Deletes temporary files of killed writers and the least recently used models."""
    now = time.time()
    for partial in directory.glob("*.partial"):
        try:
            if now - partial.stat().st_mtime > STALE_PARTIAL_SECONDS:
                partial.unlink()
        except OSError:
            pass  # Renamed or removed by its writer meanwhile.
    models = []
    for path in directory.glob("*.mjb"):
        try:
            models.append((path.stat().st_mtime, path))
        except OSError:
            pass
    for _, stale in sorted(models, reverse=True)[MAX_CACHED_MODELS:]:
        _remove(stale)


def _remove(path: pathlib.Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass
