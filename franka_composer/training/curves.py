"""Success-rate curves as in the paper's Fig. 4: one panel per task, one line per algorithm
(and variant, `RunConfig.variant`, dashed and dotted after the paper's setup), the median
over seeds with median ± std shaded (clipped to [0, 1]), a seed that stopped early by the
rule held at its level."""

from __future__ import annotations

import dataclasses
import pathlib
import textwrap
from typing import Any

import numpy as np

from franka_composer.atomic_files import folders_made_for, replace_atomically
from franka_composer.training.hyperparams import ALGOS
from franka_composer.training.learning_report import RunRecord, held, read_run
from franka_composer.training.report import TASK_ORDER, TASK_TITLES

COLOURS = {"ddpg": "tab:green", "sac": "tab:blue", "tqc": "tab:red"}
#: A panel's variants of one algorithm, in order ("" first): solid, dashed, dotted, ...
LINESTYLES = ("-", "--", ":", "-.")

#: Characters in a line of a panel's title or legend: a longer setup is wrapped, not cut off
#: at the figure's edge (a line of the 12-point title fills the 4.5-inch panel at about 47).
LINE_CHARACTERS = 40

Curves = dict[tuple[str, str, str], list[dict[Any, float]]]  # Keyed by steps or minutes.


def seed_curves(run_dirs: list[pathlib.Path], wall_clock: bool = False) -> Curves:
    """{(task, algo, variant): [per-seed {steps: success rate}]} from the runs' files (with
    `wall_clock`, keyed by each seed's own wall-clock minutes instead); a seed that stopped
    early by the rule holds its level over the steps (or minutes) its cell's other seeds go
    on to (`learning_report.held`), so the cell's line does not end where it stopped."""
    cells: dict[tuple[str, str, str], list[RunRecord]] = {}
    for root in run_dirs:
        run = read_run(pathlib.Path(root))
        if wall_clock:
            # Keyed by minutes, not steps as RunRecord says: `held` reads the record's curve.
            minutes = {run.wall_times[step] / 60: rate for step, rate in run.curve.items()}
            run = dataclasses.replace(run, curve=minutes)  # type: ignore[arg-type]
        cells.setdefault((run.task, run.algo, run.variant), []).append(run)
    curves: Curves = {}
    for cell, runs in cells.items():
        steps = set().union(*(run.curve for run in runs))
        curves[cell] = [held(run, run.curve, steps) for run in runs]
    return curves


def summarise(seeds: list[dict[float, float]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The steps (or minutes) at which any seed was evaluated, from the seeds' latest first
    evaluation to their earliest last one, and the median and std of success there, each
    seed read at its latest evaluation by then (seeds keyed by wall-clock minutes were
    evaluated at other moments each). A cell's line goes only as far as all its seeds: a
    seed evaluated once makes it one point."""
    start, end = max(min(s) for s in seeds), min(max(s) for s in seeds)
    steps = sorted(t for t in set().union(*seeds) if start <= t <= end)
    values = np.array([[_latest(s, step) for step in steps] for s in seeds])
    return np.array(steps), np.median(values, axis=0), np.std(values, axis=0)


def _latest(curve: dict[float, float], moment: float) -> float:
    """The curve's value at its latest point at or before `moment`."""
    return curve[max(t for t in curve if t <= moment)]


def split_setups(variants: list[str]) -> tuple[str, dict[str, str]]:
    """The parts of a panel's variants (`variant_label`'s ", "-joined parts) that all its
    lines share, for its title, and each variant's own parts, for its legend: the slide
    cells' "net_arch 256,256,256, batch_size 512, bf16" and "..., sbx" made legends wider
    than their panel."""
    parts = {variant: variant.split(", ") if variant else [] for variant in variants}
    shared = [part for part in parts[variants[0]]
              if all(part in own for own in parts.values())] if variants else []
    return ", ".join(shared), {variant: ", ".join(p for p in own if p not in shared)
                               for variant, own in parts.items()}


def plot_curves(run_dirs: list[pathlib.Path], out: pathlib.Path,
                wall_clock: bool = False) -> list[tuple[str, str, str]]:
    """Writes the figure to `out`, over environment steps or, with `wall_clock`, over each
    run's wall-clock minutes; returns the (task, algo, variant) lines drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = seed_curves(run_dirs, wall_clock)
    tasks = [t for t in TASK_ORDER if any(t == task for task, _, _ in curves)]
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.5 * len(tasks), 3.6), squeeze=False,
                             layout="constrained")
    drawn = []
    for ax, task in zip(axes[0], tasks):
        shared, own = split_setups(sorted({v for t, _, v in curves if t == task}))
        for algo in ALGOS:
            variants = sorted(v for t, a, v in curves if (t, a) == (task, algo))
            for variant in variants:
                seeds = curves[(task, algo, variant)]
                steps, median, std = summarise(seeds)
                setup = f", {own[variant]}" if own[variant] else ""
                ax.plot(steps, median, color=COLOURS[algo],
                        marker="o" if len(steps) == 1 else "",  # Else a point draws nothing.
                        linestyle=LINESTYLES[variants.index(variant) % len(LINESTYLES)],
                        label=textwrap.fill(f"{algo.upper()} ({len(seeds)} "
                                            f"seed{'s' * (len(seeds) > 1)}{setup})",
                                            LINE_CHARACTERS))
                ax.fill_between(steps, np.clip(median - std, 0, 1),
                                np.clip(median + std, 0, 1), color=COLOURS[algo], alpha=0.2,
                                linewidth=0)
                drawn.append((task, algo, variant))
        title = f"Franka{TASK_TITLES[task].replace(' & ', 'And').replace(' ', '')}"
        ax.set_title(f"{title}\n{textwrap.fill(f'({shared})', LINE_CHARACTERS)}" if shared
                     else title)
        if wall_clock:
            ax.set_xlabel("wall-clock minutes")
        else:
            ax.set_xlabel("environment steps")
            # "20k" rather than "20000": full numbers run into each other on a narrow panel.
            ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:g}k" if x else "0")
        at = {x for line in ax.get_lines() for x in line.get_xdata()}
        if len(at) == 1:  # Matplotlib widens one step by a thousandth of it: "-4e-05k" ticks.
            (x,) = at
            ax.set_xlim(x - 1, x + 1)
            ax.set_xticks([x])
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        # Within its axes it needs no room of its own; where it does not fit, room is made
        # below (`_move_tall_legends_below`).
        ax.legend(loc="upper left").set_in_layout(False)
    axes[0][0].set_ylabel("success rate")
    _move_tall_legends_below(fig, axes[0])
    with folders_made_for(out):
        replace_atomically(out, lambda partial: fig.savefig(partial, dpi=120))
    plt.close(fig)
    return drawn


def _move_tall_legends_below(fig, axes) -> None:
    """A legend taller than its panel (many setups) goes below the panel's x label, and the
    figure grows by the room it takes there: inside, it ran off the figure's bottom."""
    from matplotlib.transforms import ScaledTranslation

    fig.canvas.draw()  # Lays the panels out: the legends' sizes are known.
    renderer, grown = fig.canvas.get_renderer(), 0.0
    for ax in axes:
        if ax.get_legend().get_window_extent(renderer).y0 >= ax.bbox.y0:
            continue
        # Inches from the axes' bottom to the x label's: these stay as the figure grows.
        drop = (ax.bbox.y0 - ax.xaxis.label.get_window_extent(renderer).y0) / fig.dpi
        below = ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0), bbox_transform=(
            ax.transAxes + ScaledTranslation(0, -drop, fig.dpi_scale_trans)))
        grown = max(grown, drop + below.get_window_extent(renderer).height / fig.dpi)
    fig.set_figheight(fig.get_figheight() + grown)
