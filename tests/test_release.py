"""What a release states about itself agrees: one version in the package, the citation file
and the changelog; the licence the metadata names is the one shipped; the package's
description and docstring name every task."""

from __future__ import annotations

import configparser
import pathlib
import re

import franka_composer
from franka_composer.tasks import ALL_TASKS

REPO = pathlib.Path(__file__).resolve().parents[1]


def _setup_cfg() -> configparser.ConfigParser:
    config = configparser.ConfigParser()
    config.read(REPO / "setup.cfg")
    return config


def test_one_version_in_the_package_the_citation_and_the_changelog():
    citation = (REPO / "CITATION.cff").read_text()
    version = re.search(r"^version: (\S+)$", citation, re.MULTILINE)[1]
    assert version == franka_composer.__version__
    releases = re.findall(r"^## \[(\d[^\]]*)\] - (\d{4}-\d\d-\d\d)$",
                          (REPO / "CHANGELOG.md").read_text(), re.MULTILINE)
    assert releases[0][0] == franka_composer.__version__
    assert f'date-released: "{releases[0][1]}"' in citation


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
        assert task in docstring, task
