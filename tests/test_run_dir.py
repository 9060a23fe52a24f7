"""A run's checkpoint on disk is always whole: a new one is written beside it and takes its
place in one step (training/runs.py, `RunDir.publish_checkpoint`)."""

from __future__ import annotations

import json
import os
import re
import socket

import pytest

from franka_composer.training.runs import RunDir


def _write(folder, steps, files=("model.zip", "replay_buffer.pkl")):
    for name in files:
        (folder / name).write_text(f"{name} at {steps}")
    (folder / "state.json").write_text(json.dumps({"steps": steps}))


def _checkpoint_folders(run):
    return sorted(path.name.split("-")[1] for path in run.root.glob("checkpoint-*"))


def test_a_new_checkpoint_replaces_the_latest_only_once_written_whole(tmp_path):
    run = RunDir(tmp_path / "run")
    run.root.mkdir()
    first = run.new_checkpoint(100)
    _write(first, 100)
    run.publish_checkpoint(first)
    assert run.checkpoint.is_symlink() and run.checkpoint.resolve() == first.resolve()
    assert run.read_state() == {"steps": 100}
    # Stopped while writing the next one: the latest is untouched.
    second = run.new_checkpoint(200)
    (second / "model.zip").write_text("half")
    assert run.read_state() == {"steps": 100}
    assert run.checkpoint_model.read_text() == "model.zip at 100"
    # The next checkpoint clears what the stop left, and replaces the latest.
    third = run.new_checkpoint(300)
    assert not second.exists()
    _write(third, 300)
    run.publish_checkpoint(third)
    assert run.read_state() == {"steps": 300} and _checkpoint_folders(run) == ["300"]
    assert not (run.root / "checkpoint.next").exists()


def test_a_checkpoint_is_on_the_disk_before_it_replaces_the_latest(tmp_path, monkeypatch):
    """Its files and folder are flushed before the link moves, and the run's folder (the
    link) before the old checkpoint is removed: a crash in between leaves one whole."""
    import shutil

    run = RunDir(tmp_path / "run")
    run.root.mkdir()
    first = run.new_checkpoint(100)
    _write(first, 100)
    run.publish_checkpoint(first)
    second = run.new_checkpoint(200)
    _write(second, 200)
    events = []
    fsync, replace, rmtree = os.fsync, os.replace, shutil.rmtree
    monkeypatch.setattr(os, "fsync", lambda fd: events.append(
        ("sync", os.path.realpath(f"/proc/self/fd/{fd}"))) or fsync(fd))
    monkeypatch.setattr(os, "replace", lambda a, b: events.append(("link", str(b))) or
                        replace(a, b))
    monkeypatch.setattr(shutil, "rmtree", lambda path, *a, **k: events.append(
        ("remove", str(path))) or rmtree(path, *a, **k))
    run.publish_checkpoint(second)
    link = events.index(("link", str(run.checkpoint)))
    synced = {path for kind, path in events[:link] if kind == "sync"}
    assert synced >= {str(path.resolve()) for path in [second, *second.iterdir()]}
    removed = events.index(("remove", str(first)))
    assert ("sync", str(run.root.resolve())) in events[link:removed]


def test_a_checkpoint_folder_of_a_run_from_before_is_replaced_in_the_same_way(tmp_path):
    run = RunDir(tmp_path / "run")
    run.checkpoint.mkdir(parents=True)
    _write(run.checkpoint, 50)
    written = run.new_checkpoint(100)
    assert run.read_state() == {"steps": 50}  # Kept until the new one is whole.
    _write(written, 100)
    run.publish_checkpoint(written)
    assert run.checkpoint.is_symlink() and run.read_state() == {"steps": 100}
    assert _checkpoint_folders(run) == ["100"]


def test_a_stop_between_moving_an_old_folder_aside_and_linking_is_recovered(tmp_path):
    """The one moment without RUN_DIR/checkpoint: the newest whole folder is linked again,
    an unfinished one is not taken."""
    run = RunDir(tmp_path / "run")
    (run.root / "checkpoint-0-before").mkdir(parents=True)
    _write(run.root / "checkpoint-0-before", 50)
    (run.root / "checkpoint-100-unfinished").mkdir()
    (run.root / "checkpoint-100-unfinished" / "model.zip").write_text("half")
    assert run.read_state() == {}
    run.recover_checkpoint()
    assert run.read_state() == {"steps": 50}
    (run.root / "checkpoint-100-unfinished").rename(run.root / "checkpoint-100-whole")
    _write(run.root / "checkpoint-100-whole", 100)
    run.checkpoint.unlink()
    run.recover_checkpoint()
    assert run.read_state() == {"steps": 100}
    # Nothing to recover from: nothing is made.
    empty = RunDir(tmp_path / "empty")
    empty.root.mkdir()
    empty.recover_checkpoint()
    assert not empty.checkpoint.exists() and not empty.checkpoint.is_symlink()


def test_one_process_at_a_time_trains_a_run(tmp_path):
    """A second trainer is refused, naming the first; the lock goes with the first."""
    import subprocess
    import sys

    run = RunDir(tmp_path / "run")
    holder = subprocess.Popen(
        [sys.executable, "-c", "import pathlib, sys, time\nfrom franka_composer.training.runs "
         "import RunDir\nwith RunDir(pathlib.Path(sys.argv[1])).training_lock():\n"
         "    print('held', flush=True)\n    time.sleep(60)", str(run.root)],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert run.trainer() == f"process {holder.pid} on {socket.gethostname()}"
        with pytest.raises(ValueError, match=f"{run.root} is being trained by process "
                                             f"{holder.pid} on .*: let it end, or stop it"):
            with run.training_lock():
                pass
    finally:
        holder.kill()
        holder.wait()
    assert run.trainer() is None
    with run.training_lock():  # Free again once the holder is gone, however it ended.
        pass
    assert RunDir(tmp_path / "never trained").trainer() is None


def test_a_look_at_who_trains_a_run_does_not_turn_a_trainer_away(tmp_path):
    """`sweep --status` looks at every cell's lock: a trainer starting in that moment waits
    it out (it was refused as if the run were being trained)."""
    import fcntl
    import threading

    run = RunDir(tmp_path / "run")
    run.root.mkdir()
    run.lock_path.touch()
    look = open(run.lock_path)
    fcntl.flock(look, fcntl.LOCK_SH)  # A look, caught as it holds the lock.
    threading.Timer(0.2, look.close).start()
    with run.training_lock():
        assert run.trainer() == f"process {os.getpid()} on {socket.gethostname()}"
    assert run.trainer() is None


def test_a_folder_where_the_lock_file_goes_is_named(tmp_path):
    """It was open's IsADirectoryError, naming nothing of the run."""
    run = RunDir(tmp_path / "run")
    run.lock_path.mkdir(parents=True)
    assert run.trainer() is None
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{run.lock_path} is a folder, where the run keeps its lock file (made by hand?): "
            "remove it to train the run") + "$"):
        with run.training_lock():
            pass
