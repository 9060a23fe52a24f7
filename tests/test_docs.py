"""The documentation says what the code does: the guide's observation and randomisation
tables are generated from the tasks' layouts and the parameters, its layout tree names what
the package holds, and the README's Table II is the report's table as written."""

from __future__ import annotations

import pathlib
import re

import pytest
from conftest import doc_option, documented_commands, load_script

REPO = pathlib.Path(__file__).resolve().parents[1]
GUIDE = REPO / "docs" / "guide"


@pytest.mark.parametrize("page", ["quickstart.md", "randomization.md", "training.md"])
def test_the_guide_tables_are_the_layouts_and_parameters(page):
    tables = load_script(REPO / "tools" / "doc_tables.py")
    text = (GUIDE / page).read_text()
    assert tables.updated(page, text) == text, "stale: run python tools/doc_tables.py"


def test_the_layout_tree_names_every_module_and_only_real_paths():
    tree = (GUIDE / "layout.md").read_text().split("```", 2)[1]
    # Entries start at most two spaces in; deeper lines continue a description.
    named = set(re.findall(r"^ {0,2}([\w./-]+)", tree, flags=re.MULTILINE))
    for path in named:
        assert (REPO / path).exists() or (REPO / "franka_composer" / path).exists(), path
    package = REPO / "franka_composer"
    for module in package.iterdir():
        if module.name.startswith("__") or module.suffix not in (".py", ""):
            continue
        entry = module.name + ("/" if module.is_dir() else "")
        assert entry in named or module.name in named, f"the layout page misses {entry}"


def test_every_id_is_documented_by_its_class_page():
    """Gymnasium-Robotics style: the env class's docstring is the id's page."""
    import gymnasium as gym

    import franka_composer

    for id_, registered in franka_composer.ENV_IDS.items():
        env = gym.make(id_)
        page = type(env.unwrapped).__doc__
        assert id_ in page and f'franka_composer.load("{registered.task}")' in page
        # The page's table is the default controller's; joint control appends one field.
        table = env.unwrapped.observation_layout.markdown_table().splitlines()
        if registered.control == "joints":
            assert table.pop().startswith("| ") and "joint angles" in page
        assert "\n".join(table) in page.replace("\n    ", "\n")
        for section in ("Action space", "Observation space", "Rewards", "Starting state",
                        "Episode end", "Arguments", "Version history"):
            assert f"\n{section}\n" in page, (id_, section)
        for name, value in env.unwrapped.task.config.options.items():
            if name not in ("reward_type", "control"):
                assert f"{name} = {value!r}" in page, (id_, name)
        assert "control = 'mocap'" in page
        env.close()


def test_the_readme_quotes_table_two_as_the_report_wrote_it():
    """The README's headline table is `results/table2/table2.md`'s, row for row."""
    table = [line for line in (REPO / "results" / "table2" / "table2.md").read_text()
             .splitlines() if line.startswith("|")]
    readme = (REPO / "README.md").read_text()
    assert len(table) == 8 and "\n".join(table) in readme


def test_the_docs_link_only_to_files_that_exist():
    """Every relative link and image of the README, RESULTS.md, the changelog and the docs
    pages names a file of the repository (an anchor after # is not checked); the task pages
    Sphinx writes exist on the site only, so only the site's own pages may link them (the
    README is read in a checkout and on GitHub)."""
    pages = [REPO / name for name in ("README.md", "RESULTS.md", "CHANGELOG.md",
                                      "BENCHMARKS.md")]
    pages += sorted((REPO / "docs").rglob("*.md"))
    # The task pages, written when Sphinx starts (not committed).
    generated = set(load_script(REPO / "docs" / "_scripts" / "gen_task_pages.py").pages())
    missing = []
    for page in pages:
        text = page.read_text()
        targets = re.findall(r"\]\(([^)\s]+)\)", text) + re.findall(r'<img src="([^"]+)"', text)
        for target in targets:
            path = target.split("#", 1)[0]
            if not path or "://" in path or path.startswith("mailto:"):
                continue
            linked = (page.parent / path).resolve()
            on_site = (REPO / "docs") in page.parents
            if not linked.exists() and not (on_site and linked in generated):
                missing.append(f"{page.relative_to(REPO)}: {target}")
    assert missing == []


#: Commands the docs give for an older tree, with options today's commands no longer take:
#: (page, command, option).
OLDER_TREES = {
    ("docs/experiments/speed-levers.md", "bench", "--out"),  # Commit 0e9d700's bench.
    ("docs/guide/benchmarks.md", "bench", "--memory-envs"),  # Tree e2d0bf6's, on PYTHONPATH.
}


def test_the_docs_give_franka_composer_only_options_it_takes():
    """Every `franka-composer COMMAND ...` the pages give (`documented_commands`) names a
    command that exists and only options that command takes (after a bare `--`, `sweep`
    passes `train`'s): a renamed option would leave a reader's copied command refused."""
    from franka_composer.cli import SUBCOMMANDS, command_parser

    options = {name: set(command_parser(name)._option_string_actions) for name in SUBCOMMANDS}
    wrong, seen, older = [], 0, set()
    for page, _, words, begins in documented_commands(
            r"franka-composer|python -m franka_composer"):
        if not words or words[0] not in options:
            if begins and words and re.fullmatch(r"[a-z]+", words[0]):
                wrong.append(f"{page}: no command {words[0]!r}")
            continue
        seen += 1
        takes = options[words[0]]
        for word in words[1:]:
            if word == "--" and words[0] == "sweep":
                takes = options["train"]
            option = doc_option(word)
            if option and option not in takes:
                if (page, words[0], option) in OLDER_TREES:
                    older.add((page, words[0], option))
                else:
                    wrong.append(f"{page}: {words[0]} has no {option}")
    assert seen > 150  # The commands were found.
    assert wrong == [], "\n".join(wrong)
    assert older == OLDER_TREES  # Each still in the docs.
