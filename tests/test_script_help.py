"""Every script of the repository a reader is told to run (benchmarks/, experiments/,
tools/) answers `--help` with its usage, as `franka-composer`'s subcommands do: a script
that read its arguments by hand took `--help` for a task or a file and ended in a
traceback."""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import pytest
from conftest import doc_option, documented_commands

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPTS = sorted(path for folder in ("benchmarks", "experiments", "tools")
                 for path in (ROOT / folder).glob("*.py")
                 if 'if __name__ == "__main__":' in path.read_text())

# Runs each script as `python SCRIPT --help` would, in one interpreter (the heavy imports
# once), and reports each one's exit status, what it printed and the options of every
# argument parser it made.
_DRIVER = """
import argparse, contextlib, io, json, os, runpy, sys
made = []
build = argparse.ArgumentParser.__init__
def record(parser, *args, **kwargs):
    build(parser, *args, **kwargs)
    made.append(parser)
argparse.ArgumentParser.__init__ = record
answers = {}
for script in sys.argv[1:]:
    made.clear()
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
    options = sorted({option for parser in made for option in parser._option_string_actions})
    answers[script] = [status, out.getvalue().lstrip(), options]
print(json.dumps(answers))
"""


#: Scripts the docs name that have since been removed, each where its page says so:
#: (page, script).
REMOVED_SCRIPTS = {
    ("docs/experiments/computation-checks.md", "benchmarks/precision_fidelity.py"),
    ("docs/experiments/demonstrations.md", "benchmarks/critic_probe.py"),
    ("docs/experiments/slide-contact-fix.md", "benchmarks/policy_contact.py"),
    ("docs/experiments/speed-levers.md", "benchmarks/levers.py"),
    ("results/precision/fidelity.md", "benchmarks/precision_fidelity.py"),
}


#: The shell scripts a reader runs (a library they source has no `#!` line).
SHELL_SCRIPTS = sorted(path for folder in ("benchmarks", "experiments", "tools")
                       for path in (ROOT / folder).glob("*.sh")
                       if path.read_text().startswith("#!"))
_SHELL_HELP = """case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \\{0,1\\}//p' "$0"; exit 0 ;; esac"""


@pytest.mark.parametrize("script", SHELL_SCRIPTS, ids=lambda path: path.name)
def test_every_shell_script_answers_help_with_its_header(script):
    """`SCRIPT --help` prints the comment at its top (its usage) and does nothing else
    (`train_throughput.sh` took `--help` for a task to time, `resume_check.sh` and
    `trees_check.sh` passed it to `train` as the runs' options)."""
    assert _SHELL_HELP in script.read_text().splitlines()  # Before anything is run.
    done = subprocess.run(["bash", str(script), "--help"], capture_output=True, text=True,
                          timeout=60, check=False, cwd=ROOT)
    header = script.read_text().splitlines()[1].removeprefix("# ")
    assert (done.returncode, done.stderr) == (0, "")
    assert done.stdout.splitlines()[0] == header


@pytest.fixture(scope="module")
def answers() -> dict:
    """Each script's (exit status, what it printed, its parsers' options) for `--help`, by
    its repository path."""
    done = subprocess.run([sys.executable, "-c", _DRIVER, *map(str, SCRIPTS)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600, check=True)
    return {pathlib.Path(script).relative_to(ROOT).as_posix(): answer
            for script, answer in json.loads(done.stdout.splitlines()[-1]).items()}


def test_every_script_answers_help_with_its_usage(answers):
    assert len(answers) > 30  # The folders were found.
    wrong = {script: [answer[0], answer[1][:200]] for script, answer in answers.items()
             if answer[0] != 0 or not answer[1].startswith("usage:")}
    assert not wrong, f"scripts that do not answer --help with their usage: {wrong}"


def test_the_docs_give_each_script_only_options_it_takes(answers):
    """Every `python benchmarks/…`, `experiments/…` or `tools/…` command the pages give
    (`documented_commands`) names a script that exists, or one its page says was removed
    (`REMOVED_SCRIPTS`), and only options its parsers take (or, for the scripts that pass
    `train` and `evaluate` on, that franka-composer's command takes)."""
    from franka_composer.cli import command_parser

    passed_on = {name: set(command_parser(name)._option_string_actions)
                 for name in ("train", "evaluate")}
    wrong, seen, removed = [], 0, set()
    for page, program, words, _ in documented_commands(
            r"python\s+(?:benchmarks|experiments|tools)/\w+\.py"):
        script = program.split()[-1]
        if script not in answers:
            if (page, script) in REMOVED_SCRIPTS and not (ROOT / script).exists():
                removed.add((page, script))
            else:
                wrong.append(f"{page}: no script {script}")
            continue
        seen += 1
        takes = set(answers[script][2])
        for command in passed_on:
            if command in words and "franka-composer's options" in answers[script][1]:
                takes |= passed_on[command]
        for word in words:
            option = doc_option(word)
            if option and option not in takes:
                wrong.append(f"{page}: {script} has no {option}")
    assert seen > 100  # The commands were found.
    assert wrong == [], "\n".join(wrong)
    assert removed == REMOVED_SCRIPTS  # Each still named, and still gone.
