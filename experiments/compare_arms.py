"""Do two training setups learn the same? Success per arm at fixed steps, mean ± std over seeds.

The campaign's rule for a faster setting (bf16, sbx) is that it learns what the reference learns
within the seed spread; this prints the table both of its checks are judged on, from the
runs' eval.csv files:

    python experiments/compare_arms.py --arm fp32 'results/precision/fp32/*' \\
        --arm bf16 'results/precision/bf16/*' --marks 50000 100000 --window 60000 100000

An arm is a name and a glob of run directories (one per seed). `--window A B` adds each
run's mean success over its evaluations from A to B (a run counts once it has reached B).
`--paper TASK ALGO` adds the paper's published curve for that cell as a last row (read off
its figures by `experiments/paper_curves.py`: one line, the paper's mean over its seeds, so
no spread), to set a run beside the curve it should follow:

    python experiments/compare_arms.py --arm reference-env 'results/reference-env/*' \
        --marks 200000 300000 400000 --window 380000 440000 --paper pick_and_place tqc

`--windows STEP` adds a second table: each arm's mean success over consecutive windows
(A, A + STEP], from step 0 to the last evaluation, at 0.1 % (each run's mean over its
evaluations in the window, then the mean ± std over the arm's runs that evaluated there; a
window a run stopped inside reads "(to Nk)"). RESULTS.md's per-5e4-step tables are its output:

    python experiments/compare_arms.py --arm learning-starts 'results/learning-starts/*' \
        --windows 50000 --paper pick_and_place tqc
"""

from __future__ import annotations

import argparse
import glob
import pathlib

import numpy as np

from franka_composer.training.learning_report import read_paper_curves
from franka_composer.training.runs import read_eval_rows

#: The paper's curves as experiments/paper_curves.py wrote them.
PAPER_CURVES = pathlib.Path(__file__).resolve().parents[1] / "results/paper-curves/curves.csv"


def _percent(rates: list[float]) -> str:
    if not rates:
        return "–"
    return f"{100 * np.mean(rates):.0f} ± {100 * np.std(rates):.0f} % (n={len(rates)})"


def arm_row(runs: list[list[dict[str, float]]], marks: list[int],
            window: tuple[int, int] | None) -> list[str]:
    """The cells of one arm's row: each mark over the runs that evaluated it, then the window."""
    cells = [_percent([row["success_rate"] for rows in runs for row in rows
                       if row["steps"] == mark]) for mark in marks]
    if window:
        start, end = window
        cells.append(_percent([
            float(np.mean([row["success_rate"] for row in rows if start <= row["steps"] <= end]))
            for rows in runs if rows and rows[-1]["steps"] >= end]))
    return cells


def paper_row(curve: dict[int, float], marks: list[int],
              window: tuple[int, int] | None) -> list[str]:
    """The cells of the paper's curve: its point at each mark, then its mean over the window
    ("–" where the figure has no point there)."""
    def cell(rates: list[float]) -> str:
        return f"{100 * np.mean(rates):.0f} %" if rates else "–"
    cells = [cell([curve[mark]] if mark in curve else []) for mark in marks]
    if window:
        cells.append(cell([rate for step, rate in curve.items()
                           if window[0] <= step <= window[1]]))
    return cells


def window_cell(runs: list[list[dict[str, float]]], start: int, end: int) -> str:
    """The mean over runs of each run's mean success in (start, end], at 0.1 % (± their
    standard deviation where the arm has more than one run, and how many runs where not all
    evaluated there)."""
    means, stopped = [], []
    for rows in runs:
        rates = [row["success_rate"] for row in rows if start < row["steps"] <= end]
        if rates:
            means.append(np.mean(rates))
            if rows[-1]["steps"] < end:
                stopped.append(int(rows[-1]["steps"]))
    if not means:
        return ""
    cell = f"{100 * np.mean(means):.1f}"
    if len(runs) > 1:
        cell += f" ± {100 * np.std(means):.1f}"
        if len(means) < len(runs):
            cell += f" (n={len(means)})"
    return f"{cell} (to {min(stopped) // 1000}k)" if stopped else cell


def windows_table(arms: list[tuple[str, list[list[dict[str, float]]]]], step: int,
                  paper: tuple[str, dict[int, float]] | None = None) -> str:
    """Each arm's (and the paper's, as an arm of one run) mean success per window
    (A, A + step], to the last evaluation of any arm."""
    last = max((rows[-1]["steps"] for _, runs in arms for rows in runs if rows), default=0)
    if not last:
        raise SystemExit("--windows: no arm has an evaluation after step 0")
    if paper:
        name, curve = paper
        arms = arms + [(name, [[{"steps": at, "success_rate": rate}
                                for at, rate in sorted(curve.items())]])]
    edges = list(range(0, int(np.ceil(last / step)) * step + 1, step))
    windows = list(zip(edges, edges[1:]))
    lines = ["| mean success (%) per window | "
             + " | ".join(f"{start // 1000}–{end // 1000}k" for start, end in windows) + " |",
             "|---|" + "---|" * len(windows)]
    for name, runs in arms:
        lines.append(f"| {name} | "
                     + " | ".join(window_cell(runs, *window) for window in windows) + " |")
    return "\n".join(lines)


def read_arms(arms: list[tuple[str, str]]) -> list[tuple[str, list[list[dict[str, float]]]]]:
    """Each arm's name and its runs' evaluations, one list per run directory its glob matches."""
    read = []
    for name, pattern in arms:
        run_dirs = sorted(pathlib.Path(path) for path in glob.glob(pattern)
                          if (pathlib.Path(path) / "eval.csv").is_file())
        if not run_dirs:
            raise SystemExit(f"arm {name!r}: no run directory (one with an eval.csv) "
                             f"matches {pattern!r}")
        read.append((name, [read_eval_rows(run / "eval.csv") for run in run_dirs]))
    return read


def paper_curve(task: str, algo: str) -> dict[int, float]:
    curves = read_paper_curves(PAPER_CURVES)
    if (task, algo) not in curves:
        raise SystemExit(f"--paper: {PAPER_CURVES} has no curve for {task} {algo} (it has "
                         + ", ".join(" ".join(key) for key in sorted(curves)) + ")")
    return curves[task, algo]


def table(arms: list[tuple[str, str]], marks: list[int],
          window: tuple[int, int] | None,
          paper: tuple[str, str] | None = None, windows: int | None = None) -> str:
    heads = [f"{mark // 1000}k" for mark in marks]
    if window:
        heads.append(f"mean {window[0] // 1000}k–{window[1] // 1000}k")
    lines = ["| arm | " + " | ".join(heads) + " |", "|---|" + "---|" * len(heads)]
    read = read_arms(arms)
    for name, runs in read:
        lines.append(f"| {name} | " + " | ".join(arm_row(runs, marks, window)) + " |")
    paper_arm = (f"the paper's {paper[0]} {paper[1]}", paper_curve(*paper)) if paper else None
    if paper_arm:
        name, curve = paper_arm
        lines.append(f"| {name} | " + " | ".join(paper_row(curve, marks, window)) + " |")
    if windows:
        lines += ["", windows_table(read, windows, paper_arm)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arm", nargs=2, action="append", required=True,
                        metavar=("NAME", "GLOB"), help="an arm: its name, its runs' directories")
    parser.add_argument("--marks", nargs="+", type=int,
                        default=[10_000, 20_000, 30_000, 40_000])
    parser.add_argument("--window", nargs=2, type=int, metavar=("START", "END"))
    parser.add_argument("--paper", nargs=2, metavar=("TASK", "ALGO"),
                        help="also the paper's published curve of this cell")
    parser.add_argument("--windows", type=int, metavar="STEP",
                        help="also each arm's mean success per window (A, A + STEP]")
    args = parser.parse_args(argv)
    if args.windows is not None and args.windows <= 0:
        parser.error(f"--windows: the step must be positive, not {args.windows}")
    if args.window and args.window[0] > args.window[1]:
        parser.error(f"--window: start {args.window[0]} is after end {args.window[1]}")
    print(table([tuple(arm) for arm in args.arm], args.marks,
                tuple(args.window) if args.window else None,
                tuple(args.paper) if args.paper else None, args.windows))


if __name__ == "__main__":
    main()
