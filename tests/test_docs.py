"""The README says what the code does: its observation tables are generated from the tasks'
layouts, and its layout tree names what the package holds."""

from __future__ import annotations

import importlib.util
import pathlib
import re

REPO = pathlib.Path(__file__).resolve().parents[1]


def _tool(name: str):
    spec = importlib.util.spec_from_file_location(name, REPO / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_observation_tables_are_the_layouts():
    readme = (REPO / "README.md").read_text()
    tables = _tool("readme_tables")
    assert tables.updated(readme) == readme, "stale: run python tools/readme_tables.py"


def test_the_readme_layout_tree_names_every_module_and_only_real_paths():
    readme = (REPO / "README.md").read_text()
    tree = readme.split("## Layout", 1)[1].split("```", 2)[1]
    # Entries start at most two spaces in; deeper lines continue a description.
    named = set(re.findall(r"^ {0,2}([\w./-]+)", tree, flags=re.MULTILINE))
    for path in named:
        assert (REPO / path).exists() or (REPO / "franka_composer" / path).exists(), path
    package = REPO / "franka_composer"
    for module in package.iterdir():
        if module.name.startswith("__") or module.suffix not in (".py", ""):
            continue
        entry = module.name + ("/" if module.is_dir() else "")
        assert entry in named or module.name in named, f"README's layout misses {entry}"


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
