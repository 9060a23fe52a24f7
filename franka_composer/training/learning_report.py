"""What each cell (task x algorithm x `RunConfig.variant`) took to learn and what it cost,
from its runs' files alone (config.json, eval.csv, outcome.json): the steps each seed
reached, how many stopped early by the rule, the steps to a success threshold, and
wall-clock and CPU hours.

Steps to a threshold are read off the median over seeds, as one reads the paper's Fig. 4,
of each seed's curve smoothed over `SMOOTHING` evaluations (a trailing mean: 75 episodes at
Table I's 15 per evaluation, so one lucky evaluation does not count): the first evaluated
step at which it reaches the threshold. A seed that stopped early (5 evaluations in a row at
95 % or more) holds its level, the mean of those evaluations, for the steps the others go
on to (`held`; the figure's curves take it so too).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import pathlib

import numpy as np

from franka_composer.training.report import cell_order, group_by_cell, with_variant
from franka_composer.training.runs import RunDir, success_curve
from franka_composer.wording import counted

#: Evaluations in the trailing mean of a seed's curve.
SMOOTHING = 5
#: What the steps and minutes to a threshold read for a cell with a seed too short to smooth.
TOO_FEW = f"n/a (a seed has < {SMOOTHING} evaluations)"
#: How far below a threshold a smoothed success rate may lie and still reach it: a mean of
#: k/15 rates lands on a threshold such as 0.4 or 0.8 only up to rounding (6, 6, 7, 6 and 5
#: of 15 average to 0.39999999999999997), while rates that differ do so by 1/75 or more.
REACH_TOLERANCE = 1e-9
#: Success rates whose first crossing is reported by default (the paper's curves are read at
#: these).
THRESHOLDS = (0.8, 0.9)


def _unfinished(run: "RunRecord") -> str:
    """What the steps column says of a run that has not ended: training now, or stopped
    (to be resumed, or lost)."""
    return "" if run.finished else " (training)" if run.training else " (unfinished)"


@dataclasses.dataclass(frozen=True)
class RunRecord:
    """One run as its files tell it."""

    task: str
    algo: str
    variant: str
    seed: int
    steps: int  # the last evaluated step (a finished run's final step)
    finished: bool
    stopped_early: bool
    wall_s: float
    # To its end, or to its latest checkpoint where unfinished (a lower bound); None where
    # not recorded throughout, or unfinished without a checkpoint.
    cpu_s: float | None
    curve: dict[int, float]  # evaluated step -> success rate
    wall_times: dict[int, float]  # evaluated step -> the run's wall-clock seconds there
    stop_after: int = SMOOTHING  # the evaluations in a row the stopping rule asks for
    training: bool = False  # unfinished, and a process holds its training lock now


def read_run(root: pathlib.Path) -> RunRecord:
    run = RunDir(pathlib.Path(root))
    run.check_config_checkpointed()  # (A hand edit would be reported as another cell.)
    config = run.read_config()
    rows = run.evaluations()
    outcome = run.read_outcome()
    last = rows[-1]
    return RunRecord(
        task=config.task, algo=config.algo, variant=config.variant, seed=config.seed,
        steps=int(outcome.get("steps", last["steps"])), finished=bool(outcome),
        stopped_early=bool(outcome.get("stopped_early", False)),
        wall_s=float(outcome.get("wall_time_s", last["wall_time_s"])),
        cpu_s=(outcome or run.read_state()).get("cpu_time_s"), curve=success_curve(rows),
        wall_times={row["steps"]: row["wall_time_s"] for row in rows},
        stop_after=config.hyperparameters.stop_after_evaluations,
        training=not outcome and run.trainer() is not None)


def smoothed(curve: dict[int, float]) -> dict[int, float]:
    """The trailing mean over `SMOOTHING` evaluations, from the first full window on."""
    steps = sorted(curve)
    values = np.array([curve[step] for step in steps])
    return {steps[i]: float(values[i + 1 - SMOOTHING:i + 1].mean())
            for i in range(SMOOTHING - 1, len(steps))}


def steps_to(runs: list[RunRecord], threshold: float) -> int | None:
    """The first step at which the median over seeds of the smoothed curves reaches
    `threshold`; None if it never does within the steps every seed reached."""
    curves = [smoothed(run.curve) for run in runs]
    if not all(curves):
        return None
    evaluated = set().union(*curves)
    curves = [held(run, curve, evaluated) for run, curve in zip(runs, curves)]
    common = sorted(set.intersection(*(set(curve) for curve in curves)))
    return first_reaching({step: float(np.median([curve[step] for curve in curves]))
                           for step in common}, threshold)


def minutes_to(runs: list[RunRecord], threshold: float) -> float | None:
    """The median over seeds of the wall-clock minutes at which each seed's smoothed curve
    first reaches `threshold` (a seed that never does counts as never); None if the median
    seed never does. What a recipe costs to learn, where steps to a threshold do not
    compare recipes whose steps cost differently."""
    minutes = [np.inf if step is None else run.wall_times[step] / 60 for run, step in (
        (run, _first_reaching_held(run, threshold)) for run in runs)]
    median = float(np.median(minutes)) if minutes else np.inf
    return median if np.isfinite(median) else None


def held(run: RunRecord, curve: dict[int, float], steps) -> dict[int, float]:
    """`curve` (the run's own or smoothed) with the `steps` after its last at the level a
    run that stopped early by the rule holds from there on: the mean of the evaluations
    that met the rule, its last `stop_after` (each at the rule's rate or more). Another
    run's curve comes back as it is."""
    if not run.stopped_early:
        return curve
    last, level = max(curve), _held_level(run)
    return {**curve, **{step: level for step in steps if step > last}}


def _held_level(run: RunRecord) -> float:
    """The level a run stopped early by the rule holds: the mean of its last `stop_after`
    evaluations, those that met the rule."""
    return float(np.mean([run.curve[step] for step in sorted(run.curve)[-run.stop_after:]]))


def _first_reaching_held(run: RunRecord, threshold: float) -> int | None:
    """The first step at which the run's smoothed curve reaches `threshold`, or, for a run
    stopped early whose held level (`held`) reaches it first, its last step: what
    `steps_to` reads, so the two columns agree (a rule of fewer evaluations than the
    smoothing's holds above the curve's last smoothed value)."""
    step = first_reaching(smoothed(run.curve), threshold)
    if step is None and run.stopped_early and _held_level(run) >= threshold - REACH_TOLERANCE:
        return max(run.curve)
    return step


def first_reaching(curve: dict[int, float], threshold: float) -> int | None:
    """The first step at which `curve` reaches `threshold` (to `REACH_TOLERANCE`); None if
    it never does."""
    return next((step for step in sorted(curve)
                 if curve[step] >= threshold - REACH_TOLERANCE), None)


#: The columns of the paper's curves as `experiments/paper_curves.py` writes them.
PAPER_CURVE_COLUMNS = ("task", "algo", "steps", "success")
#: How far outside [0, 1] a success rate read off a figure's pixels may lie (the paper's
#: push SAC curve reads 1.002 at its top).
READ_OFF_TOLERANCE = 0.01


def read_paper_curves(path: pathlib.Path) -> dict[tuple[str, str], dict[int, float]]:
    """The paper's published curves as `experiments/paper_curves.py` writes them (a CSV of
    task, algo, steps, success): {(task, algo): {steps: success}}. A file or row it does not
    write (not UTF-8 text, a task or algorithm this suite has not, steps below 0, a success
    rate outside [0, 1] beyond what reading a figure leaves: a percentage?) is a ValueError
    naming the file and its line."""
    from franka_composer.tasks import ALL_TASKS
    from franka_composer.training.hyperparams import ALGOS

    try:
        text = path.read_text(encoding="utf-8-sig")  # A spreadsheet's byte-order mark too.
    except UnicodeDecodeError as error:
        raise ValueError(f"{path} is not a CSV of curves: it is not UTF-8 text "
                         f"({error})") from None
    curves: dict[tuple[str, str], dict[int, float]] = {}
    reader = csv.DictReader(io.StringIO(text, newline=""))
    missing = [c for c in PAPER_CURVE_COLUMNS if c not in (reader.fieldnames or ())]
    if missing:
        raise ValueError(f"{path} is not a CSV of curves: it has no "
                         f"{', '.join(missing)} column(s) (it needs "
                         f"{', '.join(PAPER_CURVE_COLUMNS)})")
    for line, row in enumerate(reader, start=2):
        try:
            steps, success = int(row["steps"]), float(row["success"])
        except (TypeError, ValueError):
            raise ValueError(f"{path}, line {line}: steps must be a whole number and "
                             f"success a number, got {row['steps']!r}, "
                             f"{row['success']!r}") from None
        problem = (f"unknown task {row['task']!r}" if row["task"] not in ALL_TASKS else
                   f"unknown algorithm {row['algo']!r}" if row["algo"] not in ALGOS else
                   f"steps must be >= 0, got {steps}" if steps < 0 else
                   f"success must be a fraction, within [0, 1] (to {READ_OFF_TOLERANCE:g}, "
                   f"read off a figure), got {success:g}"
                   if not -READ_OFF_TOLERANCE <= success <= 1.0 + READ_OFF_TOLERANCE else None)
        if problem:
            raise ValueError(f"{path}, line {line}: {problem}")
        curves.setdefault((row["task"], row["algo"]), {})[steps] = success
    return curves


def markdown_table(runs: list[RunRecord],
                   paper: dict[tuple[str, str], dict[int, float]] | None = None,
                   wall_clock: bool = False,
                   thresholds: tuple[float, ...] = THRESHOLDS) -> str:
    """One row per cell, in the paper's order, and a line with what all of them cost. With
    the paper's curves (`read_paper_curves`), its steps to each threshold beside ours, read
    the same way off its curve ("–": never reached; blank: no curve for the cell). With
    `wall_clock`, the median seed's minutes to each threshold too (`minutes_to`). A cell
    with a seed of fewer than `SMOOTHING` evaluations has no smoothed curve to read:
    `TOO_FEW`, not "–" (a run stopped early at 100 % after three is not one that never
    reached 80 %)."""
    cells = group_by_cell(sorted(runs, key=lambda r: r.seed))
    columns = [f"steps to {t * 100:g} %" for t in thresholds]
    if wall_clock:
        columns += [f"minutes to {t * 100:g} %" for t in thresholds]
    if paper is not None:
        columns += [f"paper: steps to {t * 100:g} %" for t in thresholds]
    lines = ["| task | algorithm | seeds | steps reached | stopped early | "
             + " | ".join(columns) + " | wall h | CPU h |",
             "|---|---|---|---|---|" + "---|" * len(columns) + "---|---|"]
    for task, variant, algo in sorted(cells, key=cell_order):
        cell = cells[(task, variant, algo)]
        reached = ", ".join(f"{run.steps:,}" + _unfinished(run)
                            for run in cell)
        if any(not smoothed(run.curve) for run in cell):  # Too short to tell.
            crossings = [TOO_FEW] * len(thresholds) * (1 + wall_clock)
        else:
            crossings = [steps_text(steps_to(cell, t)) for t in thresholds]
            if wall_clock:
                crossings += [minutes_text(minutes_to(cell, t)) for t in thresholds]
        if paper is not None:
            curve = paper.get((task, algo))
            crossings += [steps_text(first_reaching(smoothed(curve), t)) if curve else ""
                          for t in thresholds]
        lines.append(
            f"| {with_variant(task, variant)} | {algo.upper()} | "
            f"{', '.join(str(r.seed) for r in cell)} | {reached} | "
            f"{sum(r.stopped_early for r in cell)} of {len(cell)} | "
            + " | ".join(crossings)
            + f" | {sum(r.wall_s for r in cell) / 3600:.1f} | {_cpu_hours(cell)} |")
    return "\n".join(lines) + "\n\n" + _total(runs) + "\n"


def steps_text(step: int | None) -> str:
    """A step in a table: "–" for never."""
    return "–" if step is None else f"{step:,}"


def minutes_text(minutes: float | None) -> str:
    """Minutes in a table, to the tenth: "–" for never."""
    return "–" if minutes is None else f"{minutes:.1f}"


def _cpu_hours(runs: list[RunRecord]) -> str:
    """Their CPU hours; a lower bound where some runs' are unknown or counted to their
    checkpoints (unfinished); "–" where all are unknown."""
    known = [run.cpu_s for run in runs if run.cpu_s is not None]
    if not known:
        return "–"
    hours = f"{sum(known) / 3600:.1f}"
    if len(known) < len(runs):
        return f"≥ {hours} ({len(runs) - len(known)} unknown)"
    return f"≥ {hours}" if not all(run.finished for run in runs) else hours


def _total(runs: list[RunRecord]) -> str:
    finished = sum(run.finished for run in runs)
    return (f"{'All ' if len(runs) > 1 else ''}{counted(len(runs), 'run')} ({finished} "
            "finished): "
            f"{sum(run.wall_s for run in runs) / 3600:.1f} wall-clock hours of runs (one CPU "
            f"each), {_cpu_hours(runs)} CPU hours; {sum(run.steps for run in runs):,} "
            "environment steps.")
