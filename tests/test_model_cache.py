"""The compiled-model cache: byte-identical models, verified contents, read-only caches,
parallel writers and leftovers of killed ones."""

from __future__ import annotations

import os
import threading
import time

import mujoco
import numpy as np
import pytest
from absl import logging

from franka_composer import model_cache
from franka_composer.model_cache import compile_physics
from dm_control import mjcf
from franka_composer.tasks import build_task, task_config


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("FRANKA_COMPOSER_CACHE", str(tmp_path))
    return tmp_path


@pytest.fixture
def root():
    """A push task's MJCF without the Panda's visual meshes (quick to compile)."""
    return build_task(task_config("push"), renderable=False).root_entity.mjcf_model


def _model_bytes(model: mujoco.MjModel) -> bytes:
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


@pytest.fixture
def warnings_logged(monkeypatch):
    messages = []
    monkeypatch.setattr(logging, "warning", lambda message, *args: messages.append(
        message % args))
    return messages


def test_cached_model_is_byte_identical_to_a_fresh_compile(cache, monkeypatch):
    full = build_task(task_config("push")).root_entity.mjcf_model
    compiled = compile_physics(full)  # Compiles, then writes the cache.
    assert len(list(cache.glob("*.mjb"))) == 1
    with monkeypatch.context() as patched:
        patched.setattr(mjcf.Physics, "from_mjcf_model",
                        classmethod(lambda cls, model: pytest.fail("compiled again")))
        cached = compile_physics(full)  # Reads the cache.
    assert _model_bytes(cached.model.ptr) == _model_bytes(compiled.model.ptr)
    monkeypatch.setenv("FRANKA_COMPOSER_CACHE", "off")
    assert _model_bytes(compile_physics(full).model.ptr) == _model_bytes(compiled.model.ptr)


def test_a_cached_model_changed_on_disk_is_rebuilt(cache, root, warnings_logged):
    """Issue 10: a cached model whose timestep changed from 0.002 to 0.0025 still loads; it
    must not be used."""
    assert compile_physics(root).model.opt.timestep == 0.002
    (path,) = cache.glob("*.mjb")
    tampered = mujoco.MjModel.from_binary_path(str(path))
    tampered.opt.timestep = 0.0025
    mujoco.mj_saveModel(tampered, str(path), None)  # Same name, different bytes.
    physics = compile_physics(root)
    assert physics.model.opt.timestep == 0.002
    assert any("changed on disk" in m for m in warnings_logged)
    (rebuilt,) = cache.glob("*.mjb")
    assert mujoco.MjModel.from_binary_path(str(rebuilt)).opt.timestep == 0.002


def test_a_readable_cached_model_that_cannot_be_touched_is_used(cache, root, monkeypatch,
                                                                 warnings_logged):
    compile_physics(root)

    def refuse(*args, **kwargs):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(os, "utime", refuse)
    monkeypatch.setattr(mjcf.Physics, "from_mjcf_model",
                        classmethod(lambda cls, model: pytest.fail("compiled again")))
    for _ in range(3):
        assert compile_physics(root).model.opt.timestep == 0.002
    assert warnings_logged == []


def test_threads_compiling_at_once_write_one_model_and_no_warnings(cache, root,
                                                                   warnings_logged):
    errors = []

    def work():
        try:
            compile_physics(root)
        except Exception as error:  # pylint: disable=broad-except
            errors.append(error)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == [] and warnings_logged == []
    assert len(list(cache.glob("*.mjb"))) == 1
    assert list(cache.glob("*.partial")) == []


@pytest.mark.parametrize("where", ["a file", "a folder that cannot be made"])
def test_a_cache_that_cannot_be_written_is_said_once_and_models_still_compile(
        tmp_path, root, monkeypatch, warnings_logged, where):
    """FRANKA_COMPOSER_CACHE naming a file, or a folder under one: every env made (each
    worker of a vector env, the evaluation env) logged the same warning again."""
    monkeypatch.setattr(model_cache, "_UNWRITABLE", set())
    (tmp_path / "file").write_text("not a folder")
    directory = tmp_path / "file" if where == "a file" else tmp_path / "file" / "cache"
    monkeypatch.setenv("FRANKA_COMPOSER_CACHE", str(directory))
    for _ in range(3):
        assert compile_physics(root).model.opt.timestep == 0.002
    because = "it is a file, not a folder" if where == "a file" else "[Errno 20] Not a directory"
    assert len(warnings_logged) == 1
    assert warnings_logged[0].startswith(f"could not cache compiled models in {directory} "
                                         f"({because}")
    assert warnings_logged[0].endswith("each new env compiles its model (~1 s); said once")
    assert (tmp_path / "file").read_text() == "not a folder"


def test_a_killed_writers_leftover_is_swept_and_a_live_one_is_kept(cache, root):
    stale = cache / "0123.abcd.partial"
    stale.write_bytes(b"\0" * 1000)
    hour_and_a_bit = time.time() - model_cache.STALE_PARTIAL_SECONDS - 60
    os.utime(stale, (hour_and_a_bit, hour_and_a_bit))
    live = cache / "4567.efgh.partial"
    live.write_bytes(b"\0" * 1000)
    compile_physics(root)  # Saves, and sweeps.
    assert not stale.exists() and live.exists()


def test_a_cache_miss_keeps_dm_controls_readable_compile_errors(cache, root):
    root.worldbody.add("geom", name="broken", type="mesh", mesh=None)  # A mesh geom w/o mesh.
    with pytest.raises(ValueError) as error:
        compile_physics(root)
    # dm_control's form: MuJoCo's error, then the element and its MJCF.
    message = str(error.value)
    assert message.startswith("Compile error raised by Mujoco")
    assert "Error: mesh geom 'broken' (id = 1) must have valid meshid\n" in message
    assert message.endswith('\n<geom name="broken" class="/" type="mesh"/>')
