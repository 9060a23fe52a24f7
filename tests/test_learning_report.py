"""`franka-composer report`: steps to thresholds and costs per cell, from run files alone
(training/learning_report.py, cli/report.py); what makes a cell (`RunConfig.variant`, also
for `evaluate`'s Table II, training/report.py)."""

from __future__ import annotations

import json
import pathlib

import pytest

from franka_composer import cli
from franka_composer.training import hyperparameters
from franka_composer.training import report
from franka_composer.training.learning_report import (SMOOTHING, markdown_table,
                                                      minutes_to, read_paper_curves,
                                                      read_run, smoothed, steps_to)
from franka_composer.training.run_config import RunConfig
from franka_composer.training.runs import RunDir


def _write_run(root, task, algo, seed, rates, outcome=None, name="", seconds=10,
               **settings):
    """A run whose evaluations every 2000 steps had `rates`, `seconds` apart; `outcome` is
    (stopped_early, cpu_time_s) for a finished run; `settings` go to its RunConfig."""
    run = RunDir(root / f"{task}-{algo}-seed{seed}{name}")
    run.write_config(RunConfig(task, algo, seed, hyperparameters(task, algo), **settings))
    run.eval_csv.write_text("steps,wall_time_s,success_rate,mean_reward\n" + "".join(
        f"{2000 * i},{seconds * i},{rate},-1\n" for i, rate in enumerate(rates)))
    if outcome is not None:
        run.write_outcome(2000 * (len(rates) - 1), outcome[0], 10 * (len(rates) - 1),
                          outcome[1])
    return run.root


def test_a_curve_is_smoothed_over_full_windows_of_five_evaluations():
    assert SMOOTHING == 5
    curve = {0: 0.0, 2000: 1.0, 4000: 0.0, 6000: 1.0, 8000: 0.5, 10000: 1.0}
    assert smoothed(curve) == {8000: pytest.approx(0.5), 10000: pytest.approx(0.7)}
    assert smoothed({0: 1.0, 2000: 1.0}) == {}  # No full window yet.


def test_steps_to_a_threshold_follow_the_median_seed(tmp_path):
    # Smoothed: seed 0 reaches 0.8 at 14000 and 1.0 at 16000, seed 1 0.8 at 10000 and 1.0
    # at 12000, seed 2 never passes 0.2: the median is seed 0, the second best.
    seed0 = [0.0] * 4 + [1.0] * 6
    seed1 = [0.0] * 2 + [1.0] * 8
    seed2 = [0.2] * 10
    runs = [read_run(_write_run(tmp_path, "push", "sac", s, rates))
            for s, rates in enumerate((seed0, seed1, seed2))]
    assert (steps_to(runs, 0.8), steps_to(runs, 0.9)) == (14000, 16000)
    assert steps_to(runs[1:2], 0.8) == 10000
    assert steps_to(runs[2:], 0.1) == 8000  # The first full window.
    assert steps_to(runs[2:], 0.3) is None


def test_a_smoothed_rate_on_the_threshold_reaches_it(tmp_path):
    """6, 6, 7, 6 and 5 successes of 15 are 30 of 75, 40 %: their mean in floating point is
    0.39999999999999997, and it reaches 0.4 all the same (it did not: 104k for 100k in
    RESULTS.md's randomisation table); 29 of 75 does not."""
    rates = [0.0] * 3 + [k / 15 for k in (6, 6, 7, 6, 5)]
    assert smoothed(dict(enumerate(rates)))[7] < 0.4
    run = read_run(_write_run(tmp_path, "push", "sac", 0, rates))
    assert steps_to([run], 0.4) == 14000
    below = read_run(_write_run(tmp_path, "push", "sac", 1, rates[:-1] + [4 / 15]))
    assert steps_to([below], 0.4) is None


def test_minutes_to_a_threshold_are_the_median_seeds_own_wall_clock(tmp_path, capsys):
    # Smoothed, seed 0 reaches 0.8 at its 8th evaluation (70 s) and 0.9 at its 9th (80 s);
    # seed 1, whose steps take 3x longer, at its 6th (150 s) and 7th (180 s); seed 2
    # never, so it counts as never: the median is seed 1's, though in steps it is ahead.
    for seed, rates, seconds in ((0, [0.0] * 4 + [1.0] * 6, 10),
                                 (1, [0.0] * 2 + [1.0] * 8, 30), (2, [0.2] * 10, 10)):
        _write_run(tmp_path, "push", "sac", seed, rates, seconds=seconds)
    runs = [read_run(root) for root in sorted(tmp_path.iterdir())]
    assert (minutes_to(runs, 0.8), minutes_to(runs, 0.9)) == (2.5, 3.0)
    assert minutes_to(runs[:1], 0.9) == pytest.approx(80 / 60)
    assert minutes_to(runs[2:], 0.3) is None
    assert minutes_to(runs[1:], 0.8) is None  # Seed 1's 150 s and never: the median never.
    assert cli.main(["report", str(tmp_path), "--wall-clock"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0] == ("| task | algorithm | seeds | steps reached | stopped early | "
                       "steps to 80 % | steps to 90 % | minutes to 80 % | minutes to 90 % | "
                       "wall h | CPU h |")
    assert rows[2] == ("| push | SAC | 0, 1, 2 | 18,000 (unfinished), 18,000 (unfinished), "
                       "18,000 (unfinished) | 0 of 3 | 14,000 | 16,000 | 2.5 | 3.0 | 0.1 | – |")
    # One whose training lock a process holds is training now (all three read "running",
    # stopped or not).
    with RunDir(tmp_path / "push-sac-seed1").training_lock():
        assert cli.main(["report", str(tmp_path)]) == 0
    assert ("| 0, 1, 2 | 18,000 (unfinished), 18,000 (training), 18,000 (unfinished) |"
            in capsys.readouterr().out)


def test_curves_over_wall_clock_read_each_seed_at_its_latest_evaluation(tmp_path):
    """Seeds evaluated at other moments: the median is taken at every moment any seed was
    evaluated, each seed at its latest evaluation by then, up to the earliest last one."""
    from franka_composer.training.curves import seed_curves, summarise

    fast = _write_run(tmp_path, "push", "sac", 0, [0.0, 0.5, 1.0, 1.0], seconds=60)
    slow = _write_run(tmp_path, "push", "sac", 1, [0.0, 0.2, 0.4, 0.6], seconds=90)
    seeds = seed_curves([fast, slow], wall_clock=True)[("push", "sac", "")]
    assert seeds == [{0.0: 0.0, 1.0: 0.5, 2.0: 1.0, 3.0: 1.0},
                     {0.0: 0.0, 1.5: 0.2, 3.0: 0.4, 4.5: 0.6}]
    minutes, median, _ = summarise(seeds)
    assert minutes.tolist() == [0.0, 1.0, 1.5, 2.0, 3.0]  # Up to the fast seed's last.
    assert median.tolist() == pytest.approx([0.0, 0.25, 0.35, 0.6, 0.7])
    # Over steps, both were evaluated at the same steps: nothing is held across.
    steps, median, _ = summarise(seed_curves([fast, slow])[("push", "sac", "")])
    assert steps.tolist() == [0, 2000, 4000, 6000]
    assert median.tolist() == pytest.approx([0.0, 0.35, 0.7, 0.8])


def test_plot_over_wall_clock_writes_the_figure(tmp_path, capsys):
    runs = [_write_run(tmp_path / "runs", "push", "sac", seed, [0.0, 0.5, 1.0], seconds=60)
            for seed in (0, 1)]
    out = tmp_path / "curves.png"
    assert cli.main(["plot", *map(str, runs), "--wall-clock", "--out", str(out)]) == 0
    assert capsys.readouterr().out == f"1 curve -> {out}\n" and out.stat().st_size > 0


def _plotted(runs, out, monkeypatch):
    """The figure `plot` draws of `runs` into `out`, laid out at its own size."""
    import matplotlib.pyplot as plt

    figures, close = [], plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: figures.append(fig) or close(fig))
    assert cli.main(["plot", *map(str, runs), "--out", str(out)]) == 0
    figures[0].draw_without_rendering()  # Closed, its canvas no longer draws.
    return figures[0]


def test_a_cell_whose_seeds_share_one_evaluation_is_a_point_that_shows(tmp_path, monkeypatch):
    """A seed evaluated once cuts its cell's line to one point, which a line without a
    marker does not draw, on an axis matplotlib ticked at "-4e-05k"."""
    from franka_composer.training.curves import seed_curves, summarise

    runs = [_write_run(tmp_path, "push", "sac", 0, [0.6]),
            _write_run(tmp_path, "push", "sac", 1, [0.0, 0.2, 0.6, 1.0])]
    steps, median, _ = summarise(seed_curves(runs)[("push", "sac", "")])
    assert steps.tolist() == [0] and median.tolist() == [0.3]
    for drawn in (runs, runs[:1]):  # A run evaluated once alone is a point too.
        (axes,) = _plotted(drawn, tmp_path / "curves.png", monkeypatch).axes
        (line,) = axes.get_lines()
        assert line.get_xdata().tolist() == [0] and line.get_marker() == "o"
        assert [label.get_text() for label in axes.get_xticklabels()] == ["0"]
        left, right = axes.get_xlim()
        assert left < 0 < right and right - left >= 2


def test_long_setups_are_wrapped_and_nothing_is_cut_off(tmp_path, monkeypatch):
    """A legend of long variants ran off the figure's right edge, and one of many off its
    bottom; the title of one long variant was cut on both sides."""
    long = {"control_timestep": 0.1, "weld_time_constant": 0.02, "object_damping": 0.01}
    runs = [_write_run(tmp_path, "push", "sac", 0, [0.0, 0.5]),
            _write_run(tmp_path, "push", "sac", 0, [0.0, 0.5], name="a", **long),
            _write_run(tmp_path, "push", "sac", 0, [0.0, 0.5], name="b",
                       terminate_on_success=False, **long),
            _write_run(tmp_path, "slide", "sac", 0, [0.0, 0.5], terminate_on_success=False,
                       **long)]
    runs += [_write_run(tmp_path, "pick_and_place", algo, 0, [0.0, 0.5], name=f"{weld}",
                        control_timestep=0.1, weld_time_constant=weld, object_damping=damping)
             for algo in ("ddpg", "sac", "tqc")
             for weld, damping in ((0.02, 0.01), (0.03, 0.02), (0.04, 0.03))]
    fig = _plotted(runs, tmp_path / "curves.png", monkeypatch)
    push, slide, many = fig.axes
    assert "no termination on success" in slide.get_title()
    for artist in (a for ax in fig.axes for a in (ax.title, ax.xaxis.label, ax.yaxis.label,
                                                   ax.get_legend())):
        extent = artist.get_window_extent()
        assert fig.bbox.contains(extent.x0, extent.y0), artist
        assert fig.bbox.contains(extent.x1, extent.y1), artist
    # Three entries fit inside their panel; nine go below its x label.
    inside, below = (ax.get_legend().get_window_extent() for ax in (push, many))
    assert push.bbox.y0 < inside.y0 and inside.y1 < push.bbox.y1
    assert len(many.get_legend().get_texts()) == 9
    assert below.y1 < many.xaxis.label.get_window_extent().y0


def test_plot_writes_its_figure_whole_or_not_at_all(tmp_path, monkeypatch):
    """An interrupted save left a broken image where the figure was to be."""
    import io

    from matplotlib.figure import Figure

    save = Figure.savefig

    def interrupted(fig, path, **options):
        if isinstance(path, io.BytesIO):  # --out's check that png can be written here.
            return save(fig, path, **options)
        pathlib.Path(path).write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt

    run = _write_run(tmp_path / "runs", "push", "sac", 0, [0.0, 0.5])
    out = tmp_path / "figures" / "curves.png"
    out.parent.mkdir()
    out.write_text("kept")
    monkeypatch.setattr(Figure, "savefig", interrupted)
    with pytest.raises(KeyboardInterrupt):
        cli.main(["plot", str(run), "--out", str(out)])
    assert [path.name for path in out.parent.iterdir()] == ["curves.png"]
    assert out.read_bytes() == b"kept"


@pytest.mark.parametrize("command, name", [("plot", "curves.png"), ("report", "table.md")])
def test_a_command_stopped_before_its_file_lands_leaves_no_folder_it_made(
        tmp_path, monkeypatch, command, name):
    """`--out sub/deeper/x` made sub/deeper/, and left it empty when stopped before x
    landed (and `new/..` on the way made new/)."""
    from franka_composer import atomic_files

    run = _write_run(tmp_path / "runs", "push", "sac", 0, [0.0, 0.5])

    def stopped(path):
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic_files, "sync_to_disk", stopped)
    given = str(run) if command == "plot" else str(run.parent)
    with pytest.raises(KeyboardInterrupt):
        cli.main([command, given, "--out", f"{tmp_path}/new/../sub/deeper/{name}"])
    assert [path.name for path in tmp_path.iterdir()] == ["runs"]


def test_an_out_through_a_link_and_up_is_where_the_shell_puts_it(tmp_path):
    """`..` after a link leads up from where the link leads, as the file system takes it:
    taken out from the path's text, `lnk/../t.md` was written beside the link."""
    run = _write_run(tmp_path / "runs", "push", "sac", 0, [0.0, 0.5])
    (tmp_path / "deep" / "inner").mkdir(parents=True)
    (tmp_path / "lnk").symlink_to(tmp_path / "deep" / "inner")
    assert cli.main(["report", str(run.parent), "--out", f"{tmp_path}/lnk/../t.md"]) == 0
    assert (tmp_path / "deep" / "t.md").is_file() and not (tmp_path / "t.md").exists()


def test_a_seed_that_stopped_early_holds_its_level(tmp_path):
    stopped = read_run(_write_run(tmp_path, "push", "tqc", 0, [1.0] * 5, (True, 50.0)))
    going = read_run(_write_run(tmp_path, "push", "tqc", 1, [0.0] * 5 + [1.0] * 5))
    # Without holding, the seeds share no step after 8000 and the median never reaches 0.9.
    # Held at 1.0, the median of (1.0, seed 1) reaches 0.9 once seed 1's mean is 0.8.
    assert steps_to([stopped, going], 0.9) == 16000


def test_a_cell_with_a_seed_too_short_to_smooth_says_so_not_never(tmp_path):
    """A run stopped early at 100 % after three evaluations has no smoothed
    curve: the table cannot read its steps to 80 %, and says so rather than "–" (never),
    for the wall clock too; a cell of full seeds beside it reads as ever."""
    _write_run(tmp_path, "push", "tqc", 0, [0.0, 1.0, 1.0], (True, 30.0))
    _write_run(tmp_path, "slide", "sac", 0, [0.0] * 4 + [1.0] * 6, (False, 3600.0))
    runs = [read_run(root) for root in sorted(tmp_path.iterdir())]
    lines = markdown_table(runs, wall_clock=True).splitlines()
    too_few = f"n/a (a seed has < {SMOOTHING} evaluations)"
    assert lines[2] == (f"| push | TQC | 0 | 4,000 | 1 of 1 | {too_few} | {too_few} | "
                        f"{too_few} | {too_few} | 0.0 | 0.0 |")
    assert lines[3].startswith("| slide | SAC | 0 | 18,000 | 0 of 1 | 14,000 | 16,000 | ")


def test_a_seed_stopped_by_a_shorter_rule_holds_the_evaluations_that_met_it(tmp_path):
    """With `--stop-after 3` a run can stop after fewer evaluations than the smoothing's 5
    (the figure failed with a KeyError), and holds the mean of the 3 that met the rule, not
    of 5 that reach back past them."""
    import dataclasses

    from franka_composer.training.curves import seed_curves
    from franka_composer.training.learning_report import held

    root = _write_run(tmp_path, "push", "tqc", 0, [0.0, 1.0, 1.0, 1.0], (True, 50.0))
    config = RunDir(root).read_config()
    RunDir(root).write_config(dataclasses.replace(config, hyperparameters=(
        config.hyperparameters.replace(stop_after_evaluations=3))))
    stopped = read_run(root)
    assert held(stopped, stopped.curve, [8000, 10000]) == {
        0: 0.0, 2000: 1.0, 4000: 1.0, 6000: 1.0, 8000: 1.0, 10000: 1.0}
    # Table I's rule (5): its 5 evaluations at 95 % or more, as the smoothing reads them.
    longer = read_run(_write_run(tmp_path, "push", "tqc", 1, [0.0, 0.0, 0.96, 0.98, 1.0, 1.0,
                                                              0.99], (True, 50.0)))
    assert held(longer, longer.curve, [14000]) == {**longer.curve, 14000: pytest.approx(0.986)}
    going = _write_run(tmp_path, "push", "tqc", 2, [0.0] * 6)
    curves = seed_curves([root, going])[("push", "tqc", "")]
    assert curves[0][10000] == 1.0


def test_the_figure_holds_a_seed_that_stopped_early_as_the_steps_to_thresholds_do(tmp_path):
    """Without holding, the cell's median line ended at the first seed's stop (8,000 steps
    of the 18,000 the other seed reached)."""
    from franka_composer.training.curves import seed_curves, summarise

    stopped = _write_run(tmp_path, "push", "tqc", 0, [0.6, 1.0, 0.8, 1.0, 1.0, 1.0],
                         (True, 50.0))
    going = _write_run(tmp_path, "push", "tqc", 1, [0.0] * 5 + [0.4] * 5)
    curves = seed_curves([stopped, going])
    level = (0.8 + 1.0 + 1.0 + 1.0 + 1.0) / 5  # The stopped seed's last 5 evaluations.
    assert curves[("push", "tqc", "")][0] == {
        **{2000 * i: rate for i, rate in enumerate([0.6, 1.0, 0.8, 1.0, 1.0, 1.0])},
        **{step: pytest.approx(level) for step in range(12000, 20000, 2000)}}
    steps, median, _ = summarise(curves[("push", "tqc", "")])
    assert steps.tolist() == list(range(0, 20000, 2000))
    assert median[-1] == pytest.approx((level + 0.4) / 2)
    # A seed still running is not held: the line ends at the steps both reached.
    curves = seed_curves([_write_run(tmp_path, "push", "sac", 0, [1.0] * 6), going])
    assert summarise(curves[("push", "sac", "")])[0].tolist() == list(range(0, 12000, 2000))


def test_a_panel_titles_the_setup_its_lines_share_and_each_legend_keeps_its_own():
    from franka_composer.training.curves import split_setups

    slide = ["net_arch 256,256,256, batch_size 512, bf16", "net_arch 256,256,256, batch_size 512"]
    assert split_setups(slide) == ("net_arch 256,256,256, batch_size 512", {
        slide[0]: "bf16", slide[1]: ""})
    assert split_setups(["", "bf16", "sbx"]) == ("", {"": "", "bf16": "bf16", "sbx": "sbx"})
    assert split_setups(["osc control"]) == ("osc control", {"osc control": ""})
    assert split_setups([]) == ("", {})


def test_the_table_has_a_row_per_cell_in_the_papers_order_and_the_total(tmp_path, capsys):
    _write_run(tmp_path, "slide", "sac", 0, [0.0] * 4 + [1.0] * 6, (False, 3600.0))
    _write_run(tmp_path, "push", "tqc", 1, [1.0] * 5, (True, 1800.0))
    _write_run(tmp_path, "push", "tqc", 0, [0.0] * 6)  # Still running.
    runs = [read_run(root) for root in sorted(tmp_path.iterdir())]
    table = markdown_table(runs)
    assert table.splitlines() == [
        "| task | algorithm | seeds | steps reached | stopped early | steps to 80 % | "
        "steps to 90 % | wall h | CPU h |",
        "|---|---|---|---|---|---|---|---|---|",
        "| push | TQC | 0, 1 | 10,000 (unfinished), 8,000 | 1 of 2 | – | – | 0.0 | "
        "≥ 0.5 (1 unknown) |",
        "| slide | SAC | 0 | 18,000 | 0 of 1 | 14,000 | 16,000 | 0.0 | 1.0 |",
        "",
        "All 3 runs (2 finished): 0.1 wall-clock hours of runs (one CPU each), ≥ 1.5 (1 "
        "unknown) CPU hours; 36,000 environment steps."]
    out = tmp_path / "report.md"
    assert cli.main(["report", str(tmp_path), "--out", str(out)]) == 0
    assert capsys.readouterr().out == out.read_text() == table


def test_an_unfinished_runs_cpu_hours_are_counted_to_its_checkpoint(tmp_path):
    """They read "unknown" though its checkpoint records them: every row of a campaign
    under way did."""
    _write_run(tmp_path, "push", "tqc", 1, [1.0] * 5, (True, 1800.0))
    running = pathlib.Path(_write_run(tmp_path, "push", "tqc", 0, [0.0] * 6))
    saved = running / "checkpoint-8000-0"
    saved.mkdir()
    (saved / "state.json").write_text(json.dumps({"steps": 8000, "wall_time_s": 40.0,
                                                  "cpu_time_s": 720.0}))
    (running / "checkpoint").symlink_to(saved.name)
    runs = [read_run(root) for root in sorted(tmp_path.iterdir())]
    assert [run.cpu_s for run in runs] == [720.0, 1800.0]
    table = markdown_table(runs).splitlines()
    assert table[2].endswith(" | 0.0 | ≥ 0.7 |")  # To the checkpoint: a lower bound.
    assert "≥ 0.7 CPU hours" in table[-1]


def test_the_papers_steps_to_each_threshold_stand_beside_ours(tmp_path, capsys):
    runs = tmp_path / "runs"
    _write_run(runs, "push", "tqc", 0, [0.0] * 4 + [1.0] * 6, (False, 3600.0))
    _write_run(runs, "reach", "sac", 0, [1.0] * 5, (True, 60.0))
    paper = tmp_path / "curves.csv"
    # The paper's push TQC, smoothed: 0.84 at 8000 and 10000, so 80 % at 8000, never 90 %.
    paper.write_text("task,algo,steps,success\n" + "".join(
        f"push,tqc,{2000 * i},{rate}\n" for i, rate in enumerate([0.6, 0.8, 1.0, 0.8, 1.0, 0.6])))
    assert read_paper_curves(paper) == {
        ("push", "tqc"): {0: 0.6, 2000: 0.8, 4000: 1.0, 6000: 0.8, 8000: 1.0, 10000: 0.6}}
    assert cli.main(["report", str(runs), "--paper-curves", str(paper)]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0] == ("| task | algorithm | seeds | steps reached | stopped early | "
                       "steps to 80 % | steps to 90 % | paper: steps to 80 % | "
                       "paper: steps to 90 % | wall h | CPU h |")
    assert rows[2] == ("| push | TQC | 0 | 18,000 | 0 of 1 | 14,000 | 16,000 | 8,000 | – | 0.0 "
                       "| 1.0 |")
    # No curve of the paper's for the cell: blank, not "never".
    assert rows[3] == "| reach | SAC | 0 | 8,000 | 1 of 1 | 8,000 | 8,000 |  |  | 0.0 | 0.0 |"
    with pytest.raises(ValueError, match="--paper-curves: .*nowhere.csv is not a file"):
        cli.main(["report", str(runs), "--paper-curves", str(tmp_path / "nowhere.csv")])
    # Written over, the curves were the table, and the next report could not read them.
    before = paper.read_bytes()
    with pytest.raises(ValueError, match="--out .*curves.csv is the --paper-curves file"
                                         ": the table would replace the "
                                         "curves it read; give another file"):
        cli.main(["report", str(runs), "--paper-curves", str(paper), "--out",
                  str(tmp_path / "." / "curves.csv")])
    assert paper.read_bytes() == before
    other = tmp_path / "other.csv"
    other.write_text("task,algorithm,steps,rate\npush,tqc,0,0.5\n")
    with pytest.raises(ValueError, match="other.csv is not a CSV of curves: it has no algo, "
                                         r"success column\(s\) \(it needs task, algo, steps, "
                                         r"success\)"):
        read_paper_curves(other)
    other.write_text("task,algo,steps,success\npush,tqc,0,0.5\npush,tqc,2k,0.6\n")
    with pytest.raises(ValueError, match="other.csv, line 3: steps must be a whole number and "
                                         "success a number, got '2k', '0.6'"):
        read_paper_curves(other)
    # Rows the paper's curves never hold: each was read as a curve, its columns left blank
    # or its steps to each threshold wrong (a percentage is always over 90 %).
    for row, problem in (("push,tqc,2000,50", r"success must be a fraction, within \[0, 1\] "
                                              r"\(to 0.01, read off a figure\), got 50"),
                         ("reech,tqc,2000,0.5", "unknown task 'reech'"),
                         ("push,sacc,2000,0.5", "unknown algorithm 'sacc'"),
                         ("push,tqc,-2000,0.5", "steps must be >= 0, got -2000")):
        other.write_text(f"task,algo,steps,success\npush,tqc,0,0.5\n{row}\n")
        with pytest.raises(ValueError, match=f"other.csv, line 3: {problem}$"):
            read_paper_curves(other)
    other.write_bytes("\ufefftask,algo,steps,success\npush,tqc,0,0.5\n".encode())  # A BOM.
    assert read_paper_curves(other) == {("push", "tqc"): {0: 0.5}}
    other.write_bytes(b"\x00\xff\xfe")
    with pytest.raises(ValueError, match="other.csv is not a CSV of curves: it is not UTF-8 "
                                         "text"):
        cli.main(["report", str(runs), "--paper-curves", str(other)])
    # The committed curves, read off the paper's figures, top out just above 1.
    assert max(max(curve.values()) for curve in read_paper_curves(
        pathlib.Path(__file__).parents[1] / "results" / "paper-curves" / "curves.csv").values()) \
        == 1.002


def test_the_thresholds_are_chosen_in_percent(tmp_path, capsys):
    """A cell that stays below 80 % is read at 50 %: smoothed, this seed reaches 0.6 at
    16,000 steps and 0.76 at 20,000; the paper's curve 0.84 from 8,000."""
    runs = tmp_path / "runs"
    _write_run(runs, "push", "tqc", 0, [0.0] * 4 + [0.6] * 5 + [1.0] * 2, (False, 3600.0))
    paper = tmp_path / "curves.csv"
    paper.write_text("task,algo,steps,success\n" + "".join(
        f"push,tqc,{2000 * i},{rate}\n" for i, rate in enumerate([0.6, 0.8, 1.0, 0.8, 1.0, 0.6])))
    assert cli.main(["report", str(runs), "--paper-curves", str(paper), "--wall-clock",
                     "--thresholds", "90", "50", "80", "50"]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert rows[0] == ("| task | algorithm | seeds | steps reached | stopped early | "
                       "steps to 50 % | steps to 80 % | steps to 90 % | minutes to 50 % | "
                       "minutes to 80 % | minutes to 90 % | paper: steps to 50 % | "
                       "paper: steps to 80 % | paper: steps to 90 % | wall h | CPU h |")
    assert rows[1] == "|---|---|---|---|---|" + "---|" * 9 + "---|---|"
    assert rows[2] == ("| push | TQC | 0 | 20,000 | 0 of 1 | 16,000 | – | – | 1.3 | – | – | "
                       "8,000 | 8,000 | – | 0.0 | 1.0 |")
    assert cli.main(["report", str(runs), "--thresholds", "57.5"]) == 0
    assert "| steps to 57.5 % | wall h |" in capsys.readouterr().out


@pytest.mark.parametrize("given", ["0", "-50", "100.5", "0.8x", "nan", "0.8", "1"])
def test_a_threshold_outside_1_to_100_percent_is_refused(tmp_path, capsys, given):
    """Fractions ("0.8", "1", as train's --stop-at-success takes them) included: read as
    percent they asked for steps to 0.8 % and printed them."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["report", str(tmp_path), "--thresholds", "80", given])
    assert exit_info.value.code == 2
    assert (f"argument --thresholds: must be a success rate in percent, 1 < x <= 100 "
            f"(80 for 80 %), got {given!r}") in capsys.readouterr().err


def test_a_report_written_to_a_new_folder_makes_it(tmp_path, capsys):
    runs = tmp_path / "runs"
    _write_run(runs, "push", "tqc", 0, [0.0] * 4 + [1.0] * 6, (False, 3600.0))
    out = tmp_path / "new" / "folder" / "report.md"
    assert cli.main(["report", str(runs), "--out", str(out)]) == 0
    assert out.read_text() == capsys.readouterr().out


def test_a_damaged_run_file_is_named_with_what_is_wrong(tmp_path, capsys):
    root = _write_run(tmp_path, "push", "sac", 0, [0.0, 0.5])
    run = RunDir(root)
    for text, message in (
            ("step,success\n0,1\n", r"eval.csv is not an eval.csv: its columns are step, "
                                     "success, not steps, wall_time_s, success_rate, "
                                     "mean_reward"),
            ("steps,wall_time_s,success_rate,mean_reward\n0,1,0.5,-3\n2000,x,0.5\n",
             r"eval.csv, line 3: expected numbers for steps, wall_time_s, success_rate, "
             "mean_reward, got")):
        run.eval_csv.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_run(root)
    recorded = json.loads(run.config_path.read_text())
    for text, message in (("{bad json", "config.json is not a run's config: Expecting "
                                        "property name"),
                          ('{"task": "push"}', "config.json is not a run's config: it has no "
                                               "'algo'"),
                          (None, "config.json is not a run's config: it has no "
                                 "'hyperparameters.total_steps'")):
        if text is None:  # Read as the default's 500,000 steps, a 2,000-step run unfinished.
            del recorded["hyperparameters"]["total_steps"]
            text = json.dumps(recorded)
        run.config_path.write_text(text)
        with pytest.raises(ValueError, match=message):
            run.read_config()
        assert cli.console(["report", str(root)]) == 2
        assert message.split(":")[0] in capsys.readouterr().err


def test_a_run_without_evaluations_is_refused_by_name(tmp_path):
    root = _write_run(tmp_path, "push", "sac", 0, [])
    with pytest.raises(ValueError, match="push-sac-seed0 has no evaluations yet"):
        read_run(root)


@pytest.mark.parametrize("command", ["report", "plot"])
def test_a_sweep_under_way_is_read_without_its_runs_not_evaluated_yet(tmp_path, capsys,
                                                                       command):
    """A cell not begun (config.json only) or begun and not evaluated (an empty eval.csv)
    is named on stderr and left out; both refused the whole sweep. Runs none of which has
    evaluated are still refused, each named."""
    runs = tmp_path / "sweep"
    _write_run(runs, "push", "sac", 0, [0.0] * 4 + [1.0] * 6)
    _write_run(runs, "push", "sac", 1, [])
    RunDir(runs / "push-sac-seed2").write_config(
        RunConfig("push", "sac", 2, hyperparameters("push", "sac")))
    out = ["--out", str(tmp_path / "curves.png")] if command == "plot" else []
    assert cli.console([command, str(runs), *out]) == 0
    printed = capsys.readouterr()
    assert printed.err.splitlines() == [
        f"left out: {runs / f'push-sac-seed{seed}'} has no evaluations yet" for seed in (1, 2)]
    if command == "report":
        assert printed.out.splitlines()[2].startswith(
            "| push | SAC | 0 | 18,000 (unfinished) | 0 of 1 | 14,000 | 16,000 |")
    else:
        assert printed.out == f"1 curve -> {tmp_path / 'curves.png'}\n"
    assert cli.console([command, str(runs / "push-sac-seed1"), str(runs / "push-sac-seed2"),
                        *out]) == 2
    assert (f"no evaluations yet in {runs / 'push-sac-seed1'}, {runs / 'push-sac-seed2'}"
            in capsys.readouterr().err)
    # Ended, with its evaluations lost: refused, not left out as one not begun.
    RunDir(runs / "push-sac-seed1").write_outcome(18000, False, 180.0, 3600.0)
    assert cli.console([command, str(runs), *out]) == 2
    assert (f"{runs / 'push-sac-seed1'} has ended and has no evaluations (its eval.csv lost "
            "or emptied?)" in capsys.readouterr().err)


def test_a_variant_names_what_differs_from_the_papers_setup():
    table_i = hyperparameters("slide", "tqc")
    assert RunConfig("slide", "tqc", 0, table_i.replace(
        total_steps=10, eval_every=10, eval_episodes=1, stop_success_rate=0.95)).variant == ""
    campaign_slide = table_i.replace(net_arch=[256, 256, 256], batch_size=512,
                                     update_schedule="episode")
    config = RunConfig("slide", "tqc", 0, campaign_slide, control="osc", precision="bf16",
                       randomization="default", demos="/data/slide-expert-100.npz",
                       demo_episodes=50, terminate_on_success=False, control_timestep=0.5)
    assert config.setup == (
        "net_arch 256,256,256, batch_size 512, update_schedule episode, osc control, "
        "0.5 s per step, randomization default, demos slide-expert-100.npz[:50], "
        "no termination on success")
    assert config.computation == "bf16"
    assert config.variant == config.setup + ", bf16"
    sbx = RunConfig("push", "sac", 0, hyperparameters("push", "sac"), backend="sbx")
    assert (sbx.setup, sbx.computation, sbx.variant) == ("", "sbx", "sbx")


def test_runs_of_different_variants_are_not_seeds_of_one_cell(tmp_path):
    _write_run(tmp_path, "push", "sac", 0, [0.5] * 5)
    _write_run(tmp_path, "push", "sac", 1, [0.5] * 5)
    _write_run(tmp_path, "push", "sac", 0, [1.0] * 5, name="-bf16", precision="bf16")
    rows = markdown_table([read_run(root) for root in sorted(tmp_path.iterdir())]).splitlines()
    assert [row.split(" | ")[:3] for row in rows[2:4]] == [
        ["| push", "SAC", "0, 1"], ["| push (bf16)", "SAC", "0"]]
    results = [report.RunResult("a", "push", "sac", 0, 10, 0.5),
               report.RunResult("b", "push", "sac", 1, 10, 1.0),
               report.RunResult("c", "push", "sac", 0, 10, 0.0, computation="bf16"),
               report.RunResult("d", "push", "tqc", 0, 10, 0.2, computation="sbx"),
               report.RunResult("e", "push", "sac", 0, 10, 0.4, "osc control", "bf16"),
               report.RunResult("f", "slide", "tqc", 0, 10, 1.0)]
    # A row per task and setup; runs computed otherwise share its cells, not averaged. The
    # paper's row under each Table II task's; none for a task not in the paper's table.
    assert report.markdown_table(results + [report.RunResult("g", "reach", "sac", 0, 10, 1.0)]
                                 ).splitlines()[2:] == [
        "| Push | – | 75.0 ± 25.0; 0.0 ± 0.0 (bf16) | 20.0 ± 0.0 (sbx) |",
        "| Push (osc control) | – | 40.0 ± 0.0 (bf16) | – |",
        "| Push: the paper's | 11.7 ± 0.3 | 100.0 ± 0.0 | 100.0 ± 0.0 |",
        "| Slide | – | – | 100.0 ± 0.0 |",
        "| Slide: the paper's | 71.7 ± 0.5 | 85.0 ± 0.4 | 85.1 ± 0.4 |",
        "| Reach | – | 100.0 ± 0.0 | – |"]
    assert report.seeds_note(results).splitlines() == [
        "- push / sac: seeds 0, 1; trained steps 10, 10; success 50.0, 100.0 %",
        "- push (bf16) / sac: seeds 0; trained steps 10; success 0.0 %",
        "- push (osc control, bf16) / sac: seeds 0; trained steps 10; success 40.0 %",
        "- push (sbx) / tqc: seeds 0; trained steps 10; success 20.0 %",
        "- slide / tqc: seeds 0; trained steps 10; success 100.0 %"]


def test_minutes_to_read_a_seed_stopped_by_a_shorter_rule_as_steps_to_do(tmp_path):
    """With `--stop-after 2` a stopped seed holds the mean of the 2 evaluations that met the
    rule (1.0), above its last smoothed value (0.44): steps to 80 % counted it reached, at
    its stop, and minutes to 80 % counted it never ("–" beside a step)."""
    import dataclasses

    roots = []
    for seed in (0, 1):
        root = _write_run(tmp_path, "reach", "sac", seed, [0.0, 0.0, 0.0, 0.0, 0.2, 1.0, 1.0],
                          (True, 50.0), seconds=30)
        config = RunDir(root).read_config()
        RunDir(root).write_config(dataclasses.replace(config, hyperparameters=(
            config.hyperparameters.replace(stop_after_evaluations=2))))
        roots.append(root)
    roots.append(_write_run(tmp_path, "reach", "sac", 2, [0.0, 0.0, 0.0, 0.0, 0.2, 0.6, 0.8,
                                                          0.8, 0.8, 0.8], seconds=30))
    runs = [read_run(root) for root in roots]
    assert max(smoothed(runs[0].curve).values()) == pytest.approx(0.44)
    assert steps_to(runs, 0.8) == 14000  # Two of three seeds held at 1.0 there.
    assert minutes_to(runs, 0.8) == pytest.approx(3.0)  # Theirs at their stop: 6 x 30 s.
    assert minutes_to(runs, 0.3) == pytest.approx(3.0)  # Their own smoothed curves: 0.44.
