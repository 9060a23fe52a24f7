"""`franka-composer demo` and `rollout` run end to end and explain every option."""

from __future__ import annotations

import pathlib
import re
import time

import imageio.v2 as imageio
import pytest

import franka_composer
from franka_composer.cli import main
from franka_composer.policies import Trajectories


@pytest.mark.slow
def test_demo_prints_its_table_and_writes_videos(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--episodes", "2", "--out", str(out), "--width", "160",
                 "--height", "120"]) == 0
    printed = capsys.readouterr().out
    assert "success rate" in printed and "env steps/s" in printed
    for task in franka_composer.ALL_TASKS:
        row = next(line for line in printed.splitlines() if line.startswith(task + " "))
        assert row.split()[1] == "2"
        assert (out / f"{task}.mp4").stat().st_size > 0
        assert imageio.imread(out / f"{task}.png").shape == (120, 160, 3)
        assert len(imageio.mimread(out / f"{task}.mp4")) > 2


def test_demo_without_video_writes_nothing(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--tasks", "push", "--episodes", "1", "--no-video",
                 "--out", str(out)]) == 0
    assert not out.exists()
    assert "push " in capsys.readouterr().out


def test_demo_runs_the_experts_at_the_timing_it_is_given(capsys):
    assert main(["demo", "--tasks", "slide", "--episodes", "2", "--no-video", "--timing",
                 "reference"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines()
               if line.startswith("slide "))
    # 0.5 s steps: the expert's strike glides the puck to the goal in ~10 steps, not ~30.
    assert row.split()[2] == "100%" and float(row.split()[3]) < 15
    with pytest.raises(ValueError, match="--timing sets the control timestep: give --timing "
                                         "or --control-timestep, not both"):
        main(["demo", "--tasks", "slide", "--no-video", "--timing", "reference",
              "--control-timestep", "0.5"])
    capsys.readouterr()
    with pytest.raises(ValueError, match="^--control-timestep must be > 0, got 0.0$"):
        main(["demo", "--tasks", "push", "slide", "--no-video", "--control-timestep", "0"])
    assert capsys.readouterr().err == ""  # Refused before the progress bar starts.


def test_rollout_command_saves_loadable_demonstrations(tmp_path, capsys):
    path = tmp_path / "sub" / "push.npz"
    assert main(["rollout", "--task", "push", "--episodes", "3", "--seed", "4",
                 "--out", str(path)]) == 0
    loaded = Trajectories.load(path)
    assert len(loaded) == 3
    assert loaded.episodes[0]["observation"].shape == (loaded.lengths[0] + 1, 18)


@pytest.mark.parametrize("out", ["sub/push.npz", "new/../sub/push.npz"])
def test_a_rollout_stopped_before_its_file_lands_leaves_no_folder_it_made(tmp_path,
                                                                         monkeypatch, out):
    """`new/../sub` made new on the way, which was not removed with sub."""
    from franka_composer import atomic_files

    def stopped(path):
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic_files, "sync_to_disk", stopped)
    with pytest.raises(KeyboardInterrupt):
        main(["rollout", "--task", "push", "--episodes", "1", "--out", f"{tmp_path}/{out}"])
    assert list(tmp_path.iterdir()) == []


def test_unknown_task_is_an_error_naming_the_valid_ones(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--tasks", "push,lift", "--no-video"])
    assert exit_info.value.code == 2
    assert f"valid tasks: {', '.join(franka_composer.ALL_TASKS)}" in capsys.readouterr().err


def test_count_options_take_whole_positive_numbers_and_name_a_bad_one(capsys):
    import argparse

    from franka_composer.cli.options import positive_int

    assert positive_int("20") == 20 and positive_int("5e5") == 500_000
    for bad in ("0", "-3", "1.5", "ten", "nan", "inf"):
        with pytest.raises(argparse.ArgumentTypeError, match=f"positive integer, got '{bad}'"):
            positive_int(bad)
    with pytest.raises(SystemExit):
        main(["evaluate", "runs/x", "--episodes", "0"])
    assert "--episodes: must be a positive integer, got '0'" in capsys.readouterr().err
    # Past int64, what steps are counted in (1e99 steps was taken, and trained on for
    # good): refused as parsed.
    assert positive_int(str(2**63 - 1)) == 2**63 - 1
    with pytest.raises(SystemExit):
        main(["train", "--task", "push", "--total-steps", "1e99", "--out", "never"])
    assert "--total-steps: must be at most 2**63 - 1 (9.22e+18), got '1e99'" in (
        capsys.readouterr().err)


@pytest.mark.parametrize("argv, message", [
    # ffmpeg wrote an empty video of an odd size, and the demo said it wrote them.
    (["--width", "33"], "--width 33: the videos are H.264 (yuv420p), whose frames have even "
                        "sizes; give an even size, or --no-video"),
    (["--width", "97", "--height", "61"], "--width 97 and --height 61: the videos"),
])
def test_demo_refuses_a_video_size_h264_cannot_take_before_any_episode(argv, message,
                                                                       tmp_path):
    with pytest.raises(ValueError, match=re.escape(message)):
        main(["demo", "--tasks", "reach", "--episodes", "1", "--out", str(tmp_path / "out"),
              *argv])
    assert not (tmp_path / "out").exists()
    assert main(["demo", "--tasks", "reach", "--episodes", "1", "--no-video", *argv]) == 0


def test_demo_refuses_a_task_twice_and_an_empty_out(tmp_path, capsys):
    with pytest.raises(SystemExit):  # Its second run wrote its files over the first's.
        main(["demo", "--episodes", "1", "--tasks", "push", "reach,push", "--out",
              str(tmp_path / "out")])
    assert ("argument --tasks: names push more than once: each task is run once"
            in capsys.readouterr().err)
    assert not (tmp_path / "out").exists()
    with pytest.raises(SystemExit):  # It wrote into the working folder.
        main(["demo", "--episodes", "1", "--out", ""])
    assert "argument --out: must be a path, got an empty one ('')" in capsys.readouterr().err


def test_demo_interrupted_while_writing_a_video_leaves_none(tmp_path, monkeypatch):
    """Ctrl-C while ffmpeg wrote push.mp4 left 48 bytes no player reads, beside the first
    frame, and in an existing folder the old video beside the new frame: a video and its
    frame are written beside their places and moved there together, or not at all, and a
    folder made for them goes with them."""
    import imageio as demo_imageio  # The module `demo` writes with.

    get_writer = demo_imageio.get_writer

    def interrupted(path, **options):
        """A writer interrupted at its third frame, once ffmpeg has begun the file."""
        writer = get_writer(path, **options)
        append, frames = writer.append_data, iter(range(2))

        def append_data(frame):
            if next(frames, None) is None:
                deadline = time.monotonic() + 10
                while not pathlib.Path(path).exists() and time.monotonic() < deadline:
                    time.sleep(0.01)
                raise KeyboardInterrupt
            append(frame)

        writer.append_data = append_data
        return writer

    out = tmp_path / "demo"
    argv = ["demo", "--tasks", "push", "--episodes", "1", "--out", str(out), "--width", "64",
            "--height", "48"]
    monkeypatch.setattr(demo_imageio, "get_writer", interrupted)
    with pytest.raises(KeyboardInterrupt):
        main(argv)
    assert not out.exists()
    monkeypatch.undo()
    assert main(argv) == 0
    assert sorted(path.name for path in out.iterdir()) == ["push.mp4", "push.png"]
    assert imageio.mimread(out / "push.mp4")[0].shape == (48, 64, 3)
    written = {path.name: path.read_bytes() for path in out.iterdir()}
    monkeypatch.setattr(demo_imageio, "get_writer", interrupted)
    with pytest.raises(KeyboardInterrupt):
        main([*argv[:-4], "--width", "32", "--height", "24"])  # Another frame.
    assert {path.name: path.read_bytes() for path in out.iterdir()} == written


def test_demo_stopped_as_ffmpeg_starts_leaves_nothing_behind(tmp_path, monkeypatch,
                                                             ctrl_c_reaches_the_process):
    """Ctrl-C as imageio started ffmpeg, before imageio could stop it again: ffmpeg ran on,
    and wrote an empty .reach.mp4.partial.mp4 into the demo's folder once the demo had
    cleaned up."""
    import signal
    import subprocess

    out = tmp_path / "demo"
    argv = ["demo", "--tasks", "reach", "--episodes", "1", "--out", str(out), "--width", "32",
            "--height", "24"]
    assert main(argv) == 0
    written = {path.name: path.read_bytes() for path in out.iterdir()}
    popen, started = subprocess.Popen, []

    def signalled_as_it_starts(command, *args, **kwargs):
        process = popen(command, *args, **kwargs)
        if "rawvideo" in command:  # ffmpeg, to write a video.
            started.append(process.pid)  # Not the process: its pipe closes as it goes.
            signal.raise_signal(signal.SIGINT)
        return process

    def ended(pid: int) -> bool:
        try:  # Gone, or a zombie (its parent has not reaped it).
            return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")")[-1].split()[0] \
                == "Z"
        except FileNotFoundError:
            return True

    monkeypatch.setattr(subprocess, "Popen", signalled_as_it_starts)
    with pytest.raises(KeyboardInterrupt):
        main([*argv[:-4], "--width", "64", "--height", "48"])  # Another frame.
    monkeypatch.undo()
    assert len(started) == 1
    deadline = time.monotonic() + 30
    while not ended(started[0]) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert ended(started[0])
    assert {path.name: path.read_bytes() for path in out.iterdir()} == written
