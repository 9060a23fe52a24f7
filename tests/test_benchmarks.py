"""The benchmark tooling reports every figure, and its bare-MuJoCo baseline simulates exactly
what the env simulates. Nothing here is timed."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

from conftest import load_script
from franka_composer.adapters.registration import env_id
from franka_composer.cli import main

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
_RUN_FIGURES = ("steps_per_s_resets_included", "steps_per_s_resets_excluded",
                "floor_steps_per_s", "overhead_ratio")



@pytest.mark.slow
def test_the_full_benchmark_writes_every_figure(tmp_path):
    out = tmp_path / "results.json"
    completed = subprocess.run(
        [sys.executable, str(BENCHMARKS / "bench.py"), "--tasks", "push", "--steps", "60",
         "--reset-samples", "3", "--render-frames", "2", "--cold-start-samples", "1",
         "--vector-workers", "1", "--memory-envs", "2", "--out", str(out)],
        capture_output=True, text=True, timeout=600, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    results = json.loads(out.read_text())
    assert {"python", "mujoco", "dm-control", "gymnasium"} <= set(results["versions"])
    assert results["machine"]["nproc"] >= 1
    push = results["tasks"]["push"]
    assert push["env_id"] == "FrankaPushSparse-v0"
    for run in ("random", "expert"):
        assert push[run]["steps"] == 60
        for figure in _RUN_FIGURES:
            assert push[run][figure] > 0, (run, figure)
        # The baseline replays the same episodes with the same MuJoCo calls.
        assert push[run]["floor_mean_contacts"] == push[run]["mean_contacts"]
    for figure in ("reset_ms_median", "compute_reward_1024_us", "peak_rss_mb"):
        assert push[figure] > 0, figure
    assert push["render"]["ms_per_frame"] > 0
    assert push["cold_start"]["median_s"] > 0 and push["cold_start"]["uncached_s"] > 0
    assert push["vector_steps_per_s"]["1"] > 0
    lean, full = push["memory"]["none"], push["memory"]["rgb_array"]
    assert lean["envs"] == full["envs"] == 3
    # Measured 20 and 71 MB: the visual meshes are most of an env.
    assert 0 < lean["per_additional_env_mb"] < full["per_additional_env_mb"]
    assert "| push |" in completed.stdout and str(out) in completed.stdout
    assert "| vector 1 workers |" in completed.stdout  # The workers measured, not "1 / 2".


def test_the_benchmark_refuses_an_out_it_cannot_write_before_measuring(tmp_path, capsys):
    """It measured everything, then failed to write (a folder, a path under a file)."""
    bench = load_script(BENCHMARKS / "bench.py")
    (tmp_path / "file").write_text("")
    under_a_file = tmp_path / "file" / "r.json"
    for out, refusal in [(tmp_path, f"must be a file, got the folder '{tmp_path}'"),
                         (under_a_file, f"cannot write to {under_a_file}: "
                                        f"{tmp_path / 'file'} is not a folder")]:
        with pytest.raises(SystemExit):
            bench.build_parser().parse_args(["--out", str(out)])
        assert f"argument --out: {refusal}\n" in capsys.readouterr().err


def test_the_quick_bench_command_times_each_task(capsys):
    assert main(["bench", "--tasks", "push", "slide", "--steps", "50"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert [row.split("|")[1].strip() for row in rows[1:]] == ["push", "slide"]
    assert all(float(row.split("|")[2]) > 0 and float(row.split("|")[3]) > 0
               for row in rows[1:])


def test_bench_rejects_an_unknown_task_naming_the_valid_ones(capsys):
    with pytest.raises(SystemExit) as exit:
        main(["bench", "--tasks", "lift"])
    assert exit.value.code == 2
    assert capsys.readouterr().err.endswith(
        "argument --tasks: unknown task(s) lift; valid tasks: push, slide, pick_and_place, "
        "reach, stack, flip\n")


@pytest.mark.parametrize("task", ["push", "stack", "flip"])
def test_compute_reward_is_timed_on_goals_the_task_takes(task):
    """Positions, two blocks' six coordinates, flip's unit quaternions (its compute_reward
    refuses others, which failed `bench.py` on its default tasks)."""
    measure = load_script(BENCHMARKS / "measure.py")
    env = gym.make(env_id(task, "sparse"))
    assert measure.compute_reward_us(env, batch=8) > 0


@pytest.mark.parametrize("control", ["mocap", "osc", "joints"])
def test_the_baseline_follows_the_env_trajectory_bit_for_bit(control):
    """Same model, start state, actions, action law and MuJoCo calls: the baseline ends
    exactly where the env ends (one code path, one machine)."""
    measure = load_script(BENCHMARKS / "measure.py")
    env = gym.make("FrankaPickAndPlaceSparse-v0", control=control)
    env.reset(seed=1)
    physics = env.unwrapped.composer_env.physics
    episode = measure.Episode(measure._snapshot(physics.model.ptr, physics.data.ptr))
    rng = np.random.default_rng(0)
    for _ in range(20):
        action = rng.uniform(-1, 1, env.action_space.shape)
        env.step(action.astype(np.float32))
        episode.actions.append(action.astype(np.float32).astype(np.float64))
    baseline = measure.BareMujocoBaseline(env)
    seconds, contacts = baseline.replay(episode)
    assert seconds > 0 and contacts > 0
    np.testing.assert_array_equal(baseline.data.qpos, physics.data.qpos)
    np.testing.assert_array_equal(baseline.data.qvel, physics.data.qvel)


def test_the_timestep_study_writes_its_table_against_the_finest_step(tmp_path):
    study = load_script(BENCHMARKS / "timestep_study.py")
    assert study.main(["--episodes", "1", "--tasks", "reach", "--out", str(tmp_path)]) == 0
    import csv

    with open(tmp_path / "timestep-study.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["policy"], float(r["timestep_ms"]), int(r["substeps"])) for r in rows] == [
        (policy, ms, substeps) for policy in ("expert", "random")
        for ms, substeps in ((2.0, 25), (1.0, 50), (0.5, 100))]
    finest = [r for r in rows if float(r["timestep_ms"]) == 0.5]
    assert all(float(r["final_position_diff_max_mm"]) == 0.0 for r in finest)
    # The same random actions at 2 ms end the hand elsewhere, by millimetres, not metres.
    coarse = next(r for r in rows if r["policy"] == "random" and r["substeps"] == "25")
    assert 0.0 < float(coarse["final_position_diff_max_mm"]) < 50.0
    assert (tmp_path / "timestep-study.md").read_text().count("| reach |") == 6


def test_the_timestep_study_reads_a_resting_blocks_weight_on_the_floor():
    """A 1 kg block resting on the floor: four corner contacts share its 9.81 N, and the
    stiff contacts (contacts.py) leave it tens of microns deep (0.04 mm measured)."""
    study = load_script(BENCHMARKS / "timestep_study.py")
    env = gym.make("FrankaPushSparse-v0")
    peaks = study.ContactPeaks(env.unwrapped.composer_env)
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(3, np.float32))
    assert 9.81 / 4 * 0.9 < peaks.force < 9.81
    assert peaks.force_pair == "world/block/"
    assert 0.0 < peaks.penetration < 1e-4


def test_the_timestep_study_refuses_an_unknown_task(capsys):
    study = load_script(BENCHMARKS / "timestep_study.py")
    with pytest.raises(SystemExit):
        study.main(["--tasks", "push,fly"])
    assert "unknown task(s) fly; valid tasks: push, slide" in capsys.readouterr().err


def test_the_timestep_study_refuses_an_out_it_cannot_write_before_measuring(tmp_path, capsys,
                                                                            monkeypatch):
    """It ran the whole study (minutes), then failed with a traceback writing it."""
    study = load_script(BENCHMARKS / "timestep_study.py")
    monkeypatch.setattr(study, "run_cell", lambda *args: pytest.fail("measured first"))
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit):
        study.main(["--tasks", "reach", "--episodes", "1", "--out", str(tmp_path / "file")])
    assert "argument --out: must be a folder, got the file" in capsys.readouterr().err


def test_the_overhead_breakdown_takes_the_shared_tasks_option_and_counts_each_tasks_reads(
        capsys, monkeypatch):
    """It took positional names, unchecked until their turn (`--help` was a task), and
    labelled every task's observation read "8 reads"."""
    overhead = load_script(BENCHMARKS / "overhead.py")
    with pytest.raises(SystemExit):
        overhead.main(["--tasks", "push,fly"])
    assert "unknown task(s) fly; valid tasks: push, slide" in capsys.readouterr().err
    monkeypatch.setattr(overhead, "best_us", lambda function, number: 1.0)  # No timing.
    assert "observables (4 reads)" in overhead.breakdown("reach")
    assert "observables (13 reads)" in overhead.breakdown("stack")


def test_the_precision_benchmark_refuses_cuda_without_a_gpu_in_one_line(capsys):
    import torch

    if torch.cuda.is_available():
        pytest.skip("a GPU is here")
    precision = load_script(BENCHMARKS / "precision.py")
    with pytest.raises(SystemExit):
        precision.main(["--device", "cuda", "--algos", "sac"])
    assert capsys.readouterr().err.endswith(
        "error: --device cuda, but torch sees no CUDA GPU (torch.cuda.is_available() is "
        "False); use --device cpu\n")


def _use_tools(repo: pathlib.Path, path: str, **environment: str):
    """What `use_tools` (benchmarks/tools.sh) sets in a checkout at `repo`, with `PATH`."""
    script = ('source benchmarks/tools.sh && use_tools && '
              'echo "$BIN|${MENAGERIE_ROOT-unset}|$OMP_NUM_THREADS"')
    return subprocess.run(["/bin/bash", "-c", script], cwd=repo, capture_output=True,
                          text=True, env={"PATH": path, **environment}, check=False)


def _bin(folder: pathlib.Path) -> pathlib.Path:
    folder.mkdir(parents=True)
    for tool in ("python", "franka-composer"):
        (folder / tool).write_text("#!/bin/sh\n")
        (folder / tool).chmod(0o755)
    return folder


def test_the_scripts_find_a_pip_installs_tools_and_leave_menagerie_to_the_package(tmp_path):
    """They ran `.venv/bin/franka-composer` (missing after a pip install: exit 127) and set
    MENAGERIE_ROOT to `../shared/menagerie` whether or not it was there, so that the
    package could neither take its cache nor download the Panda."""
    repo = tmp_path / "checkout"
    (repo / "benchmarks").mkdir(parents=True)
    (repo / "benchmarks" / "tools.sh").write_text((BENCHMARKS / "tools.sh").read_text())
    system = "/usr/bin:/bin"
    installed = _bin(tmp_path / "env" / "bin")
    done = _use_tools(repo, f"{installed}:{system}")
    assert done.stdout == f"{installed}|unset|1\n", done.stderr
    # The repository's venv first, and the copy of Menagerie beside the checkout where it
    # holds the Panda; what the user set is kept.
    venv = _bin(repo / ".venv" / "bin")
    (tmp_path / "shared" / "menagerie" / "franka_emika_panda").mkdir(parents=True)
    done = _use_tools(repo, f"{installed}:{system}")
    assert done.stdout == f"{venv}|{tmp_path / 'shared' / 'menagerie'}|1\n", done.stderr
    done = _use_tools(repo, system, BIN=str(installed), MENAGERIE_ROOT="/mine")
    assert done.stdout == f"{installed}|/mine|1\n", done.stderr
    # Nowhere: refused, saying what to do.
    done = _use_tools(repo, system, BIN=str(tmp_path / "nothing"))
    assert (done.returncode, done.stdout) == (1, "")
    assert done.stderr == (f"no franka-composer and python in {tmp_path / 'nothing'}: run "
                           "make setup, or set BIN to the bin folder of the virtualenv you "
                           "installed franka_composer into\n")
