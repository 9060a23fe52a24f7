"""Every script of the repository a reader is told to run (benchmarks/, experiments/,
tools/) answers `--help` with its usage, as `franka-composer`'s subcommands do: a script
that read its arguments by hand took `--help` for a task or a file and ended in a
traceback."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPTS = sorted(path for folder in ("benchmarks", "experiments", "tools")
                 for path in (ROOT / folder).glob("*.py")
                 if 'if __name__ == "__main__":' in path.read_text())

# Runs each script as `python SCRIPT --help` would, in one interpreter (the heavy imports
# once), and reports each one's exit status and the first line it printed.
_DRIVER = """
import contextlib, io, json, os, runpy, sys
answers = {}
for script in sys.argv[1:]:
    out = io.StringIO()
    sys.argv = [script, "--help"]
    sys.path[0] = os.path.dirname(script)  # Where `python SCRIPT` looks first.
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            runpy.run_path(script, run_name="__main__")
        status = "returned without exiting"
    except SystemExit as exit:
        status = exit.code or 0
    except Exception as error:
        status = f"{type(error).__name__}: {error}"
    answers[script] = [status, out.getvalue().lstrip()[:200]]
print(json.dumps(answers))
"""


def test_every_script_answers_help_with_its_usage():
    assert len(SCRIPTS) > 30  # The folders were found.
    done = subprocess.run([sys.executable, "-c", _DRIVER, *map(str, SCRIPTS)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600, check=True)
    answers = json.loads(done.stdout.splitlines()[-1])
    wrong = {pathlib.Path(script).relative_to(ROOT).as_posix(): answer
             for script, answer in answers.items()
             if answer[0] != 0 or not answer[1].startswith("usage:")}
    assert not wrong, f"scripts that do not answer --help with their usage: {wrong}"
