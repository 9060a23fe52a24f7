"""Argument types shared by the subcommands, so a bad value is one clear argparse error."""

from __future__ import annotations

import argparse
import functools
import math
import os
import pathlib
import sys

from franka_composer.training.run_config import MAX_TRAINING_SEED
from franka_composer.validation import check_writable, repeated, spelled


def number(text: str) -> float:
    """`text` as a float; NaN (which fails every range check) if it is not a number."""
    try:
        return float(text)
    except ValueError:
        return float("nan")


def finite_number(text: str) -> float:
    """`text` as a finite float, for a task option whose own check then says which range it
    must be in (a word would otherwise reach that check as NaN)."""
    value = number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


#: The largest count a command takes: numpy's and SB3's step counters are int64 (1e99
#: steps was taken, and trained on for good).
MAX_COUNT = 2**63 - 1


def _whole_number(text: str, minimum: int, what: str, maximum: float = math.inf) -> int:
    """`text` as an integer from `minimum` to `maximum`, also written in scientific notation
    (5e5); written in digits, it is read exactly however long (a seed of 20 digits)."""
    value: int | None
    try:
        value = int(text)
    except ValueError:
        as_float = number(text)
        value = int(as_float) if as_float.is_integer() else None
    if value is None or not minimum <= value <= maximum:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """A count: an integer from 1 to `MAX_COUNT`; a whole number in scientific notation
    (5e5) is accepted too."""
    value = _whole_number(text, 1, "a positive integer")
    if value > MAX_COUNT:
        raise argparse.ArgumentTypeError(f"must be at most 2**63 - 1 ({MAX_COUNT:.3g}), got "
                                         f"{text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0; a whole number in scientific notation (1e4) is accepted too."""
    return _whole_number(text, 0, "an integer >= 0")


def frame_size(text: str) -> int:
    """A frame's width or height in pixels: 1 to MuJoCo's offscreen buffer's side."""
    from franka_composer.arenas.floor import MAX_RENDER_SIZE

    return _whole_number(text, 1, f"a whole number of pixels from 1 to {MAX_RENDER_SIZE}",
                         MAX_RENDER_SIZE)


def output_file(text: str) -> pathlib.Path:
    """A file to write at the end of a command: not a folder, and where a file can be made
    (missing parent folders are made when it is written), so a long evaluation is not lost
    to a bad path."""
    path = normal_path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"must be a file, got the folder {text!r}")
    return _writable(path, folder=False)


def output_folder(text: str) -> pathlib.Path:
    """A folder to write into: made if missing, refused if a file stands there or nothing
    can be written there."""
    return _writable(folder_path(text), folder=True)


def normal_path(text: str) -> pathlib.Path:
    """A path a command writes to, with `..` taken out as the file system takes it (after
    a link, from where the link leads; past a folder not there yet, from the path's text):
    "x/../out" made x on the way, which a command that failed left. An empty one is refused
    (`given_path`)."""
    path = given_path(text)
    return pathlib.Path(os.path.realpath(path)) if ".." in path.parts else path


def folder_path(text: str) -> pathlib.Path:
    """A folder that may be read or written, as the command decides (`sweep --out`: read by
    --status and --sync, written by a run, which checks it then): not a file."""
    path = normal_path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"must be a folder, got the file {text!r}")
    return path


def _writable(path: pathlib.Path, folder: bool) -> pathlib.Path:
    """`check_writable`, its refusal as argparse's."""
    try:
        return check_writable(path, folder=folder)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def figure_file(text: str) -> pathlib.Path:
    """An image file in a format matplotlib writes here (png, pdf, svg, ...): pgf needs a
    TeX on the PATH, and failed without one once the figure was drawn."""
    import io

    from matplotlib.backend_bases import FigureCanvasBase
    from matplotlib.figure import Figure

    path = output_file(text)
    formats = FigureCanvasBase.get_supported_filetypes()
    extension = path.suffix[1:].lower()
    if extension not in formats:
        raise argparse.ArgumentTypeError(
            f"must end in an image format's extension ({', '.join(sorted(formats))}), "
            f"got {text!r}")
    probe = Figure(figsize=(1, 1))
    probe.text(0.5, 0.5, "1")  # Text: what pgf asks TeX to measure.
    try:
        probe.savefig(io.BytesIO(), format=extension)
    except Exception as error:  # Whatever stops a format stops it for the figure too.
        raise argparse.ArgumentTypeError(
            f"cannot write {extension} files here, got {text!r}: {error}") from None
    return path


def training_seed(text: str) -> int:
    """A training run's seed: an integer in [0, MAX_TRAINING_SEED]; a whole number in
    scientific notation (1e4) is accepted too."""
    return _whole_number(text, 0, f"an integer from 0 to {MAX_TRAINING_SEED}",
                         MAX_TRAINING_SEED)


def _positive(text: str, what: str) -> float:
    """`text` as a finite number > 0; refused as "must be `what` > 0"."""
    value = number(text)
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be {what} > 0, got {text!r}")
    return value


def positive_number(text: str) -> float:
    """A finite number > 0."""
    return _positive(text, "a number")


def success_percent(text: str) -> float:
    """A success rate in percent, 1 < x <= 100, as the fraction the curves hold. Up to 1 is
    refused: it reads as a fraction (train's --stop-at-success takes one), and a threshold
    of 1 % or less is no threshold for evaluations of 20 episodes (5 % apart)."""
    value = number(text)
    if not 1.0 < value <= 100.0:
        raise argparse.ArgumentTypeError(
            f"must be a success rate in percent, 1 < x <= 100 (80 for 80 %), got {text!r}")
    return value / 100.0


def positive_seconds(text: str) -> float:
    """A finite number of seconds > 0."""
    return _positive(text, "a number of seconds")


def episode_seed(text: str) -> int:
    """The first episode's seed: any integer >= 0 (Gymnasium's seeds); a whole number in
    scientific notation (1e4) is accepted too."""
    return non_negative_int(text)


def standard_deviation(text: str) -> float:
    """A finite number >= 0."""
    value = number(text)
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a standard deviation >= 0, got {text!r}")
    return value


def the_runs_control(policy: pathlib.Path, config, control: str | None) -> str:
    """The controller the --policy run (`config`, its `RunConfig`) acts through; a
    --control that names another is an error."""
    if control not in (None, config.control):
        raise ValueError(f"--policy {policy} acts through {config.control} control, not "
                         f"--control {control}")
    return config.control


def given_path(text: str) -> pathlib.Path:
    """`text` as a path; an empty one (`--out ""`, a variable unset in a script) is refused,
    where pathlib reads it as the current folder: `evaluate ""` scanned that for runs, and
    `rollout --out ""` said that "." must end in .npz."""
    if not text:
        raise argparse.ArgumentTypeError("must be a path, got an empty one ('')")
    return pathlib.Path(text)


def add_run_dirs(parser: argparse.ArgumentParser) -> None:
    """The RUN_DIR arguments of the commands that read finished or running runs."""
    parser.add_argument("runs", nargs="+", type=given_path, metavar="RUN_DIR",
                        help="run directories written by `franka-composer train`, or "
                             "sweep directories (every run in them)")


def report_waiting(waiting, why: str = "has no evaluations yet") -> None:
    """Names on stderr the runs left out as not far enough yet (`split_evaluated`,
    `split_trained`): the table or figure has the others' seeds only."""
    for run in waiting:
        print(f"left out: {run} {why}", file=sys.stderr)


def task_names(text: str) -> tuple[str, ...]:
    """One `--tasks` word: a task name, or several joined by commas (push,slide), each
    checked against `franka_composer.tasks.ALL_TASKS`."""
    from franka_composer.tasks import ALL_TASKS

    tasks = tuple(name.strip() for name in text.split(",") if name.strip())
    unknown = [name for name in tasks if name not in ALL_TASKS]
    if unknown or not tasks:
        raise argparse.ArgumentTypeError(
            f"unknown task(s) {', '.join(unknown) or '(none given)'}; valid tasks: "
            f"{', '.join(ALL_TASKS)}")
    return tasks


class _JoinTasks(argparse.Action):
    """Joins the `--tasks` words, each a tuple of names, into one tuple, in order; a task
    named twice is refused (demo's second run wrote its files over the first's, a sweep's
    over its cells, and a benchmark timed it twice)."""

    def __call__(self, parser, namespace, values, option_string=None):
        tasks = tuple(name for word in values for name in word)
        twice = repeated(tasks)
        if twice:
            raise argparse.ArgumentError(self, f"names {', '.join(twice)} more than once: "
                                               "each task is run once")
        setattr(namespace, self.dest, tasks)


def add_tasks_argument(parser: argparse.ArgumentParser, default, help_text: str) -> None:
    """`--tasks`, one syntax for every subcommand: names separated by spaces, commas or
    both (`--tasks push slide`, `--tasks push,slide`), as one tuple of task names, each
    once."""
    parser.add_argument("--tasks", nargs="+", type=task_names, action=_JoinTasks,
                        default=default, metavar="TASK[,TASK]",
                        help=f"{help_text}; names separated by spaces or commas")


def add_timing(parser: argparse.ArgumentParser, control_timestep_help: str) -> None:
    """--control-timestep SECONDS and --timing NAME (`tasks.options.TIMINGS`), one or the
    other; `timing_options` reads them."""
    from franka_composer.tasks.options import TIMINGS

    parser.add_argument("--control-timestep", type=finite_number, default=None,
                        metavar="SECONDS",
                        help=control_timestep_help)
    parser.add_argument("--timing", choices=tuple(TIMINGS), default=None,
                        help="a named timing instead of --control-timestep: 'default' "
                             "(0.05 s of physics per step, velocities per step) or "
                             "'reference' (what the paper's code runs: 0.5 s of physics per "
                             "step, velocities multiplied by 0.05 s, its softer weld)")


def add_object_damping(parser: argparse.ArgumentParser, default: str) -> None:
    """--object-damping DAMPING: the task option `object_damping` (None when not given);
    `default` says what is damped then."""
    parser.add_argument("--object-damping", type=finite_number, default=None,
                        metavar="DAMPING",
                        help=f"damp the objects' free joints (N s/m and N m s/rad; default: "
                             f"{default}); 0.01 is the paper's code's block, which a push "
                             "slides where an undamped one can tip over (docs/guide/"
                             "physics.md)")


def add_guard_ignores_carried(parser: argparse.ArgumentParser) -> None:
    """--guard-ignores-carried {true,false}: the task option `guard_ignores_carried` (None
    when not given: the task's own)."""
    parser.add_argument("--guard-ignores-carried", type=true_or_false, default=None,
                        metavar="{true,false}",
                        help="whether the surface guard counts a block the hand carries as "
                             "part of the hand, not a surface beneath it (default: the "
                             "task's own: true for stack since its v1, false for the "
                             "others; docs/guide/physics.md)")


def true_or_false(text: str) -> bool:
    """`true` or `false` (any case) as a bool, for argparse."""
    if text.lower() not in ("true", "false"):
        raise argparse.ArgumentTypeError(f"must be true or false, got {text!r}")
    return text.lower() == "true"


def as_flags(command: str, **others: str):
    """Refusals made within it name a setting by `command`'s flag for it, not its field's
    name ("--train-every > 1 needs --update-schedule 'step'"); `others` spells settings a
    flag of another name sets (`stop_after_evaluations="--stop-after"`)."""
    return spelled({**_flags(command), **others})


@functools.cache
def _flags(command: str) -> dict[str, str]:
    """`command`'s flags by the settings they set, read off its parser once (`sweep` asks
    for train's for every cell)."""
    from franka_composer.cli import command_parser

    return {action.dest: option for action in command_parser(command)._actions
            for option in action.option_strings
            if option == "--" + action.dest.replace("_", "-")}


def timing_options(args: argparse.Namespace) -> dict:
    """`control_timestep`, `velocity_timestep` and `weld_time_constant` from --timing or
    --control-timestep (None: the task's); both given is refused."""
    from franka_composer.tasks.options import TIMINGS

    if args.timing is None:
        return {"control_timestep": args.control_timestep, "velocity_timestep": None,
                "weld_time_constant": None}
    if args.control_timestep is not None:
        raise ValueError("--timing sets the control timestep: give --timing or "
                         "--control-timestep, not both")
    return dict(TIMINGS[args.timing])


def given_timing(args: argparse.Namespace, run_timing: dict | None = None) -> dict:
    """The timing options the command line gives (those left to the task omitted); with
    none given, `run_timing` (a --policy run's: it acts at the timing it learned)."""
    given = {name: value for name, value in timing_options(args).items() if value is not None}
    if given or run_timing is None:
        return given
    return {name: value for name, value in run_timing.items() if value is not None}
