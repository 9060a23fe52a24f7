"""The release's archives are checked for what a user needs (.ci/smoke_wheel.py, which CI
runs on the built sdist and wheel), and the package ships its PEP 561 marker. What a release
states about itself agrees: one version in the package, the citation file and the
changelog; the licence the metadata names is the one shipped; the package's description and
docstring name every task."""

from __future__ import annotations

import configparser
import io
import pathlib
import re
import tarfile
import zipfile

from conftest import load_script

import franka_composer
from franka_composer.tasks import ALL_TASKS

REPO = pathlib.Path(__file__).resolve().parents[1]


def _smoke_wheel():
    return load_script(REPO / ".ci" / "smoke_wheel.py")


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
    # setuptools adds tests/test*.py to an sdist by default, without conftest.py.
    with_tests = tmp_path / "with-tests"
    _release(with_tests, [*smoke.SDIST_FILES, "LICENSE", "tests/test_suite.py"],
             smoke.WHEEL_FILES)
    assert smoke.missing_from_archives(with_tests, checkout) == [
        "franka_composer-0.1.0.tar.gz: holds tests/test_suite.py"]


def test_the_package_ships_py_typed():
    from setuptools.config.setupcfg import read_configuration

    package_data = read_configuration(REPO / "setup.cfg")["options"]["package_data"]
    assert package_data == {"franka_composer": ["py.typed"]}
    assert (REPO / "franka_composer" / "py.typed").is_file()


def _setup_cfg() -> configparser.ConfigParser:
    config = configparser.ConfigParser()
    config.read(REPO / "setup.cfg")
    return config


def test_one_version_in_the_package_the_citation_and_the_changelog():
    """The citation names the last release, and so does the package on its release commit;
    with changes since (an [Unreleased] section that is not empty) the package is the next
    release's .dev0: a wheel built between releases was named as the last one."""
    from packaging.version import Version

    changelog = (REPO / "CHANGELOG.md").read_text()
    citation = (REPO / "CITATION.cff").read_text()
    releases = re.findall(r"^## \[(\d[^\]]*)\] - (\d{4}-\d\d-\d\d)$", changelog,
                          re.MULTILINE)
    last, released_on = releases[0]
    assert re.search(r"^version: (\S+)$", citation, re.MULTILINE)[1] == last
    assert f'date-released: "{released_on}"' in citation
    unreleased = changelog.split("## [Unreleased]", 1)[1].split(f"## [{last}]", 1)[0]
    version = Version(franka_composer.__version__)
    if unreleased.strip():
        assert version.is_devrelease and Version(version.base_version) > Version(last)
        assert str(version) == f"{version.base_version}.dev0"
    else:
        assert str(version) == last


def test_the_licence_shipped_is_the_one_the_metadata_names():
    assert _setup_cfg()["metadata"]["license"] == "Apache-2.0"
    text = (REPO / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert "END OF TERMS AND CONDITIONS" in text
    assert "Menagerie" in (REPO / "NOTICE").read_text()


def test_the_description_and_the_docstring_name_every_task():
    description = _setup_cfg()["metadata"]["description"]
    docstring = franka_composer.__doc__
    for task in ALL_TASKS:
        assert task.replace("_", "-") in description, task
        assert re.search(rf"\b{task}\b", docstring), task  # A word, not "pushes".
