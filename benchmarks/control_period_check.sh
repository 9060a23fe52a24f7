#!/usr/bin/env bash
# Is pick-and-place below the paper's because the paper's code steps 0.5 s per action (10 x
# 25 substeps: the arm and fingers at rest before each observation) where the tasks step
# 0.05 s? pick_and_place TQC (sbx), the Table II cells' settings (Table I, the
# campaign's stopping rule, 4e5 steps) with `--control-timestep 0.5`, seeds 0, 1, 2 beside
# the campaign's cells, at low priority, runs outside the work tree (RESULTS.md).
#
#   benchmarks/control_period_check.sh run      train (or resume) the seeds, WORKERS at a
#                                               time (default 1); FROZEN=COMMIT runs that
#                                               commit's code (a worktree beside $RUNS)
#   benchmarks/control_period_check.sh stop     checkpoint the running cells and stop
#   benchmarks/control_period_check.sh status   the table of cells
#   benchmarks/control_period_check.sh sync     what the cells kept, into results/control-period/
#
# SEEDS (default "0 1 2") picks the seeds; RUNS (default ~/franka_runs/control-period).
set -uo pipefail
cd "$(dirname "$0")/.."
source benchmarks/background_sweep.sh
sweep_settings "$HOME/franka_runs/control-period"
read -ra seeds <<< "${SEEDS:-0 1 2}"
sweep=(sweep --out "$RUNS" --tasks pick_and_place --algos tqc --seeds "${seeds[@]}"
       --steps 400000)

case "${1:-}" in
  run)
    if [ -n "${FROZEN:-}" ]; then use_frozen_tree "$FROZEN" "$RUNS" || exit 1; fi
    lower_session_priority
    nice -n 10 "$BIN/franka-composer" "${sweep[@]}" --num-cpus "$WORKERS" --refresh 600 -- \
      --backend sbx --control-timestep 0.5 --stop-at-success 0.95 --stop-after 5 \
      --checkpoint-every 10000 --threads 1 --device cpu
    ;;
  stop)
    stop_sweep "franka-composer sweep --out $RUNS " "$RUNS" || exit 1
    "$BIN/franka-composer" "${sweep[@]}" --status
    ;;
  status) "$BIN/franka-composer" "${sweep[@]}" --status ;;
  sync) "$BIN/franka-composer" "${sweep[@]}" --sync results/control-period ;;
  *) sed -n '2,15p' "$0"; exit 2 ;;
esac
