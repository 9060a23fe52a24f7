"""The `franka-composer` command as a shell runs it: what it prints when the Panda cannot be
found, and how it ends when its reader has gone (`... | head`)."""

from __future__ import annotations

import os
import pathlib
import re
import signal
import subprocess
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
A_COMMITTED_RUN = REPO / "results" / "table2" / "push-sac-seed0"


def franka_composer(*argv: str, env: dict | None = None, **kwargs):
    return subprocess.run([sys.executable, "-m", "franka_composer", *argv], cwd=REPO,
                          env=env, stderr=subprocess.PIPE, text=True, **kwargs)


def test_a_reader_gone_ends_the_command_quietly_with_sigpipes_status():
    read_end, write_end = os.pipe()
    os.close(read_end)  # Every write to the pipe now fails, as after `| head` has exited.
    try:
        gone = franka_composer("report", str(A_COMMITTED_RUN), stdout=write_end)
    finally:
        os.close(write_end)
    assert (gone.returncode, gone.stderr) == (128 + signal.SIGPIPE, "")
    read = franka_composer("report", str(A_COMMITTED_RUN), stdout=subprocess.PIPE)
    assert read.returncode == 0 and "| push (bf16) | SAC | 0 | 250,000 |" in read.stdout


def test_a_demo_into_a_log_prints_its_table_and_no_progress_bar():
    """Off a terminal, its progress bar wrote a line to stderr for each update."""
    done = franka_composer("demo", "--tasks", "reach", "--episodes", "2", "--no-video",
                           stdout=subprocess.PIPE)
    assert (done.returncode, done.stderr) == (0, "")
    assert done.stdout.splitlines()[2].split()[:3] == ["reach", "2", "100%"]


def test_an_rlds_rollout_prints_its_line_and_nothing_else(tmp_path):
    """envlogger's C++ writer logged "Empty steps, nothing to do" three times on stderr,
    after glog's own "Logging before InitGoogleLogging()"."""
    recorded = franka_composer("rollout", "--task", "push", "--episodes", "2", "--format",
                               "rlds", "--out", str(tmp_path / "data"),
                               stdout=subprocess.PIPE)
    assert (recorded.returncode, recorded.stderr) == (0, "")
    assert recorded.stdout == (f"push: 2 episodes, 36 steps, success rate 100% -> "
                               f"{tmp_path / 'data'}\n")


@pytest.mark.parametrize("signum, format", [
    (signal.SIGINT, "npz"),
    pytest.param(signal.SIGTERM, "rlds", marks=pytest.mark.slow),
    pytest.param(signal.SIGTERM, "minari", marks=pytest.mark.slow)])
def test_ctrl_c_ends_a_command_in_one_line_leaving_nothing_half_written(tmp_path, signum,
                                                                        format):
    """A rollout interrupted while it records: a 40-line traceback ending in
    KeyboardInterrupt; now one line and the status a shell gives SIGINT, the file it was
    writing never made. `kill` (SIGTERM) stops it the same way: it left half an RLDS or
    Minari dataset; its status is SIGTERM's (it was SIGINT's, 130)."""
    import time

    out = tmp_path / ("push.npz" if format == "npz" else "push")
    # SIGINT as a terminal sends it: a test run in the background of a shell without job
    # control ignores it, and so would the command it starts.
    with subprocess.Popen([sys.executable, "-m", "franka_composer", "rollout", "--task",
                           "push", "--episodes", "5000", "--format", format, "--out",
                           str(out)], cwd=REPO,
                          env={**os.environ, "MINARI_DATASETS_PATH": str(tmp_path / "minari")},
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                           signal.SIG_DFL)) as rollout:
        time.sleep(15)  # Past the imports (seconds): recording episodes (minutes).
        rollout.send_signal(signum)
        try:
            _, stderr = rollout.communicate(timeout=60)
        finally:
            rollout.kill()
    assert rollout.returncode == 128 + signum
    # (RLDS's writer logs its own lines around it.)
    assert (stderr if format == "npz" else "\n".join(
        line for line in stderr.splitlines() if line.startswith("franka-composer")) + "\n"
    ) == "franka-composer: interrupted\n"
    assert list(tmp_path.iterdir()) == []


def test_a_ctrl_c_python_dropped_still_stops_a_command(monkeypatch, capsys,
                                                     ctrl_c_reaches_the_process):
    """Ctrl-C raised inside a gc callback (jax adds one) is dropped by Python: the command
    went on. `console` takes Ctrl-C as it takes SIGTERM, and raises it again."""
    import gc
    import time

    from franka_composer import cli

    def a_long_command(argv):
        def callback(phase, info):
            if phase == "start" and callback in gc.callbacks:
                gc.callbacks.remove(callback)
                signal.raise_signal(signal.SIGINT)

        gc.callbacks.append(callback)
        gc.collect()
        time.sleep(10)
        return 0

    monkeypatch.setattr(cli, "main", a_long_command)
    begun = time.monotonic()
    assert cli.console([]) == 128 + signal.SIGINT
    assert time.monotonic() - begun < 5
    assert capsys.readouterr().err == "franka-composer: interrupted\n"


def test_a_panda_that_cannot_be_found_is_one_line_naming_what_to_set(tmp_path):
    env = {**os.environ, "MENAGERIE_ROOT": str(tmp_path)}
    out = tmp_path / "demo"
    result = franka_composer("demo", "--tasks", "push", "--episodes", "1", "--out", str(out),
                             env=env, stdout=subprocess.PIPE)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert result.stderr.splitlines()[-1] == (
        "franka-composer: error: Could not resolve Menagerie's 'franka_emika_panda': "
        f"'franka_emika_panda' not found under MENAGERIE_ROOT={tmp_path}. Set MENAGERIE_ROOT "
        "to a folder that contains franka_emika_panda/ (a Menagerie checkout) when "
        "offline.")
    assert not out.exists()  # No empty video folder left behind.


@pytest.mark.parametrize("command", [["report"], ["plot", "--out", "{tmp}/curves.png"],
                                     ["keep", "--into", "{tmp}/kept"]])
def test_reading_runs_needs_no_panda(tmp_path, command):
    """Reading a run's config.json (timing options set, as in the reference-timing cells)
    built Menagerie's Panda to check objects' clearance, which no option read changes:
    report, plot and keep failed offline without MENAGERIE_ROOT."""
    empty = tmp_path / "no-menagerie"
    empty.mkdir()
    env = {**os.environ, "MENAGERIE_ROOT": str(empty)}
    run = REPO / "results" / "reference-timing" / "pick_and_place-tqc-seed0"
    argv = [part.format(tmp=tmp_path) for part in command]
    done = franka_composer(*argv, str(run), env=env, stdout=subprocess.PIPE)
    assert (done.returncode, done.stderr) == (0, "")
    assert (argv[0] != "report"
            or "| pick_and_place (reference timing, sbx) | TQC | 0 | 500,000 |" in done.stdout)


#: Runs the command in a Python where the package `missing` is not installed (its imports
#: fail as they do then), as `franka_composer.cli.console` runs it.
_WITHOUT = """
import sys
class Missing:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == {missing!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
sys.meta_path.insert(0, Missing())
from franka_composer.cli import console
sys.exit(console(sys.argv[1:]))
"""


@pytest.mark.parametrize("missing, extra, argv, why", [
    ("minari", "data", ["rollout", "--task", "reach", "--episodes", "1", "--format", "minari",
                        "--out", "{tmp}/minari"], "No module named 'minari'"),
    ("h5py", "data", ["rollout", "--task", "reach", "--episodes", "1", "--format", "minari",
                      "--out", "{tmp}/minari"], "h5py is not installed."),  # Minari's words.
    ("envlogger", "data", ["rollout", "--task", "reach", "--episodes", "1", "--format", "rlds",
                           "--out", "{tmp}/rlds"], "No module named 'envlogger'"),
    ("matplotlib", "train", ["plot", str(A_COMMITTED_RUN), "--out", "{tmp}/curves.png"],
     "No module named 'matplotlib'"),
    ("torch", "train", ["evaluate", str(A_COMMITTED_RUN), "--episodes", "1"],
     "No module named 'torch'"),
    ("stable_baselines3", "train", ["train", "--task", "reach", "--algo", "sac",
                                    "--total-steps", "200", "--out", "{tmp}/run"],
     "No module named 'stable_baselines3'"),
])
def test_a_command_without_its_extra_names_the_extra_to_install(tmp_path, missing, extra,
                                                                argv, why):
    """Each was Python's ImportError traceback (sweep and --backend sbx already named
    theirs), and nothing is made before it."""
    result = subprocess.run(
        [sys.executable, "-c", _WITHOUT.format(missing=missing),
         *(word.format(tmp=tmp_path) for word in argv)],
        cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    torch_first = (", after torch from PyTorch's CPU index: pip install -c constraints.txt "
                   "torch --index-url https://download.pytorch.org/whl/cpu"
                   if missing == "torch" else "")
    assert result.stderr.splitlines()[-1].startswith(
        f"franka-composer: error: this command needs {missing}, which the '{extra}' extra "
        f"installs: in the checkout, pip install -c constraints.txt -e '.[{extra}]'"
        f"{torch_first} (docs/guide/installation.md; {why}")
    assert list(tmp_path.iterdir()) == []


def test_only_a_missing_extras_import_error_is_taken_for_one(monkeypatch):
    """Any other is a broken installation or a bug, whose traceback says where: a package
    that is installed but fails to import (a version that lacks a name, a broken C
    extension) was told to be installed."""
    from franka_composer.cli.extras import missing_extra

    assert missing_extra(ModuleNotFoundError("No module named 'lxml'", name="lxml")) is None
    with pytest.raises(ImportError) as real:
        from torch import no_such_name  # noqa: F401
    assert real.value.name == "torch" and missing_extra(real.value) is None
    assert missing_extra(ImportError("broken", name="torch._C")) is None
    assert missing_extra(ImportError("could not load the ray tracer")) is None  # Ray is here.
    from franka_composer.cli import extras

    monkeypatch.setitem(extras.EXTRA_OF, "franka_absent", "data")  # Not installed anywhere.
    for error in (ModuleNotFoundError("No module named 'franka_absent'",
                                      name="franka_absent.sub"),
                  ImportError("franka_absent is not installed")):
        assert missing_extra(error) == (
            f"this command needs franka_absent, which the 'data' extra installs: in the "
            f"checkout, pip install -c constraints.txt -e '.[data]' "
            f"(docs/guide/installation.md; {error})")
    # The train extra without torch: CPU torch first, as the install guide says.
    monkeypatch.setitem(extras.EXTRA_OF, "franka_absent", "train")
    monkeypatch.setattr(extras, "_installed", lambda name: False)
    assert missing_extra(ModuleNotFoundError("No module named 'torch'", name="torch")) == (
        "this command needs torch, which the 'train' extra installs: in the checkout, pip "
        "install -c constraints.txt -e '.[train]', after torch from PyTorch's CPU index: pip "
        "install -c constraints.txt torch --index-url https://download.pytorch.org/whl/cpu "
        "(docs/guide/installation.md; No module named 'torch')")


def test_each_extra_named_brings_its_package():
    """`EXTRA_OF` against setup.cfg: each package is one of its extra's requirements, or a
    requirement of one of them (torch of stable-baselines3, jax of sbx-rl)."""
    import configparser
    from importlib import metadata

    from packaging.requirements import Requirement

    from franka_composer.cli.extras import EXTRA_OF

    def name(text):
        return Requirement(text).name.lower().replace("_", "-")

    config = configparser.ConfigParser()
    config.read(REPO / "setup.cfg")
    extras = config["options.extras_require"]
    distributions = metadata.packages_distributions()
    for module, extra in EXTRA_OF.items():
        direct = [line for line in extras[extra].splitlines() if line.strip()]
        brought = {name(line) for line in direct}
        for requirement in direct:
            brought |= {name(r) for r in metadata.requires(Requirement(requirement).name) or ()
                        if "extra ==" not in r}
        assert {name(d) for d in distributions[module]} & brought, (module, extra)


def test_a_damaged_panda_is_one_line_naming_the_file(tmp_path):
    """A truncated panda.xml under MENAGERIE_ROOT: lxml's XMLSyntaxError came as a
    43-line traceback."""
    panda = tmp_path / "franka_emika_panda"
    panda.mkdir()
    whole = (pathlib.Path(os.environ["MENAGERIE_ROOT"]) / panda.name / "panda.xml").read_bytes()
    (panda / "panda.xml").write_bytes(whole[:2000])
    env = {**os.environ, "MENAGERIE_ROOT": str(tmp_path), "FRANKA_COMPOSER_CACHE": "off"}
    result = franka_composer("demo", "--tasks", "push", "--episodes", "1", "--no-video",
                             env=env, stdout=subprocess.PIPE)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert re.fullmatch(
        re.escape(f"franka-composer: error: {panda / 'panda.xml'} is not Menagerie's Panda: it "
                  "is not well-formed XML (") + r".+, line \d+, column \d+" + re.escape(
            "); a damaged or edited copy? Point MENAGERIE_ROOT at a whole one"),
        result.stderr.splitlines()[-1]), result.stderr


def test_version_prints_the_package_version():
    from franka_composer import __version__

    result = franka_composer("--version", stdout=subprocess.PIPE)
    assert (result.returncode, result.stdout) == (0, f"franka-composer {__version__}\n")


def test_a_warning_of_this_package_is_one_line(tmp_path):
    """A damaged model.zip beside a committed run's policy file: played, saying so."""
    run = tmp_path / "run"
    run.mkdir()
    for name in ("config.json", "policy.pt"):
        (run / name).write_bytes((A_COMMITTED_RUN / name).read_bytes())
    (run / "model.zip").write_bytes(b"garbage")
    result = franka_composer("evaluate", str(run), "--episodes", "1", "--device", "cpu",
                             stdout=subprocess.PIPE)
    assert result.returncode == 0 and "push" in result.stdout
    assert result.stderr.splitlines() == [
        f"franka-composer: warning: {run / 'model.zip'} is damaged (not a readable zip "
        f"archive: File is not a zip file), and the run has no checkpoint to use instead: "
        f"using its policy file, {run / 'policy.pt'}"]

