"""Writes the docs site's task pages: `docs/tasks/<task>.md`, one per task, and their index.

Each page is its task's Gymnasium class docstring (`franka_composer.adapters.pages.page`,
what `help(env.unwrapped)` prints) turned into Markdown, under a title and the expert's
animation (`gen_animations.py`): one source, so the site and `help` cannot disagree.
Gymnasium-Robotics' `docs/_scripts/gen_mds.py` is the pattern. `conf.py` runs `write_pages`
when Sphinx starts, so `sphinx-build` alone is enough; the pages are not committed.
"""

from __future__ import annotations

import pathlib
import re

import franka_composer
from franka_composer.adapters.registration import TASK_ENV_CLASSES, env_id
from franka_composer.tasks import TASK_CONFIGS

DOCS = pathlib.Path(__file__).resolve().parents[1]
TASKS = DOCS / "tasks"
#: The animations and first frames, relative to a page in `TASKS`.
STATIC = "../_static/tasks"
#: How deep `pages.page` indents a section's body.
INDENT = "    "


def title(task: str) -> str:
    """`pick_and_place` -> `Pick and place`."""
    return task.replace("_", " ").capitalize()


def markdown(doc: str) -> str:
    """A class docstring laid out as `pages.page` lays it out, as Markdown: an unindented
    line followed by indented ones is a section title (a `##` heading); a section's body is
    dedented; prose paragraphs are joined onto one line; a block after a blank line inside a
    section is kept as it is, a table when it starts with `|`, else a code block (the
    options list)."""
    lines = doc.strip("\n").splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        block = [line]
        indented = line.startswith(INDENT)
        while i + len(block) < len(lines):
            following = lines[i + len(block)]
            if not following.strip() or following.startswith(INDENT) != indented:
                break
            block.append(following)
        starts_section = (not indented and len(block) == 1 and i + 1 < len(lines)
                          and lines[i + 1].startswith(INDENT))
        after_blank = i > 0 and not lines[i - 1].strip()
        body = [entry.removeprefix(INDENT) for entry in block]
        if starts_section:
            out.append(f"## {line}")
        elif indented and after_blank and body[0].startswith("|"):
            out.append("\n".join(body))
        elif indented and after_blank and len(body) > 1:
            out.append("```python\n" + "\n".join(body) + "\n```")
        else:
            out.append(" ".join(body))
        i += len(block)
    return "\n\n".join(out) + "\n"


def task_page(task: str) -> str:
    """The Markdown page of `task`: title, animation, where the text comes from, the text."""
    cls = TASK_ENV_CLASSES[task]
    sparse = env_id(task, "sparse")
    return (f"# {title(task)}\n\n"
            f"```{{image}} {STATIC}/{task}.gif\n:alt: One episode of the {title(task).lower()} "
            f"task's scripted expert\n:width: 240px\n```\n\n"
            f"One episode of the scripted expert (`franka-composer demo --tasks {task}`). "
            f"The rest of this page is the docstring of `{cls.__module__}.{cls.__name__}`, "
            f"which `help(gym.make(\"{sparse}\").unwrapped)` shows.\n\n"
            + markdown(cls.__doc__))


def index_page() -> str:
    """The tasks' index: a table of every task (first frame, description, ids) and the
    toctree of their pages."""
    rows = ["| task | first frame | what it asks | Gymnasium ids |", "|---|---|---|---|"]
    for task, config in TASK_CONFIGS.items():
        description = re.sub(r"\s+", " ", config.description).strip()
        ids = ", ".join(f"`{id_}`" for id_ in franka_composer.ENV_IDS
                        if franka_composer.ENV_IDS[id_].task == task and
                        franka_composer.ENV_IDS[id_].control == "mocap")
        rows.append(f"| [{title(task)}]({task}.md) | ![{task}]({STATIC}/{task}.png) | "
                    f"{description} | {ids} |")
    toctree = "\n".join(TASK_CONFIGS)
    return ("# Tasks\n\n"
            f"{len(TASK_CONFIGS)} goal-conditioned tasks, each registered as a sparse and a "
            "dense Gymnasium id under every controller (`Osc` and `Joints` in an id's name "
            "fix the controller; the plain ids default to mocap and take a `control` "
            "option). Each task's page is its env class's docstring.\n\n"
            + "\n".join(rows) + "\n\n"
            f"```{{toctree}}\n:hidden:\n\n{toctree}\n```\n")


def gallery(columns: int = 3) -> str:
    """Every task's animation under its name, each a link to its page, in a table of
    `columns` columns, for the home page to include (`docs/index.md`; paths from `docs/`)."""
    tasks = list(TASK_CONFIGS)
    rows = []
    for start in range(0, len(tasks), columns):
        row = tasks[start:start + columns]
        rows.append("| " + " | ".join(f"[{title(task)}](tasks/{task}.md)" for task in row)
                    + " |")
        if not start:
            rows.append("|" + ":---:|" * len(row))
        rows.append("| " + " | ".join(f"[![{title(task)}](_static/tasks/{task}.gif)]"
                                      f"(tasks/{task}.md)" for task in row) + " |")
    return "\n".join(rows) + "\n"


def pages() -> dict[pathlib.Path, str]:
    """Every generated file, by path: the pages, and the home page's gallery (`.inc`, not a
    page of its own)."""
    written = {TASKS / f"{task}.md": task_page(task) for task in TASK_CONFIGS}
    written[TASKS / "index.md"] = index_page()
    written[TASKS / "gallery.inc"] = gallery()
    return written


def write_pages() -> list[pathlib.Path]:
    """Writes the pages whose text changed (an unchanged file keeps its time, so Sphinx does
    not rebuild it); returns those written."""
    TASKS.mkdir(exist_ok=True)
    changed = []
    for path, text in pages().items():
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            changed.append(path)
    return changed


if __name__ == "__main__":
    for written in write_pages():
        print(written)
