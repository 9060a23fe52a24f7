"""One `--tasks` syntax for every subcommand and benchmark script: names separated by
spaces, commas or both, checked against the tasks, with one error naming the valid ones."""

from __future__ import annotations

import pathlib

import pytest
from conftest import load_script

from franka_composer.cli import build_parser
from franka_composer.tasks import ALL_TASKS

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"
#: Each subcommand with `--tasks`, and the other arguments it needs to parse.
SUBCOMMANDS = {"demo": [], "bench": [], "sweep": ["--out", "sweep-dir"]}


@pytest.mark.parametrize("command", SUBCOMMANDS)
@pytest.mark.parametrize("words", [["push", "slide"], ["push,slide"], ["push,", "slide"],
                                   ["push", ",slide"]])
def test_every_subcommand_takes_tasks_separated_by_spaces_or_commas(command, words):
    args = build_parser().parse_args([command, *SUBCOMMANDS[command], "--tasks", *words])
    assert args.tasks == ("push", "slide")


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_every_subcommand_keeps_the_order_of_its_tasks(command):
    args = build_parser().parse_args(
        [command, *SUBCOMMANDS[command], "--tasks", "flip,push", "reach"])
    assert args.tasks == ("flip", "push", "reach")


@pytest.mark.parametrize("command", SUBCOMMANDS)
@pytest.mark.parametrize("words, twice", [(["flip,push", "reach", "push"], "push"),
                                          (["push,push"], "push"),
                                          (["reach", "slide,reach", "slide"], "reach, slide")])
def test_a_task_named_twice_is_refused_as_parsed(command, words, twice, capsys):
    """demo's second run of it wrote its files over the first's, a sweep's cells shared a
    directory, and bench timed it twice."""
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args([command, *SUBCOMMANDS[command], "--tasks", *words])
    assert exit_info.value.code == 2
    assert (f"argument --tasks: names {twice} more than once: each task is run once"
            in capsys.readouterr().err)


@pytest.mark.parametrize("command", SUBCOMMANDS)
@pytest.mark.parametrize("words, unknown", [(["push,lift"], "lift"), (["push", "lift"], "lift"),
                                            ([","], "(none given)")])
def test_an_unknown_task_is_one_error_naming_the_valid_ones(command, words, unknown, capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args([command, *SUBCOMMANDS[command], "--tasks", *words])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    assert (f"argument --tasks: unknown task(s) {unknown}; valid tasks: "
            f"{', '.join(ALL_TASKS)}") in error


def test_the_defaults_are_every_task_for_demo_and_bench_and_none_for_sweep():
    parser = build_parser()
    assert parser.parse_args(["demo"]).tasks == ALL_TASKS
    assert parser.parse_args(["bench"]).tasks == ALL_TASKS
    assert parser.parse_args(["sweep", "--out", "sweep-dir"]).tasks is None


@pytest.mark.parametrize("script", ["bench", "controllers", "pixels", "randomization"])
def test_the_benchmark_scripts_take_the_same_syntax(script, monkeypatch):
    """Each script's parser is built inside its main (or build_parser); parse through it by
    stopping at the first thing it does after parsing."""
    module = load_script(BENCHMARKS / f"{script}.py")
    if script == "bench":
        args = module.build_parser().parse_args(["--tasks", "push,slide", "reach"])
        assert args.tasks == ("push", "slide", "reach")
        return
    seen = {}

    def stop(tasks, *rest):
        seen["tasks"] = tasks
        raise StopIteration

    monkeypatch.setattr(module, "best_of_rounds", stop)
    with pytest.raises(StopIteration):
        module.main(["--tasks", "push,slide", "reach"])
    assert seen["tasks"] == ("push", "slide", "reach")


@pytest.mark.parametrize("command, option", [
    ("train", "--control-timestep"), ("demo", "--control-timestep"),
    ("rollout", "--control-timestep"), ("train", "--object-damping"),
    ("rollout", "--object-damping")])
@pytest.mark.parametrize("text", ["abc", "nan", "inf"])
def test_a_task_option_that_is_not_a_number_is_refused_as_typed(command, option, text,
                                                                 capsys):
    """The word given, not the NaN it would otherwise reach the task's range check as."""
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, option, text])
    assert f"argument {option}: must be a finite number, got {text!r}" in capsys.readouterr().err
