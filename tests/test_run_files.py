"""A run's files (training/run_files.py, runs.py): every refusal comes before the run
directory exists, the final model is written in one step, and a damaged file is named
(or, for model.zip, passed over for the final checkpoint)."""

from __future__ import annotations

import json
import pathlib
import re

import pytest

from franka_composer import cli
from franka_composer.atomic_files import folders_made_for, replace_atomically, replace_together
from franka_composer.training.runs import RunDir, read_eval_rows

#: Small enough for seconds per run; learning starts after two 50-step episodes.
TINY = ["--net-arch", "16,16", "--batch-size", "32", "--buffer-size", "2000",
        "--learning-starts", "100", "--eval-every", "100", "--eval-episodes", "1",
        "--threads", "1", "--no-progress", "--device", "cpu"]


def _train(out, steps, *extra):
    return cli.main(["train", "--task", "push", "--algo", "sac", "--seed", "1",
                     "--out", str(out), "--total-steps", str(steps), *TINY, *extra])


@pytest.mark.parametrize("extra, message", [
    # 70: SB3's HER buffer dropped the first episode as the second overwrote it, and the
    # next gradient step failed in a traceback (and so did every resume of the run).
    *[(["--buffer-size", size], f"--buffer-size {size} holds less than two push episodes "
                                "(50 steps each): HER samples finished episodes, and one must "
                                "stay whole while the next is written: give 99 or more")
      for size in ("40", "70", "98")],
    (["--device", "cuda"], "--device cuda, but torch sees no CUDA GPU"),
])
def test_a_run_train_cannot_start_is_refused_before_its_directory_exists(tmp_path,
                                                                         monkeypatch, extra,
                                                                         message):
    """Else a rerun said the directory already held a run, and --resume that it had no
    checkpoint."""
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ValueError, match=re.escape(message)):
        _train(tmp_path / "run", 100, *extra)
    assert not (tmp_path / "run").exists()


def test_a_buffer_of_two_episodes_less_a_step_trains_past_its_wrapping(tmp_path):
    """The least --buffer-size train takes: 300 steps wrap a 99-step buffer three times, and
    every gradient step finds a finished episode to sample."""
    assert _train(tmp_path / "run", 300, "--buffer-size", "99") == 0
    assert json.loads((tmp_path / "run" / "outcome.json").read_text())["steps"] == 300


def test_a_sweep_checks_what_it_forwards_to_train_before_ray_starts(tmp_path, monkeypatch):
    """Each cell's train options, --timing among them, are read by train's parser and
    checked as train checks them: a missing dataset is refused before any cell runs."""
    from franka_composer.cli import sweep

    def no_ray(*args, **kwargs):
        raise AssertionError("Ray was started")

    monkeypatch.setattr("franka_composer.training.sweep.run_sweep", no_ray)
    out = tmp_path / "sweep"
    base = ["sweep", "--out", str(out), "--tasks", "push", "--algos", "sac", "--seeds", "0",
            "1", "--steps", "100", "--", "--timing", "reference"]
    with pytest.raises(ValueError, match=re.escape(f"{tmp_path / 'missing.npz'} does not "
                                                   "exist")):
        cli.main([*base, "--demos", str(tmp_path / "missing.npz")])
    with pytest.raises(ValueError, match="--buffer-size 40 holds less than two push episodes"):
        cli.main([*base, "--buffer-size", "40"])
    assert not out.exists()
    # The options the grid gives its cells pass, --timing's settings among them.
    cells, _ = sweep.cells_of(cli.build_parser().parse_args(base[:-3]))
    sweep.check_cells(cells, out, ("--timing", "reference"))
    assert sweep.cell_config(cells[0], out, ("--timing", "reference")).control_timestep == 0.5


def test_a_file_written_in_one_step_is_whole_or_as_it_was(tmp_path):
    path = tmp_path / "model.zip"
    path.write_bytes(b"the model before")

    def killed_while_writing(partial: pathlib.Path) -> None:
        partial.write_bytes(b"half of the")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        replace_atomically(path, killed_while_writing)
    assert path.read_bytes() == b"the model before"
    replace_atomically(path, lambda partial: partial.write_bytes(b"the model after"))
    assert path.read_bytes() == b"the model after"
    assert [p.name for p in tmp_path.iterdir()] == ["model.zip"]


def test_files_that_go_together_land_together_or_not_at_all(tmp_path):
    video, frame = tmp_path / "push.mp4", tmp_path / "push.png"
    video.write_bytes(b"the video before")
    frame.write_bytes(b"the frame before")

    def killed_while_writing(partial: pathlib.Path) -> None:
        partial.write_bytes(b"half of the")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        replace_together({frame: lambda partial: partial.write_bytes(b"the frame after"),
                          video: killed_while_writing})
    assert (frame.read_bytes(), video.read_bytes()) == (b"the frame before",
                                                         b"the video before")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["push.mp4", "push.png"]
    replace_together({frame: lambda partial: partial.write_bytes(b"the frame after"),
                      video: lambda partial: partial.write_bytes(b"the video after")})
    assert (frame.read_bytes(), video.read_bytes()) == (b"the frame after",
                                                         b"the video after")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["push.mp4", "push.png"]


def test_files_that_cannot_land_together_are_refused_before_any_is_written(tmp_path):
    """Two names of one file wrote the second's bytes into the next file's place; a folder
    where the second was to go let the first land alone."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "push.mp4").mkdir()
    writes = []

    def write(partial: pathlib.Path) -> None:
        writes.append(partial)
        partial.write_bytes(b"x")

    with pytest.raises(ValueError, match=re.escape(
            f"cannot write to {tmp_path / 'sub' / '..' / 'a.txt'} twice at once: it is "
            f"{tmp_path / 'a.txt'}, given already")):
        replace_together({tmp_path / "a.txt": write, tmp_path / "sub" / ".." / "a.txt": write})
    with pytest.raises(ValueError, match=re.escape(
            f"cannot write to {tmp_path / 'push.mp4'}: it is a folder")):
        replace_together({tmp_path / "push.png": write, tmp_path / "push.mp4": write})
    assert writes == [] and sorted(p.name for p in tmp_path.iterdir()) == ["push.mp4", "sub"]


def test_the_folders_made_for_a_file_go_if_it_does_not_land(tmp_path):
    (tmp_path / "there").mkdir()
    path = tmp_path / "there" / "new" / "newer" / "table.md"
    with pytest.raises(KeyboardInterrupt), folders_made_for(path):
        assert path.parent.is_dir()
        raise KeyboardInterrupt
    assert [p.name for p in tmp_path.rglob("*")] == ["there"]
    # A folder made that holds something by then is left, with the folders above it.
    with pytest.raises(KeyboardInterrupt), folders_made_for(path):
        (path.parent / "another.md").write_text("kept")
        raise KeyboardInterrupt
    assert (path.parent / "another.md").read_text() == "kept"
    with folders_made_for(tmp_path / "other" / "table.md"):
        replace_atomically(tmp_path / "other" / "table.md", lambda p: p.write_text("x"))
    assert (tmp_path / "other" / "table.md").read_text() == "x"


@pytest.mark.parametrize("name, content, message", [
    ("outcome.json", b"{\"steps\": 3", "is not a run's outcome: Expecting"),
    ("eval.csv", b"steps,wall_time_s,success_rate,mean_reward\n0,1,\xff\xfe,0\n",
     "is not an eval.csv (damaged?): it is not UTF-8 text"),
])
def test_a_damaged_run_file_is_named(tmp_path, name, content, message):
    run = RunDir(tmp_path / "run")
    run.root.mkdir()
    (run.root / name).write_bytes(content)
    with pytest.raises(ValueError, match=re.escape(f"{run.root / name} {message}")):
        run.read_outcome() if name == "outcome.json" else read_eval_rows(run.eval_csv)


def test_a_garbage_checkpoint_state_is_named_and_never_recovered(tmp_path):
    run = RunDir(tmp_path / "run")
    run.root.mkdir()
    folder = run.new_checkpoint(100)
    (folder / "state.json").write_text(json.dumps({"steps": 100}))
    run.publish_checkpoint(folder)
    assert run.read_state() == {"steps": 100}
    run.checkpoint_state.write_bytes(b"\xff\xfe garbage")
    with pytest.raises(ValueError, match=re.escape(f"{run.checkpoint_state} is not a "
                                                   "checkpoint's state: 'utf-8' codec")):
        run.read_state()
    # A stop between moving a folder aside and linking: only a whole state file counts.
    run.checkpoint.unlink()
    for index, text in enumerate(("garbage", json.dumps({"steps": 50}), "[1]")):
        (run.root / f"checkpoint-{index}-x").mkdir()
        (run.root / f"checkpoint-{index}-x" / "state.json").write_text(text)
    run.recover_checkpoint()
    assert run.checkpoint.resolve().name == "checkpoint-1-x"


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A 200-step run, finished: model.zip and its final checkpoint."""
    out = tmp_path_factory.mktemp("runs") / "run"
    assert _train(out, 200) == 0
    return RunDir(out)


def _copy_run(run: RunDir, destination: pathlib.Path) -> RunDir:
    import shutil

    shutil.copytree(run.root, destination, symlinks=True)
    return RunDir(destination)


def _success_line(capsys):
    return [line for line in capsys.readouterr().out.splitlines() if "success" in line][0]


@pytest.mark.slow
def test_evaluate_passes_over_a_damaged_model_zip_for_the_final_checkpoint(finished,
                                                                           tmp_path, capsys):
    assert cli.main(["evaluate", str(finished.root), "--episodes", "2", "--device",
                     "cpu"]) == 0
    whole = _success_line(capsys).split(": ", 1)[1]
    run = _copy_run(finished, tmp_path / "run")
    run.final_model.write_bytes(run.final_model.read_bytes()[:1000])  # Killed while writing.
    with pytest.warns(RuntimeWarning, match=re.escape(
            f"{run.final_model} is damaged (not a readable zip archive: ") + ".*" + re.escape(
            f"using the latest checkpoint, {run.checkpoint_model}")):
        assert cli.main(["evaluate", str(run.root), "--episodes", "2", "--device",
                         "cpu"]) == 0
    assert _success_line(capsys).split(": ", 1)[1] == whole  # The same model, 200 steps.
    (run.checkpoint_model).write_bytes(b"")
    # The policy file is the same actor: what a committed run plays.
    with pytest.warns(RuntimeWarning, match=re.escape(
            f"{run.checkpoint_model} is damaged (not a readable zip archive") + ".*" + re.escape(
            f"using its policy file, {run.policy_file}")):
        assert cli.main(["evaluate", str(run.root), "--episodes", "2", "--device",
                         "cpu"]) == 0
    assert _success_line(capsys).split(": ", 1)[1] == whole
    run.policy_file.unlink()
    with pytest.raises(ValueError, match=re.escape(f"{run.checkpoint_model} is damaged "
                                                   "(not a readable zip archive")):
        cli.main(["evaluate", str(run.root), "--episodes", "2", "--device", "cpu"])


def test_evaluate_leaves_out_a_run_with_nothing_trained_yet_and_names_it(tmp_path, capsys,
                                                                        monkeypatch):
    """A run still training before its first checkpoint (config.json and eval.csv, no
    model; a sweep under way) among finished ones: `evaluate` plays the others and names it
    (it refused them all, as `report` and `plot` did). Alone, it is refused before any env
    is made; a run that ended with nothing to play is refused too."""
    import shutil

    from franka_composer.training import policy_file

    kept = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-ddpg-seed1"
    training = tmp_path / "push-ddpg-seed2"
    training.mkdir()
    shutil.copy(kept / "eval.csv", training / "eval.csv")
    config = json.loads((kept / "config.json").read_text())
    (training / "config.json").write_text(json.dumps({**config, "seed": 2}))
    assert cli.main(["evaluate", str(kept), str(training), "--episodes", "2", "--device",
                     "cpu"]) == 0
    printed = capsys.readouterr()
    assert printed.err == (f"left out: {training} has nothing trained yet (no model.zip, no "
                           "checkpoint, no policy.pt)\n")
    assert printed.out.startswith(f"{kept}: push ddpg seed 1, ")
    assert str(training) not in printed.out
    made = []
    monkeypatch.setattr(policy_file, "make_env", lambda *args, **kwargs: made.append(args))
    with pytest.raises(ValueError, match=re.escape(
            f"nothing trained yet in {training} (no model.zip, no checkpoint, no policy.pt)")):
        cli.main(["evaluate", str(training), "--episodes", "2", "--device", "cpu"])
    shutil.copy(kept / "outcome.json", training / "outcome.json")  # Ended: nothing to play.
    with pytest.raises(ValueError, match=re.escape(
            f"{training} has ended (outcome.json) and was kept without its model (no "
            "model.zip, no checkpoint, no policy.pt)")):
        cli.main(["evaluate", str(kept), str(training), "--episodes", "2", "--device", "cpu"])
    assert made == [] and "success" not in capsys.readouterr().out


@pytest.mark.parametrize("name", ["policy.pt", "model.zip", "checkpoint/model.zip"])
def test_evaluate_names_a_folder_where_a_model_file_belongs(tmp_path, name, monkeypatch):
    """A folder at policy.pt (a copy gone wrong) read as no policy.pt: the kept run was
    called one kept without its model, and a run without outcome.json one not trained
    yet, left out of `evaluate` with a word. Now refused, naming the folder, before any
    env is made."""
    import shutil

    from franka_composer.training import policy_file

    kept = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-ddpg-seed1"
    for ended in (True, False):
        run = tmp_path / f"push-ddpg-seed1-{ended}"
        shutil.copytree(kept, run)
        (run / "policy.pt").unlink()
        if not ended:
            (run / "outcome.json").unlink()
        (run / name).mkdir(parents=True)
        made = []
        monkeypatch.setattr(policy_file, "make_env",
                            lambda *args, **kwargs: made.append(args))
        with pytest.raises(ValueError, match=re.escape(
                f"{run / name} is a folder, where {run} keeps a model file: move it "
                "away")):
            cli.main(["evaluate", str(run), "--episodes", "2", "--device", "cpu"])
        assert made == []


@pytest.mark.slow
def test_a_kill_while_the_final_model_is_written_leaves_no_damaged_model_zip(tmp_path,
                                                                             monkeypatch):
    from stable_baselines3 import SAC

    out = tmp_path / "run"
    save = SAC.save

    def killed_in_the_run_directory(model, path, *args, **kwargs):
        if pathlib.Path(path).parent == out:  # The final model, not a checkpoint's.
            pathlib.Path(path).write_bytes(b"PK\x03\x04 half")
            raise KeyboardInterrupt
        return save(model, path, *args, **kwargs)

    monkeypatch.setattr(SAC, "save", killed_in_the_run_directory)
    assert _train(out, 100) == 130  # As Ctrl-C there ends it.
    run = RunDir(out)
    assert not run.final_model.exists()
    assert run.best_model() == run.checkpoint_model


def _longest_length_past_memory(content: bytes) -> bytes:
    """`content`, a pickle, with the highest bit of its first BYTEARRAY8's 8-byte length
    set: a length past any memory (the unpickler asked for it before reading)."""
    import pickletools

    at = next(position for opcode, _, position in pickletools.genops(content)
              if opcode.name == "BYTEARRAY8")
    damaged = bytearray(content)
    damaged[at + 8] |= 0x80
    return bytes(damaged)


@pytest.mark.slow
@pytest.mark.parametrize("name, damage, message", [
    ("replay_buffer.pkl", lambda b: b[:len(b) // 2], "is damaged (truncated or not what a "
                                                     "checkpoint writes): UnpicklingError"),
    ("replay_buffer.pkl", _longest_length_past_memory, "is damaged (truncated or not what a "
                                                       "checkpoint writes): OverflowError"),
    ("generators.pkl", lambda b: b"", "is damaged (truncated or not what a checkpoint "
                                      "writes): EOFError"),
    ("model.zip", lambda b: b"garbage", "is damaged (not a readable zip archive"),
])
def test_a_resume_names_the_damaged_checkpoint_file(finished, tmp_path, name, damage,
                                                    message):
    """As read from a checkpoint written before its files' digests (none in state.json):
    what the unpicklers and the zip reader raise is named by the file."""
    run = _copy_run(finished, tmp_path / "run")
    state = json.loads(run.checkpoint_state.read_text())
    del state["sha256"]
    run.checkpoint_state.write_text(json.dumps(state))
    path = run.checkpoint / name
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ValueError, match=re.escape(str(path)) + " " + re.escape(message)):
        cli.main(["train", "--resume", "--out", str(run.root), "--total-steps", "300",
                  "--no-progress", "--device", "cpu"])
    assert run.read_state()["steps"] == 200  # Left as it was.


def test_evaluate_finds_a_run_with_only_a_damaged_model_before_playing_any(tmp_path, capsys,
                                                                          monkeypatch):
    """Every run is checked before the first is played: one whose only model is damaged
    (no checkpoint, no policy file) is refused, by its file, before the whole ones play."""
    import shutil

    from franka_composer.training import policy_file

    kept = pathlib.Path(__file__).parents[1] / "results" / "table2" / "push-ddpg-seed1"
    damaged = tmp_path / "push-ddpg-seed2"
    damaged.mkdir()
    for name in ("eval.csv", "outcome.json"):
        shutil.copy(kept / name, damaged / name)
    config = json.loads((kept / "config.json").read_text())
    (damaged / "config.json").write_text(json.dumps({**config, "seed": 2}))
    (damaged / "model.zip").write_bytes(b"")
    made = []
    monkeypatch.setattr(policy_file, "make_env", lambda *args, **kwargs: made.append(args))
    with pytest.raises(ValueError, match=re.escape(
            f"{damaged / 'model.zip'} is damaged (not a readable zip archive: ") + ".*"
            + re.escape("and the run has no whole model to play instead")):
        cli.main(["evaluate", str(kept), str(damaged), "--episodes", "2", "--device", "cpu"])
    assert made == [] and "success" not in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("name", ["replay_buffer.pkl", "generators.pkl", "model.zip"])
def test_a_resume_refuses_a_checkpoint_file_changed_since_by_its_digest(finished, tmp_path,
                                                                        name):
    """One flipped bit in a pickle's data unpickled as another replay buffer or other
    generators' states, and the run went on as an exact resume: each file's SHA-256, kept
    in state.json, is checked before anything is unpickled."""
    run = _copy_run(finished, tmp_path / "run")
    assert set(run.read_state()["sha256"]) == {"generators.pkl", "model.zip",
                                               "replay_buffer.pkl"}
    path = run.checkpoint / name
    content = bytearray(path.read_bytes())
    content[len(content) // 2] ^= 0x01
    path.write_bytes(bytes(content))
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{path} is not the file its checkpoint wrote (its SHA-256 differs from the one "
            "in state.json): damaged since") + "$"):
        cli.main(["train", "--resume", "--out", str(run.root), "--total-steps", "300",
                  "--no-progress", "--device", "cpu"])
    assert run.read_state()["steps"] == 200 and run.final_model.is_file()  # As it was.


def test_a_checkpoint_state_whose_digests_are_not_file_names_is_refused(finished, tmp_path):
    run = _copy_run(finished, tmp_path / "run")
    state = json.loads(run.checkpoint_state.read_text())
    run.checkpoint_state.write_text(json.dumps({**state, "sha256": {"../config.json": "0"}}))
    with pytest.raises(ValueError, match=re.escape(
            f"{run.checkpoint_state} is not a checkpoint's state (edited or damaged?): its "
            "sha256 must map the checkpoint's file names to digests, got {'../config.json': "
            "'0'}")):
        run.read_state()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["replay_buffer.pkl", "model.zip"])
def test_a_resume_names_a_missing_checkpoint_file(finished, tmp_path, name):
    """SB3 raised an OSError naming replay_buffer.pkl.pkl; a missing model.zip was said to
    be damaged ("not a readable zip archive: [Errno 2] No such file ...")."""
    run = _copy_run(finished, tmp_path / "run")
    (run.checkpoint / name).unlink()
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{run.checkpoint / name} is missing: a checkpoint cannot be resumed without it")
            + "$"):
        cli.main(["train", "--resume", "--out", str(run.root), "--total-steps", "300",
                  "--no-progress", "--device", "cpu"])
    assert run.read_state()["steps"] == 200 and run.final_model.is_file()  # As it was.


@pytest.mark.slow
@pytest.mark.parametrize("edit, says", [
    ({"algo": "ddpg"}, "algo ddpg, backend sb3 (a model of stable_baselines3.td3)"),
    ({"backend": "sbx"}, "algo sac, backend sbx (a model of sbx.sac)"),
])
def test_a_model_of_another_algorithm_or_library_than_config_json_says_is_named(
        finished, tmp_path, monkeypatch, edit, says):
    """A config.json edited to another algo or backend than the run's model was trained
    with met an AttributeError from inside SB3's load, after the env was built."""
    from franka_composer.training import policy_file

    run = _copy_run(finished, tmp_path / "run")
    config = json.loads(run.config_path.read_text())
    run.config_path.write_text(json.dumps({**config, **edit}))
    made = []
    monkeypatch.setattr(policy_file, "make_env", lambda *args, **kwargs: made.append(args))
    # Its checkpoint's record of the settings names the edit first; without one (a
    # checkpoint from before it was recorded), the model itself does.
    with pytest.raises(ValueError, match=re.escape(
            f"{run.config_path} says other than the settings the run's checkpoint")):
        cli.main(["evaluate", str(run.root), "--episodes", "1", "--device", "cpu"])
    state = json.loads(run.checkpoint_state.read_text())
    del state["config"]
    run.checkpoint_state.write_text(json.dumps(state))
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{run.final_model} holds a model of stable_baselines3.sac, and its run's "
            f"config.json says {says}: put them back as the run was trained") + "$"):
        cli.main(["evaluate", str(run.root), "--episodes", "1", "--device", "cpu"])
    assert made == []  # Before an env was built.
