"""Results over many runs in the layout of the paper's Table II (tasks x algorithms)."""

from __future__ import annotations

import collections
import dataclasses

import numpy as np

from franka_composer.tasks import ALL_TASKS
from franka_composer.training.hyperparams import ALGOS
from franka_composer.training.run_config import variant_label

#: Row order of the paper's Table II; the other tasks follow in the registry's order.
TABLE_II_TASKS = ("push", "slide", "pick_and_place")
TASK_ORDER = TABLE_II_TASKS + tuple(t for t in ALL_TASKS if t not in TABLE_II_TASKS)
TASK_TITLES = {task: task.replace("_and_", " & ").replace("_", " ").title()
               for task in ALL_TASKS}
#: The paper's Table II: success %, mean ± std over its 3 seeds, 20 test episodes per model,
#: written under a task's rows so that ours stand beside it.
PAPER_TABLE_II = {
    "push": {"ddpg": "11.7 ± 0.3", "sac": "100.0 ± 0.0", "tqc": "100.0 ± 0.0"},
    "slide": {"ddpg": "71.7 ± 0.5", "sac": "85.0 ± 0.4", "tqc": "85.1 ± 0.4"},
    "pick_and_place": {"ddpg": "58.3 ± 0.4", "sac": "75.0 ± 0.5", "tqc": "100.0 ± 0.0"},
}


@dataclasses.dataclass(frozen=True)
class RunResult:
    """One trained model's final test."""

    run: str
    task: str
    algo: str
    seed: int
    steps: int
    success_rate: float  # fraction in [0, 1]
    setup: str = ""  # `RunConfig.setup`: "" for the paper's
    computation: str = ""  # `RunConfig.computation`: "" for the paper's (SB3, fp32)

    @property
    def variant(self) -> str:
        return variant_label(self.setup, self.computation)


def with_variant(name: str, variant: str) -> str:
    """`name`, with " (variant)" after it for a run not of the paper's setup."""
    return name + (f" ({variant})" if variant else "")


def task_label(task: str, variant: str) -> str:
    """"Push", or "Push (osc control)" for a variant: the row a run belongs to."""
    return with_variant(TASK_TITLES[task], variant)


def group_by_cell(results: list) -> dict[tuple[str, str, str], list]:
    """Runs (anything with `task`, `variant` and `algo`: `RunResult`,
    `learning_report.RunRecord`) keyed by (task, variant, algorithm): runs of different
    setups are not seeds of one cell."""
    cells: dict[tuple[str, str, str], list] = collections.defaultdict(list)
    for result in results:
        cells[(result.task, result.variant, result.algo)].append(result)
    return dict(cells)


def cell_order(cell: tuple[str, str, str]) -> tuple:
    """Sort key of a (task, variant, algorithm) cell: the paper's task order, a task's paper
    setup before its variants, the paper's algorithm order."""
    task, variant, algo = cell
    return TASK_ORDER.index(task), variant, ALGOS.index(algo)


def markdown_table(results: list[RunResult]) -> str:
    """Success rate % as mean ± std over seeds (population std, ddof=0), a row per task
    (and setup), a column per algorithm; "–" where no run exists. Rows and columns in the
    paper's order, a task's paper setup before its variants. How a cell's runs were
    computed, where not as the paper's, follows its number ("85.0 ± 5.0 (bf16)"): runs
    computed differently are not averaged, they share the cell side by side. Under a Table
    II task's rows, the paper's (`PAPER_TABLE_II`)."""
    rows: dict[tuple[str, str], dict[str, list[str]]] = {}
    for (task, _, algo), runs in sorted(group_by_cell(results).items(),
                                        key=lambda cell: cell_order(cell[0])):
        rates = [100.0 * run.success_rate for run in runs]
        computation = runs[0].computation
        rows.setdefault((task, runs[0].setup), {}).setdefault(algo, []).append(
            f"{np.mean(rates):.1f} ± {np.std(rates):.1f}"
            + (f" ({computation})" if computation else ""))
    lines = ["| Tasks | " + " | ".join(a.upper() for a in ALGOS) + " |",
             "|---|" + "---|" * len(ALGOS)]
    tasks = [task for task, _ in rows]
    for index, ((task, setup), entries) in enumerate(rows.items()):
        lines.append(_row(task_label(task, setup),
                          ["; ".join(entries.get(algo, [])) or "–" for algo in ALGOS]))
        if task in PAPER_TABLE_II and task not in tasks[index + 1:]:
            lines.append(_row(f"{TASK_TITLES[task]}: the paper's",
                              [PAPER_TABLE_II[task][algo] for algo in ALGOS]))
    return "\n".join(lines) + "\n"


def _row(label: str, cells: list[str]) -> str:
    return f"| {label} | " + " | ".join(cells) + " |"


def seeds_note(results: list[RunResult]) -> str:
    """One line per non-empty cell: the seeds, steps and success rates it averages, so a
    written table keeps each model's figure and not only the mean ± std."""
    notes = []
    for (task, variant, algo), runs in sorted(group_by_cell(results).items()):
        seeds = ", ".join(str(r.seed) for r in runs)
        steps = ", ".join(str(r.steps) for r in runs)
        success = ", ".join(f"{100 * r.success_rate:.1f}" for r in runs)
        notes.append(f"- {with_variant(task, variant)} / {algo}: seeds {seeds}; trained "
                     f"steps {steps}; success {success} %")
    return "\n".join(notes) + "\n"
