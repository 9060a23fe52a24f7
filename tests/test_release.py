"""The release's archives are checked for what a user needs (.ci/smoke_wheel.py, which CI
runs on the built sdist and wheel), and the package ships its PEP 561 marker."""

from __future__ import annotations

import importlib.util
import io
import pathlib
import tarfile
import zipfile

REPO = pathlib.Path(__file__).resolve().parents[1]


def _smoke_wheel():
    spec = importlib.util.spec_from_file_location("smoke_wheel", REPO / ".ci" / "smoke_wheel.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _release(dist: pathlib.Path, sdist_files, wheel_files) -> None:
    dist.mkdir()
    with tarfile.open(dist / "franka_composer-0.1.0.tar.gz", "w:gz") as archive:
        for name in sdist_files:
            member = tarfile.TarInfo(f"franka_composer-0.1.0/{name}")
            archive.addfile(member, io.BytesIO(b""))
    with zipfile.ZipFile(dist / "franka_composer-0.1.0-py3-none-any.whl", "w") as archive:
        for name in wheel_files:
            archive.writestr(name, "")


def test_the_release_check_names_each_file_the_archives_lack(tmp_path):
    smoke = _smoke_wheel()
    checkout = tmp_path / "checkout"
    checkout.mkdir()
    (checkout / "LICENSE").write_text("")  # Present in the checkout: the sdist must hold it.
    sdist = [name for name in smoke.SDIST_FILES if name != "franka_composer/py.typed"]
    _release(tmp_path / "dist", sdist, ["franka_composer/__init__.py"])
    assert smoke.missing_from_archives(tmp_path / "dist", checkout) == [
        "franka_composer-0.1.0.tar.gz: franka_composer/py.typed",
        "franka_composer-0.1.0.tar.gz: LICENSE",
        "franka_composer-0.1.0-py3-none-any.whl: franka_composer/py.typed"]
    complete = tmp_path / "complete"
    _release(complete, [*smoke.SDIST_FILES, "LICENSE"], smoke.WHEEL_FILES)
    assert smoke.missing_from_archives(complete, checkout) == []


def test_the_package_ships_py_typed():
    from setuptools.config.setupcfg import read_configuration

    package_data = read_configuration(REPO / "setup.cfg")["options"]["package_data"]
    assert package_data == {"franka_composer": ["py.typed"]}
    assert (REPO / "franka_composer" / "py.typed").is_file()
