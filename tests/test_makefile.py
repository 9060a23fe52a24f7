"""The Makefile's MENAGERIE_ROOT: the user's when set; left unset when mujoco-menagerie's
cache has the Panda or there is no local copy; else the local copy beside the project.
Run through `make demo` with a stand-in venv whose franka-composer prints what it got."""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys

import mujoco_menagerie
import pytest
from mujoco_menagerie._cache import SENTINEL

from franka_composer.assets import PANDA_NAME

REPO = pathlib.Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def _make_demo(tmp_path: pathlib.Path, cache: pathlib.Path, copy: pathlib.Path,
               menagerie_root: str | None = None) -> str:
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True, exist_ok=True)
    python, command = venv / "bin" / "python", venv / "bin" / "franka-composer"
    python.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    command.write_text('#!/bin/sh\necho "MENAGERIE_ROOT=${MENAGERIE_ROOT-unset}"\n')
    python.chmod(0o755)
    command.chmod(0o755)
    (venv / ".setup-demo").touch()  # Set up, after constraints.txt and setup.cfg.
    env = {key: value for key, value in os.environ.items() if key != "MENAGERIE_ROOT"}
    env["MENAGERIE_CACHE_DIR"] = str(cache)
    if menagerie_root is not None:
        env["MENAGERIE_ROOT"] = menagerie_root
    completed = subprocess.run(
        ["make", "-s", "-C", str(REPO), "demo", f"VENV={venv}", f"MENAGERIE_COPY={copy}"],
        env=env, capture_output=True, text=True, check=True, timeout=120)
    return completed.stdout.strip().splitlines()[-1]


@pytest.fixture
def copy(tmp_path):
    (tmp_path / "copy" / PANDA_NAME).mkdir(parents=True)
    return tmp_path / "copy"


def test_the_users_menagerie_root_is_kept(tmp_path, copy):
    assert _make_demo(tmp_path, tmp_path / "cache", copy, "/mine") == "MENAGERIE_ROOT=/mine"


def test_without_one_and_without_the_panda_cached_the_local_copy_is_used(tmp_path, copy):
    assert _make_demo(tmp_path, tmp_path / "cache", copy) == f"MENAGERIE_ROOT={copy}"


def test_a_cached_panda_or_no_local_copy_leaves_it_unset(tmp_path, copy, monkeypatch):
    assert _make_demo(tmp_path, tmp_path / "cache", tmp_path / "none") == "MENAGERIE_ROOT=unset"
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path / "cache"))
    published = mujoco_menagerie.Cache().model_path(mujoco_menagerie.get(PANDA_NAME))
    published.mkdir(parents=True)
    (published / SENTINEL).touch()
    assert _make_demo(tmp_path, tmp_path / "cache", copy) == "MENAGERIE_ROOT=unset"


def test_torch_comes_from_the_cpu_index_beside_pips_own(tmp_path):
    """`make setup` adds PyTorch's CPU index to pip's, never in their place: torch's own
    dependencies (filelock, ...) come from pip's indexes, and where PyTorch's index cannot
    be reached a local +cpu wheel still installs (with --index-url alone it could not)."""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").write_text("#!/bin/sh\nexit 1\n")
    (venv / "bin" / "python").chmod(0o755)
    default = {name: value for name, value in os.environ.items() if name != "TORCH_INDEX"}
    recipe = subprocess.run(["make", "-n", "-C", str(REPO), "setup", f"VENV={venv}"],
                            capture_output=True, text=True, check=True, timeout=60,
                            env=default).stdout  # The Makefile's default, not the caller's.
    torch_line = next(line for line in recipe.splitlines() if "torch==2.13.0" in line)
    assert "--extra-index-url https://download.pytorch.org/whl/cpu" in torch_line
    assert " --index-url" not in torch_line


@pytest.mark.parametrize("target", ["setup", "setup-demo"])
def test_a_venv_is_set_up_again_once_the_tested_versions_change(tmp_path, target):
    """The setups ran pip only where an import failed: a venv kept from before never took
    a new constraints.txt. A stamp older than constraints.txt or setup.cfg installs again;
    a newer one runs nothing. (In a copy of the three files, whose times are set here.)"""
    project = tmp_path / "project"
    project.mkdir()
    for name in ("Makefile", "constraints.txt", "setup.cfg"):
        shutil.copy(REPO / name, project / name)
        os.utime(project / name, (1_000_000, 1_000_000))
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").touch()
    stamp = venv / f".{target}"

    def recipe() -> str:
        return subprocess.run(["make", "-n", "-C", str(project), target, f"VENV={venv}"],
                              capture_output=True, text=True, check=True, timeout=60).stdout

    def installs() -> bool:
        return "pip install -c constraints.txt" in recipe()

    assert installs() and f"touch {stamp}" in recipe()  # Never set up: it is, then stamped.
    if target == "setup":  # What setup-demo installs too.
        assert f"{venv}/.setup-demo" in recipe().split(f"touch {stamp}")[1]
    stamp.touch()
    os.utime(stamp, (2_000_000, 2_000_000))
    assert not installs()
    for source in ("constraints.txt", "setup.cfg"):
        os.utime(project / source, (3_000_000, 3_000_000))
        assert installs(), source
        os.utime(project / source, (1_000_000, 1_000_000))
        assert not installs(), source


@pytest.mark.parametrize("target", ["test", "test-fast"])
def test_the_tests_find_the_venvs_tools_on_path_wherever_the_venv_lies(tmp_path, target):
    """With VENV=elsewhere and no .venv in the checkout, the campaign scripts the tests start
    found no franka-composer (they look in .venv/bin, then on PATH). The venv's bin comes
    first on PATH, as in the venv activated. (A stand-in python prints what PATH gives.)"""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    python, command = venv / "bin" / "python", venv / "bin" / "franka-composer"
    python.write_text('#!/bin/sh\necho "found $(command -v franka-composer)"\n')
    command.write_text("#!/bin/sh\n")
    python.chmod(0o755)
    command.chmod(0o755)
    (venv / ".setup").touch()  # Set up, after constraints.txt and setup.cfg.
    (venv / ".setup-demo").touch()
    env = {**os.environ, "PATH": "/usr/bin:/bin", "MENAGERIE_ROOT": "/mine"}
    completed = subprocess.run(["make", "-s", "-C", str(REPO), target, f"VENV={venv}"],
                               env=env, capture_output=True, text=True, check=True, timeout=60)
    assert completed.stdout.strip().splitlines()[-1] == f"found {command}"
