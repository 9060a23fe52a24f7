"""Results over many runs in the layout of the paper's Table II (tasks x algorithms)."""

from __future__ import annotations

import collections
import dataclasses

import numpy as np

from franka_composer.tasks import ALL_TASKS
from franka_composer.training.hyperparams import ALGOS

#: Row order of the paper's Table II; the other tasks follow in the registry's order.
TABLE_II_TASKS = ("push", "slide", "pick_and_place")
TASK_ORDER = TABLE_II_TASKS + tuple(t for t in ALL_TASKS if t not in TABLE_II_TASKS)
TASK_TITLES = {task: task.replace("_and_", " & ").replace("_", " ").title()
               for task in ALL_TASKS}


@dataclasses.dataclass(frozen=True)
class RunResult:
    """One trained model's final test."""

    run: str
    task: str
    algo: str
    seed: int
    steps: int
    success_rate: float  # fraction in [0, 1]


def group_by_cell(results: list[RunResult]) -> dict[tuple[str, str], list[RunResult]]:
    """Results keyed by (task, algorithm)."""
    cells: dict[tuple[str, str], list[RunResult]] = collections.defaultdict(list)
    for result in results:
        cells[(result.task, result.algo)].append(result)
    return dict(cells)


def markdown_table(results: list[RunResult]) -> str:
    """Success rate % as mean ± std over seeds (population std, ddof=0) per task and
    algorithm; "–" where no run exists. Rows and columns in the paper's order."""
    cells = group_by_cell(results)
    tasks = [t for t in TASK_ORDER if any(t == task for task, _ in cells)]
    lines = ["| Tasks | " + " | ".join(a.upper() for a in ALGOS) + " |",
             "|---|" + "---|" * len(ALGOS)]
    for task in tasks:
        row = []
        for algo in ALGOS:
            rates = [100.0 * r.success_rate for r in cells.get((task, algo), [])]
            row.append(f"{np.mean(rates):.1f} ± {np.std(rates):.1f}" if rates else "–")
        lines.append(f"| {TASK_TITLES[task]} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def seeds_note(results: list[RunResult]) -> str:
    """One line per non-empty cell: how many seeds and steps it averages."""
    notes = []
    for (task, algo), runs in sorted(group_by_cell(results).items()):
        seeds = ", ".join(str(r.seed) for r in runs)
        steps = ", ".join(str(r.steps) for r in runs)
        notes.append(f"- {task} / {algo}: seeds {seeds}; trained steps {steps}")
    return "\n".join(notes) + "\n"
