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


def table(arms: list[tuple[str, str]], marks: list[int],
          window: tuple[int, int] | None,
          paper: tuple[str, str] | None = None) -> str:
    heads = [f"{mark // 1000}k" for mark in marks]
    if window:
        heads.append(f"mean {window[0] // 1000}k–{window[1] // 1000}k")
    lines = ["| arm | " + " | ".join(heads) + " |", "|---|" + "---|" * len(heads)]
    for name, pattern in arms:
        run_dirs = sorted(pathlib.Path(path) for path in glob.glob(pattern))
        if not run_dirs:
            raise SystemExit(f"arm {name!r}: no run directory matches {pattern!r}")
        runs = [read_eval_rows(run / "eval.csv") for run in run_dirs]
        lines.append(f"| {name} | " + " | ".join(arm_row(runs, marks, window)) + " |")
    if paper:
        task, algo = paper
        curves = read_paper_curves(PAPER_CURVES)
        if (task, algo) not in curves:
            raise SystemExit(f"--paper: {PAPER_CURVES} has no curve for {task} {algo} (it has "
                             + ", ".join(" ".join(key) for key in sorted(curves)) + ")")
        lines.append(f"| the paper's {task} {algo} | "
                     + " | ".join(paper_row(curves[task, algo], marks, window)) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arm", nargs=2, action="append", required=True,
                        metavar=("NAME", "GLOB"), help="an arm: its name, its runs' directories")
    parser.add_argument("--marks", nargs="+", type=int,
                        default=[10_000, 20_000, 30_000, 40_000])
    parser.add_argument("--window", nargs=2, type=int, metavar=("START", "END"))
    parser.add_argument("--paper", nargs=2, metavar=("TASK", "ALGO"),
                        help="also the paper's published curve of this cell")
    args = parser.parse_args(argv)
    if args.window and args.window[0] > args.window[1]:
        parser.error(f"--window: start {args.window[0]} is after end {args.window[1]}")
    print(table([tuple(arm) for arm in args.arm], args.marks,
                tuple(args.window) if args.window else None,
                tuple(args.paper) if args.paper else None))


if __name__ == "__main__":
    main()
