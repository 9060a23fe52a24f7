"""The README's and the guide's Python blocks run as written, and what their comments say a
line gives is what it gives: a user copies these first.

Each page's blocks run in order as one script (a later block may use an earlier one's
imports), in a fresh interpreter, as a user's would. A comment is checked where it can be:
after an expression, a leading literal (`# (50, 2.5)`, `# 1.0: a time-out`) is the
expression's value; after any statement, a comparison (`# obs["x"].shape == (4, 84, 84, 3)`)
holds. Other comments are prose.
"""
import ast
import io
import os
import re
import subprocess
import sys
import tokenize
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = sorted([REPO / "README.md", REPO / "docs" / "index.md",
                *(REPO / "docs" / "guide").glob("*.md")])
PAGES_WITH_CODE = [page for page in PAGES if "```python\n" in page.read_text()]


def python_blocks(page: Path) -> str:
    return "".join(re.findall(r"^```python\n(.*?)^```", page.read_text(), re.S | re.M))


def _comments(source: str) -> dict[int, str]:
    """Line number -> the text of that line's comment."""
    return {token.start[0]: token.string.lstrip("#").strip()
            for token in tokenize.generate_tokens(io.StringIO(source).readline)
            if token.type == tokenize.COMMENT}


def _claim(comment: str):
    """('value', literal) or ('holds', expression source) or None for prose."""
    try:
        expression = ast.parse(comment, mode="eval").body
    except SyntaxError:
        expression = None
    if isinstance(expression, ast.Compare):
        return "holds", comment
    for literal in (comment, comment.split(":")[0].strip()):  # `{'a': 1}`, `1.0: prose`
        try:
            return "value", ast.literal_eval(literal)
        except (ValueError, SyntaxError):
            continue
    return None


def checked_script(source: str) -> str:
    """The blocks' statements, each followed by an assertion of what its comment says."""
    lines = source.splitlines()
    comments = _comments(source)
    script = ["def _same(got, want):\n"
              "    import numpy as np\n"
              "    return bool(np.all(np.asarray(got) == np.asarray(want))) and "
              "np.shape(got) == np.shape(want)\n"]
    for node in ast.parse(source).body:
        text = "\n".join(lines[node.lineno - 1:node.end_lineno])
        claim = _claim(comments.get(node.end_lineno, ""))
        if claim is None:
            script.append(text)
        elif claim[0] == "holds":
            script += [text, f"assert {claim[1]}, {claim[1]!r}"]
        elif isinstance(node, ast.Expr):
            expression = ast.get_source_segment(source, node.value)
            script += [f"_got = {expression}",
                       f"assert _same(_got, {claim[1]!r}), "
                       f"({expression!r}, 'gives', _got, 'not', {claim[1]!r})"]
        else:
            script.append(text)
    return "\n".join(script) + "\n"


def test_the_pages_comments_are_read_as_claims_where_they_can_be():
    source = ('x = (50, 2.5)\nx  # (50, 2.5)\nx[0]  # 1.0: prose after the value\n'
              'y = [1, 2]  # len(y) == 3\nx  # prose\n{"a": 1}  # {"a": 1}\n')
    script = checked_script(source)
    assert "assert _same(_got, 1.0)" in script
    assert "assert len(y) == 3" in script
    assert "assert _same(_got, {'a': 1})" in script
    assert script.count("assert ") == 4  # The prose after the last x asserts nothing.
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert "AssertionError: ('x[0]', 'gives', 50, 'not', 1.0)" in run.stderr


def test_every_python_block_is_marked_as_the_runner_finds_it():
    """A block marked ```py (or ```python3, ```pycon) would be left out of the run below
    without a word."""
    languages = {line.split()[0].removeprefix("```") for page in PAGES
                 for line in page.read_text().splitlines() if line.startswith("```")}
    assert "python" in languages
    assert [language for language in languages if language != "python"
            and language.lstrip("{i").startswith("py")] == []
    assert {page.name for page in PAGES_WITH_CODE} >= {"README.md", "index.md",
                                                       "quickstart.md"}


@pytest.mark.parametrize("page", PAGES_WITH_CODE, ids=lambda page: str(page.relative_to(REPO)))
def test_each_pages_python_runs_as_written_and_gives_what_it_says(page, tmp_path):
    script = checked_script(python_blocks(page))
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         cwd=tmp_path, env=dict(os.environ), timeout=600)
    assert run.returncode == 0, f"{page.relative_to(REPO)}:\n{run.stderr[-3000:]}"
