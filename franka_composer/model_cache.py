"""Compiled models saved on disk, so a new process skips compiling Menagerie's Panda.

Compiling the Panda (400k visual mesh vertices) takes ~1 s and ~250 MB at peak. The compiled
model is saved as an MJB file keyed by a hash of the MuJoCo version, the generated XML and
every asset's bytes, and later loads read that file: the same model, byte for byte
(`tests/test_bench.py`). The folder is `$FRANKA_COMPOSER_CACHE`, else
`$XDG_CACHE_HOME/franka_composer` (default `~/.cache/franka_composer`);
`FRANKA_COMPOSER_CACHE=off` disables it.
"""

from __future__ import annotations

import hashlib
import os
import pathlib

import mujoco
from absl import logging

from franka_composer.physics import Physics

#: Compiled models kept (each ~35 MB: the Panda's visual meshes); the least recently used
#: beyond this are deleted.
MAX_CACHED_MODELS = 8


def model_cache_dir() -> pathlib.Path | None:
    """Where compiled models are kept, or None when caching is off."""
    configured = os.environ.get("FRANKA_COMPOSER_CACHE")
    if configured is not None:
        return None if configured.lower() in ("", "0", "off", "false") else pathlib.Path(configured)
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "franka_composer"


def compile_physics(mjcf_model) -> Physics:
    """`Physics.from_mjcf_model`, through the compiled-model cache when it is on."""
    xml = mjcf_model.to_xml_string()
    assets = mjcf_model.get_assets()
    directory = model_cache_dir()
    if directory is None:
        return Physics.from_xml_string(xml, assets)
    digest = hashlib.blake2b(mujoco.__version__.encode() + b"\0" + xml.encode())
    for name in sorted(assets):
        contents = assets[name]
        digest.update(b"\0" + name.encode() + b"\0")
        digest.update(contents.encode() if isinstance(contents, str) else contents)
    path = directory / f"{digest.hexdigest()[:32]}.mjb"
    if path.is_file():
        try:
            physics = Physics.from_binary_path(str(path))
            os.utime(path)  # Recently used: evicted last.
            return physics
        except Exception as error:  # pylint: disable=broad-except
            logging.warning("ignoring unreadable compiled model %s: %s", path, error)
    physics = Physics.from_xml_string(xml, assets)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(f".{os.getpid()}.partial")
        mujoco.mj_saveModel(physics.model.ptr, str(partial), None)
        os.replace(partial, path)  # Atomic: parallel workers never read half a file.
        _evict_oldest(directory)
    except OSError as error:
        logging.warning("could not cache the compiled model in %s: %s", directory, error)
    return physics


def _evict_oldest(directory: pathlib.Path) -> None:
    models = sorted(directory.glob("*.mjb"), key=lambda p: p.stat().st_mtime, reverse=True)
    for stale in models[MAX_CACHED_MODELS:]:
        stale.unlink(missing_ok=True)
