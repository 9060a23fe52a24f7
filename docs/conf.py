"""Sphinx configuration of the documentation site (furo theme, MyST Markdown pages).

`make docs` builds it with warnings as errors. The task pages are generated from the env
classes' docstrings when Sphinx starts (`_scripts/gen_task_pages.py`), so `sphinx-build`
alone builds the whole site.
"""

from __future__ import annotations

import pathlib
import re
import sys

from sphinx import addnodes

DOCS = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(DOCS.parent), str(DOCS / "_scripts")]

import franka_composer  # noqa: E402
import gen_task_pages  # noqa: E402

project = "franka_composer"
author = "franka_composer contributors"
copyright = "2026, franka_composer contributors"
release = version = franka_composer.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon",
              "sphinx.ext.viewcode", "sphinx_copybutton"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build", "_scripts"]
# Straight quotes: the pages quote code (franka_composer.load("push")) that must copy as typed.
smartquotes = False
myst_enable_extensions = ["colon_fence"]
# Headings down to ### get anchors, so pages can link to a section: [x](page.md#section).
myst_heading_anchors = 3

# The docstrings use `name` for code, as Markdown does.
default_role = "code"
# The docstrings' Args:, Attributes:, Raises: sections are Google style.
napoleon_numpy_docstring = False
# Our docstrings only: an undocumented override (FrankaGoalEnv.step) does not take
# Gymnasium's, which is another docstring style.
autodoc_inherit_docstrings = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}

html_theme = "furo"
html_title = f"franka_composer {release}"
html_static_path = ["_static"]
# Copy commands without their prompts.
copybutton_prompt_text = r"\$ "
copybutton_prompt_is_regexp = True


def _write_task_pages(app) -> None:
    gen_task_pages.write_pages()


def included_root_files() -> dict[pathlib.Path, str]:
    """The repository's own Markdown files that a page of the site includes whole
    (`changelog.md` is CHANGELOG.md), as {the file without its suffix: that page}."""
    pages = {}
    for page in DOCS.glob("*.md"):
        included = re.match(r"```\{include\} \.\./(\S+)\.md\n", page.read_text())
        if included:
            pages[DOCS.parent / included.group(1)] = page.stem
    return pages


def _link_root_files_to_their_pages(app, doctree) -> None:
    """A page's link to a repository file the site includes (`../../RESULTS.md`, right on
    GitHub) goes to the page that includes it."""
    pages = included_root_files()
    for xref in doctree.findall(addnodes.pending_xref):
        if xref.get("reftype") == "myst" and xref.get("refdomain") == "doc":
            target = pathlib.Path(app.srcdir, xref["reftarget"]).resolve()
            if target in pages:
                xref["reftarget"] = pages[target]


def setup(app) -> None:
    app.connect("builder-inited", _write_task_pages)
    app.connect("doctree-read", _link_root_files_to_their_pages)
