#!/usr/bin/env bash
# The paper's Table II on this suite (issue 15): `franka-composer sweep --grid table2`, whose
# cells, budgets and early-stopping rule are in franka_composer/training/sweep.py (GRIDS),
# run here in the background at low priority, checkpoints outside the work tree.
#
#   benchmarks/table2.sh run      train the cells, WORKERS at a time (default 1), each
#                                 resumed from its checkpoint if it has one, skipped if done
#                                 (in $RUNS, or kept as finished by sync: a machine handed
#                                 back bare does not train them again);
#                                 CELLS='push-sac-* ...' runs only the cells it names;
#                                 FROZEN=COMMIT runs that commit's code (a worktree beside
#                                 $RUNS, the sweep's working directory and PYTHONPATH, with
#                                 this checkout's venv), so the work tree can change while
#                                 the cells train
#   benchmarks/table2.sh stop     stop a `run` in the background as Ctrl-C does: each running
#                                 cell checkpoints, then exits (waits for them, up to 5 min)
#   benchmarks/table2.sh status   the table of cells: steps, steps/s, latest success
#   benchmarks/table2.sh sync     copy each cell's config.json, eval.csv (up to its
#                                 checkpoint) and, once it has finished at the grid's
#                                 budget, outcome.json and policy.pt into $KEPT/<cell>/,
#                                 from which `franka-composer evaluate $KEPT` and
#                                 `franka-composer demo --policy $KEPT/<cell>` run
#   benchmarks/table2.sh report   from what sync committed, once every cell has finished:
#                                 Table II (`evaluate --episodes 20`, table2.md; and over
#                                 200 other episodes, table2-200-episodes.md), Fig. 4
#                                 (`plot`, curves.png) and the steps to 80/90 % beside the
#                                 paper's with the costs (`report`, report.md), written into
#                                 $KEPT; PARTIAL=1 makes them of the finished cells
#                                 (evaluate) and every cell's evaluations so far
#
# Runs live in $RUNS (default ~/franka_runs/table2), so an interrupted cell resumes in a
# later session; what sync keeps, in $KEPT (default results/table2).
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
source benchmarks/background_sweep.sh
sweep_settings "$HOME/franka_runs/table2"
KEPT=${KEPT:-results/table2}
read -ra cells <<< "${CELLS:-}"  # Patterns, not globbed here.

# kept_cells finished|unfinished: the grid's cells whose finished run sync has (not) kept in
# $KEPT, in the grid's order; this checkout's code reads them (before use_frozen_tree).
kept_cells() {
  "$BIN/python" - "$KEPT" "$1" <<'PY'
import pathlib
import sys
from franka_composer.training.sweep import GRIDS, finished_in
cells = GRIDS["table2"]
finished = finished_in(pathlib.Path(sys.argv[1]), cells)
print(" ".join(c.name for c in cells if (c in finished) == (sys.argv[2] == "finished")))
PY
}

case "${1:-}" in
  run)
    if [ ${#cells[@]} -eq 0 ]; then
      unfinished=$(kept_cells unfinished) || exit 1
      [ -n "$unfinished" ] || { echo "every cell has finished ($KEPT)"; exit 0; }
      read -ra cells <<< "$unfinished"
    fi
    if [ -n "${FROZEN:-}" ]; then use_frozen_tree "$FROZEN" "$RUNS" || exit 1; fi
    lower_session_priority
    nice -n 10 "$BIN/franka-composer" sweep --grid table2 --out "$RUNS" --num-cpus "$WORKERS" \
      ${cells[@]+--cells "${cells[@]}"} --refresh 600 -- --checkpoint-every 10000 --threads 1 \
      --device cpu
    ;;
  stop)
    stop_sweep "franka-composer sweep --grid table2 --out $RUNS( |$)" "$RUNS" || exit 1
    "$BIN/franka-composer" sweep --grid table2 --out "$RUNS" --status
    ;;
  status) "$BIN/franka-composer" sweep --grid table2 --out "$RUNS" --status \
      ${cells[@]+--cells "${cells[@]}"} ;;
  sync)
    "$BIN/franka-composer" sweep --grid table2 --out "$RUNS" --sync "$KEPT"
    ;;
  report)
    unfinished=$(kept_cells unfinished) && finished=$(kept_cells finished) || exit 1
    if [ -n "$unfinished" ] && [ "${PARTIAL:-0}" != 1 ]; then
      echo "not finished (PARTIAL=1 reports the rest): ${unfinished// /, }" >&2
      exit 1
    fi
    read -ra finished <<< "$finished"
    finished=("${finished[@]/#/$KEPT/}")
    [ ${#finished[@]} -gt 0 ] || { echo "no cell has finished" >&2; exit 1; }
    report_cells "$KEPT" table2 "80 90" "${finished[@]}"
    ;;
  *) sed -n '2,32p' "$0"; exit 2 ;;
esac
