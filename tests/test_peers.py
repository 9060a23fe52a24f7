"""benchmarks/peers.py, the speed comparison with Fetch and the reference code: it measures,
reports each ratio from the same run, skips a peer it cannot run saying so, and refuses bad
arguments before any process starts. Nothing here asserts a speed."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

from conftest import load_script

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
#: A cell of the report: the median steps/s, then the range of the rounds.
_CELL = re.compile(r"(\d+) \((\d+)–(\d+)\)")


@pytest.fixture
def peers(monkeypatch):
    """benchmarks/peers.py as a module (it imports its siblings bench and peer_worker)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    return load_script(BENCHMARKS / "peers.py")


@pytest.mark.slow
def test_a_tiny_run_times_this_suite_and_says_the_reference_is_skipped(tmp_path):
    out = tmp_path / "peers.md"
    completed = subprocess.run(
        [sys.executable, str(BENCHMARKS / "peers.py"), "--suites", "ours", "reference",
         "--tasks", "push", "slide", "--steps", "20", "--rounds", "2", "--out", str(out)],
        capture_output=True, text=True, timeout=300, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert "reference code: skipped, no --reference-path given" in completed.stderr
    rows = [line for line in completed.stdout.splitlines() if line.startswith("| ")]
    assert rows[0] == "| task | this suite |"
    assert [row.split("|")[1].strip() for row in rows[1:]] == ["push", "slide"]
    for row in rows[1:]:
        median, low, high = map(int, _CELL.fullmatch(row.split("|")[2].strip()).groups())
        assert 0 < low <= median <= high
    assert "- this suite: FrankaPushSparse-v0, FrankaSlideSparse-v0" in completed.stdout
    assert "- reference code: skipped, no --reference-path given" in completed.stdout
    assert out.read_text() == completed.stdout


def test_each_ratio_is_of_the_medians_of_the_same_run(peers):
    rates = {"ours": {"push": [900.0, 1000.0, 1300.0]},
             "ours_reference_timing": {"push": [100.0, 110.0, 90.0]},
             "fetch": {"push": [400.0, 500.0, 450.0]},
             "reference": {"push": [50.0, 40.0, 55.0]}}
    facts = {suite: {"ids": {"push": f"{suite}-v0"}} for suite in rates}
    facts["fetch"]["joint_types_as_ints"] = True
    setting = dict(command="python benchmarks/peers.py", date="today", machine="a machine",
                   load_before="1.0", load_after="2.0", versions="mujoco 3.17.0")
    report = peers.format_report(SimpleNamespace(tasks=("push",), rounds=3, steps=2000),
                                 rates, facts, {}, setting)
    row = next(line for line in report.splitlines() if line.startswith("| push"))
    assert row == ("| push | 1000 (900–1300) | 100 (90–110) | 450 (400–500) | 50 (40–55) "
                   "| 2.22 | 20.00 | 2.00 |")
    assert "- Fetch: fetch-v0" in report and "joint types as ints" in report


@pytest.mark.parametrize("arguments, message", [
    (["--tasks", "reach"], "the peers have no reach"),
    (["--suites", "fetch"], "'ours' must be among them"),
    (["--reference-path", "{tmp}"], "{tmp}: no panda_mujoco_gym/__init__.py there"),
])
def test_bad_arguments_are_refused_before_any_process_starts(peers, tmp_path, capsys,
                                                             arguments, message, monkeypatch):
    arguments = [argument.format(tmp=tmp_path) for argument in arguments]
    monkeypatch.setattr(peers.subprocess, "Popen",
                        lambda *args, **kwargs: pytest.fail("a process was started"))
    with pytest.raises(SystemExit) as exit_info:
        peers.main(arguments)
    assert exit_info.value.code == 2
    assert message.format(tmp=tmp_path) in capsys.readouterr().err


def test_fetch_resets_on_this_mujoco_once_its_joint_types_are_ints(monkeypatch):
    """Gymnasium-Robotics 1.4.2 fails every Fetch reset on mujoco >= 3.12; with the joint
    types as ints the block starts where Fetch put it (its joint's qpos)."""
    import gymnasium_robotics  # The test extra's (setup.cfg): missing, this fails.
    from gymnasium_robotics.utils import mujoco_utils

    monkeypatch.setattr(mujoco_utils, "mujoco", mujoco_utils.mujoco)  # put back afterwards
    worker = load_script(BENCHMARKS / "peer_worker.py")
    worker.joint_types_as_ints()
    gym.register_envs(gymnasium_robotics)
    env = gym.make(worker.latest_version("FetchPush"))
    observation, _ = env.reset(seed=0)
    fetch = env.unwrapped
    block = mujoco_utils.get_joint_qpos(fetch.model, fetch.data, "object0:joint")
    np.testing.assert_array_equal(observation["achieved_goal"], block[:3])
    assert observation["observation"].shape == (25,)


def test_a_peer_worker_times_with_the_bench_loop_without_importing_this_suite():
    """The reference code registers this suite's ids: its process must not import ours."""
    script = (f"import sys; sys.path.insert(0, {str(BENCHMARKS)!r}); import peer_worker; "
              "loop = peer_worker.load_timing_loop(); "
              "print(loop.__name__, loop.__module__, 'franka_composer' in sys.modules)")
    completed = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                               timeout=120, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.split() == ["random_steps_per_second", "franka_composer_speed",
                                        "False"]
