"""The paper's published learning curves, read off its repository's figures
(github.com/zichunxx/panda_mujoco_gym, docs/Franka{Push,Pick,Slide}Sparse-v1.jpg), so our
Table II cells' steps to 80 % and 90 % stand beside the paper's as numbers, not as a glance.

    python experiments/paper_curves.py REPO_GIT_DIR [--out results/paper-curves] [--overlays]

REPO_GIT_DIR is a clone of that repository (`git show` reads the figures at HEAD). The
figures are seaborn plots: a grey axes area with white grid lines at known ticks, one line
per algorithm in seaborn's "deep" colours (the mean over seeds, drawn from evaluations every
2000 steps), its spread shaded. The axes are calibrated on the grid lines; each algorithm's
line is the median row of the pixels of its colour in each pixel column (columns where a line
drawn later covers it are interpolated), resampled every 2000 steps. Steps to a threshold
are then read as `franka-composer report` reads ours (`learning_report.first_reaching` on
the curve smoothed over 5 evaluations). Writes `curves.csv` (task, algo, steps, success) and
`steps-to.md`; with `--overlays`, `overlay-<task>.png` too: the traced lines and the grid
lines found, drawn over the figure, to check by eye (not committed: they are the paper's
figures).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import pathlib
import subprocess

import numpy as np

from franka_composer.training.learning_report import (PAPER_CURVE_COLUMNS, THRESHOLDS,
                                                      first_reaching, smoothed, steps_text)

#: seaborn's "deep" palette, in the order the paper's legends list the algorithms.
LINE_COLOURS = {"ddpg": (76, 114, 176), "sac": (221, 132, 82), "tqc": (85, 168, 104)}
#: How far (summed over R, G, B) a pixel may be from a line's colour: JPEG noise and the
#: tint of another algorithm's shading drawn over it stay inside; the shading of its own
#: spread (the colour at ~25 % over grey) does not.
COLOUR_TOLERANCE = 60
AXES_GREY = (234, 234, 242)
#: The paper's evaluation interval (Table I): the digitised curves are sampled at it.
EVAL_EVERY = 2000


@dataclasses.dataclass(frozen=True)
class Figure:
    """One published figure: the grid lines' values on each axis, first and step."""

    path: str
    x_ticks: tuple[float, float]  # environment steps
    y_ticks: tuple[float, float]  # success rate


FIGURES = {
    "push": Figure("docs/FrankaPushSparse-v1.jpg", (0.0, 1e5), (0.0, 0.2)),
    "pick_and_place": Figure("docs/FrankaPickSparse-v1.jpg", (0.0, 1e5), (0.0, 0.2)),
    "slide": Figure("docs/FrankaSlideSparse-v1.jpg", (0.0, 2e5), (0.0, 0.2)),
}
#: The legend's corner of the axes (fractions of its width and height, from the top left),
#: whose colour samples are not curves.
LEGEND_CORNER = (0.22, 0.25)


def _runs(mask: np.ndarray) -> list[float]:
    """Centres of the runs of True in a 1-D mask."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(start + stop - 1) / 2 for start, stop in zip(edges[::2], edges[1::2])]


def _axis(centres: list[float], ticks: tuple[float, float], name: str):
    """Pixel -> value along one axis from its grid lines' centres, listed from the lowest
    value up, which must be evenly spaced (a missed or spurious line would shift every
    value)."""
    gaps = np.diff(centres)
    if len(centres) < 3 or np.ptp(gaps) > 0.02 * abs(np.median(gaps)):
        raise ValueError(f"{name} grid lines not found evenly spaced: {centres}")
    first, step = ticks
    slope = step / np.median(gaps)
    return lambda pixel: first + (np.asarray(pixel, float) - centres[0]) * slope


@dataclasses.dataclass(frozen=True)
class Axes:
    """Where the axes area is in the image, and its grid lines (image pixels)."""

    rows: slice
    columns: slice
    x_grid: list[float]
    y_grid: list[float]  # from the lowest value up: the bottom line first


def find_axes(image: np.ndarray) -> Axes:
    """The grey axes area (rows and columns mostly of its colour) and the white grid lines
    that cross it."""
    grey = np.abs(image - np.array(AXES_GREY)).sum(axis=2) < 12
    rows = np.flatnonzero(grey.mean(axis=1) > 0.3)
    columns = np.flatnonzero(grey.mean(axis=0) > 0.3)
    rows, columns = slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1)
    white = image[rows, columns].min(axis=2) > 248
    return Axes(rows, columns,
                x_grid=[columns.start + c for c in _runs(white.mean(axis=0) > 0.3)],
                y_grid=[rows.start + r for r in _runs(white.mean(axis=1) > 0.3)][::-1])


def trace_lines(image: np.ndarray, axes: Axes) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each algorithm's line in image pixels: the columns it shows in, and in each the
    median row of the pixels of its colour (the legend's corner left out)."""
    area = image[axes.rows, axes.columns]
    legend_rows = int(LEGEND_CORNER[1] * area.shape[0])
    legend_columns = int(LEGEND_CORNER[0] * area.shape[1])
    lines = {}
    for algo, colour in LINE_COLOURS.items():
        on_line = np.abs(area - np.array(colour)).sum(axis=2) < COLOUR_TOLERANCE
        on_line[:legend_rows, :legend_columns] = False
        columns = np.flatnonzero(on_line.any(axis=0))
        if columns.size == 0:
            raise ValueError(f"no {algo} line, colour {colour}, in the figure")
        rows = np.array([np.median(np.flatnonzero(on_line[:, c])) for c in columns])
        lines[algo] = (columns + axes.columns.start, rows + axes.rows.start)
    return lines


def digitise(image: np.ndarray, figure: Figure) -> dict[str, dict[int, float]]:
    """Each algorithm's curve, {steps: success} every `EVAL_EVERY` steps it spans."""
    image = np.asarray(image, dtype=int)[..., :3]
    axes = find_axes(image)
    x_of = _axis(axes.x_grid, figure.x_ticks, "x")
    y_of = _axis(axes.y_grid, figure.y_ticks, "y")
    curves = {}
    for algo, (columns, rows) in trace_lines(image, axes).items():
        steps, success = x_of(columns), y_of(rows)
        sampled = np.arange(EVAL_EVERY * max(1, np.ceil(steps[0] / EVAL_EVERY)),
                            steps[-1] + 1, EVAL_EVERY)
        curves[algo] = {int(s): float(v) for s, v in
                        zip(sampled, np.interp(sampled, steps, success))}
    return curves


def steps_to_table(curves: dict[str, dict[str, dict[int, float]]]) -> str:
    """Steps to each threshold and the level at the end, per task and algorithm."""
    lines = ["| task | algorithm | "
             + " | ".join(f"steps to {100 * t:.0f} %" for t in THRESHOLDS)
             + " | last 10 evaluations | plotted to |",
             "|---|---|" + "---|" * len(THRESHOLDS) + "---|---|"]
    for task, by_algo in curves.items():
        for algo, curve in by_algo.items():
            crossings = [first_reaching(smoothed(curve), t) for t in THRESHOLDS]
            last = [curve[s] for s in sorted(curve)[-10:]]
            lines.append(f"| {task} | {algo.upper()} | "
                         + " | ".join(steps_text(c) for c in crossings)
                         + f" | {100 * np.mean(last):.0f} % | {max(curve):,} |")
    return "\n".join(lines) + "\n"


def _read_figure(repo: pathlib.Path, path: str) -> np.ndarray:
    from PIL import Image

    data = subprocess.run(["git", "--git-dir", str(repo), "show", f"HEAD:{path}"],
                          capture_output=True, check=True).stdout
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def _overlay(image: np.ndarray, out: pathlib.Path) -> None:
    """The traced lines in black and the grid lines found in red, over the figure."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = find_axes(np.asarray(image, dtype=int))
    fig, ax = plt.subplots(figsize=(9.75, 7.5), dpi=100)
    ax.imshow(image)
    for x in axes.x_grid:
        ax.axvline(x, color="red", linewidth=0.4)
    for y in axes.y_grid:
        ax.axhline(y, color="red", linewidth=0.4)
    for columns, rows in trace_lines(np.asarray(image, dtype=int), axes).values():
        ax.plot(columns, rows, color="black", linewidth=0.5)
    ax.set_axis_off()
    fig.savefig(out, bbox_inches="tight")
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("repo", type=pathlib.Path, help="the paper repository's git directory")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("results/paper-curves"))
    parser.add_argument("--overlays", action="store_true",
                        help="also draw the traced lines over each figure, to check by eye")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    curves = {}
    for task, figure in FIGURES.items():
        image = _read_figure(args.repo, figure.path)
        curves[task] = digitise(image, figure)
        if args.overlays:
            _overlay(image, args.out / f"overlay-{task}.png")
    with open(args.out / "curves.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(PAPER_CURVE_COLUMNS)
        for task, by_algo in curves.items():
            for algo, curve in by_algo.items():
                writer.writerows((task, algo, s, f"{v:.3f}") for s, v in sorted(curve.items()))
    table = steps_to_table(curves)
    (args.out / "steps-to.md").write_text(table)
    print(table, end="")


if __name__ == "__main__":
    main()
