#!/usr/bin/env bash
# Pick-and-place at the paper's code's timing (`--timing reference`: 0.5 s of physics per
# step, velocities multiplied by 0.05 s) and the paper's budget (5e5 steps): Table II's
# cells' settings (Table I, the campaign's stopping rule) with TQC (sbx fp32), SAC (bf16)
# or DDPG (SB3 fp32), seeds 0, 1, 2, at low priority, runs outside the work tree.
#
#   benchmarks/reference_timing.sh run      train (or resume) the cells, WORKERS at a time
#                                           (default 1); FROZEN=COMMIT runs that commit's
#                                           code (a worktree beside $RUNS)
#   benchmarks/reference_timing.sh stop     checkpoint the running cells and stop
#   benchmarks/reference_timing.sh status   the table of cells
#   benchmarks/reference_timing.sh sync     what the cells kept, into results/reference-timing/
#
# ALGO (default tqc) and SEEDS (default "0 1 2") pick the cells; RUNS (default
# ~/franka_runs/reference-timing).
set -uo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in run|stop|status|sync) ;; *) sed -n '2,16p' "$0"; exit 2 ;; esac
source benchmarks/background_sweep.sh
sweep_settings "$HOME/franka_runs/reference-timing"
read -ra seeds <<< "${SEEDS:-0 1 2}"
ALGO=${ALGO:-tqc}
# Each algorithm on the computation Table II's cells validated.
case "$ALGO" in
  tqc) computation=(--backend sbx) ;;
  sac) computation=(--precision bf16) ;;
  ddpg) computation=() ;;
  *) echo "ALGO must be tqc, sac or ddpg, not $ALGO" >&2; exit 2 ;;
esac
sweep=(sweep --out "$RUNS" --tasks pick_and_place --algos "$ALGO" --seeds "${seeds[@]}"
       --steps 500000)
train_options=(${computation[@]+"${computation[@]}"} --timing reference
               --stop-at-success 0.95 --stop-after 5 --checkpoint-every 10000 --threads 1
               --device cpu)
background_sweep "$1" results/reference-timing
