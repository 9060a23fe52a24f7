"""The documentation site's generated task pages say what `help(env)` says: each is its env
class's docstring as Markdown (docs/_scripts/gen_task_pages.py), under the animation of its
expert (docs/_scripts/gen_animations.py), which is committed for every task."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

import franka_composer
from franka_composer.adapters.registration import TASK_ENV_CLASSES
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.tasks.layout import layout_for

REPO = pathlib.Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "docs" / "_scripts"
#: What `gen_task_pages.markdown` adds around the docstring's words.
MARKUP = {"##", "```python", "```"}


def _load(path: pathlib.Path):
    """The module in `path` (the docs' scripts and conf.py are not a package)."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen_task_pages = _load(SCRIPTS / "gen_task_pages.py")


@pytest.mark.parametrize("task", franka_composer.ALL_TASKS)
def test_each_task_page_is_its_class_docstring_word_for_word(task):
    doc = TASK_ENV_CLASSES[task].__doc__
    page = gen_task_pages.task_page(task)
    body = gen_task_pages.markdown(doc)
    assert page.endswith(body)
    assert [word for word in body.split() if word not in MARKUP] == doc.split()


@pytest.mark.parametrize("task", franka_composer.ALL_TASKS)
def test_each_task_page_lays_the_docstring_out_as_markdown(task):
    config = TASK_CONFIGS[task]
    page = gen_task_pages.task_page(task)
    for section in ("Action space", "Observation space", "Rewards", "Starting state",
                    "Episode end", "Arguments", "Version history"):
        assert f"\n\n## {section}\n\n" in page, section
    # The observation table is a table (unindented), not a code block.
    assert f"\n\n{layout_for(config).markdown_table()}\n\n" in page
    options = page.split("\n## Arguments\n", 1)[1].split("```python\n", 1)[1].split("\n```")[0]
    lines = options.splitlines()
    assert lines[0] == f"timing = {config.timing_name!r}"
    assert [line for line in lines[1:] if "  # read with " not in line] == [
        f"{name} = {value!r}" for name, value in config.options.items()
        if name != "reward_type"]
    assert page.startswith(f"# {gen_task_pages.title(task)}\n\n```{{image}} "
                           f"../_static/tasks/{task}.gif\n")


def test_every_task_has_its_committed_animation_and_first_frame():
    from PIL import Image

    for task in franka_composer.ALL_TASKS:
        with Image.open(REPO / "docs" / "_static" / "tasks" / f"{task}.gif") as gif:
            assert gif.size == (240, 240) and gif.n_frames >= 2, task
        with Image.open(REPO / "docs" / "_static" / "tasks" / f"{task}.png") as png:
            assert png.size == (240, 240), task


def test_the_tasks_index_links_every_task_page():
    index = gen_task_pages.index_page()
    toctree = index.split("```{toctree}\n:hidden:\n\n", 1)[1].split("\n```")[0]
    assert toctree.splitlines() == list(franka_composer.ALL_TASKS)
    for task in franka_composer.ALL_TASKS:
        assert f"[{gen_task_pages.title(task)}]({task}.md)" in index


def test_links_to_the_repositorys_included_files_go_to_their_pages():
    """`[results](../../RESULTS.md)` in docs/experiments/ is right on GitHub; on the site it
    goes to results.html, the page that includes RESULTS.md (likewise CHANGELOG.md)."""
    from types import SimpleNamespace

    from docutils import nodes
    from sphinx import addnodes

    conf = _load(REPO / "docs" / "conf.py")
    assert conf.included_root_files() == {REPO / "CHANGELOG": "changelog",
                                          REPO / "RESULTS": "results"}
    doctree = nodes.document(None, None)
    for target in (str(REPO / "RESULTS"), "../CHANGELOG", "guide/quickstart"):
        doctree += addnodes.pending_xref(refdomain="doc", reftype="myst", reftarget=target)
    conf._link_root_files_to_their_pages(SimpleNamespace(srcdir=str(REPO / "docs")), doctree)
    assert [xref["reftarget"] for xref in doctree.findall(addnodes.pending_xref)] == [
        "results", "changelog", "guide/quickstart"]


def test_the_animation_script_takes_the_shared_tasks_syntax(tmp_path, monkeypatch):
    """Its --tasks is every subcommand's (cli.options): both forms, and a clear refusal."""
    import subprocess
    import sys

    script = REPO / "docs" / "_scripts" / "gen_animations.py"
    animations, animated = _load(script), []
    monkeypatch.setattr(animations, "OUT", tmp_path)  # (Nothing rendered, nothing written.)
    monkeypatch.setattr(animations, "episode_frames",
                        lambda task: animated.append(task) or ([], 0, True))
    monkeypatch.setattr(animations, "write_animation", lambda frames, gif: gif.touch())
    for tasks in (["push", "slide"], ["push,slide"]):
        animated.clear()
        assert animations.main(["--tasks", *tasks]) == 0 and animated == ["push", "slide"]
    done = subprocess.run([sys.executable, str(script), "--tasks", "push,fly"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2
    assert "unknown task(s) fly; valid tasks: push, slide" in done.stderr


@pytest.mark.parametrize("task", franka_composer.ALL_TASKS)
def test_a_task_page_gives_the_options_it_reads_and_marks_those_read_otherwise(task):
    """Each option the page gives with the task's value is taken back at that value (the
    page listed options every task refuses, reach's object_range, flip's goal_range,
    stack's goal_max_height); one read only under another setting says which, and is
    taken there."""
    from franka_composer.adapters.pages import option_lines

    config = TASK_CONFIGS[task]
    assert config.replace(**config.options) == config
    unread = {"reach": "object_range", "flip": "goal_range", "stack": "goal_max_height"}
    lines = option_lines(config)
    if task in unread:
        assert not [line for line in lines if line.startswith(f"{unread[task]} = ")]
    marked = {line.split(" = ")[0]: line.split("  # read with ")[1] for line in lines
              if "  # read with " in line}
    assert marked["max_joint_step"] == "control='joints'"
    assert marked["cameras"] == "observation_mode='pixels' or 'state+pixels'"
    config.replace(control="joints", max_joint_step=0.1)
    config.replace(observation_mode="pixels", cameras=("workspace",))
