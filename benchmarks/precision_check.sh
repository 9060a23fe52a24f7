#!/usr/bin/env bash
# Does bf16 learn what fp32 learns (issue 15)? SAC + HER on push, Table I settings (an
# update every step), 3 seeds in each precision, 40k steps: two sweeps side by side, one
# core each, at low priority, runs outside the work tree (resumable: run it again).
#
#   benchmarks/precision_check.sh run      train (or resume) both sweeps
#   benchmarks/precision_check.sh table    success at 10k/20k/30k/40k, mean ± std per precision
#       (MARKS="50000 60000 ..." other steps; WINDOW="60000 100000" adds each run's mean
#       success over its evaluations in that range, mean ± std over the seeds)
#   benchmarks/precision_check.sh sync     copy config.json/eval.csv into KEPT (default
#                                          results/precision)/<precision>/<cell>/
#
# STEPS (default 40000), PRECISIONS (default "fp32 bf16") and TRAIN_ARGS (more `train`
# options) make other arms: the SAC fp32 arm past 1e5 beside the campaign's bf16 push-sac
# cells is STEPS=250000 PRECISIONS=fp32 TRAIN_ARGS="--stop-at-success 0.95 --stop-after 5"
# RUNS=~/franka_runs/sac-check KEPT=results/sac-check (RESULTS.md).
set -uo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-$HOME/franka_runs/precision-check}
BIN=${BIN:-.venv/bin}
export OMP_NUM_THREADS=1 MENAGERIE_ROOT=${MENAGERIE_ROOT:-$(cd .. && pwd)/shared/menagerie}
STEPS=${STEPS:-40000}
KEPT=${KEPT:-results/precision}
read -ra PRECISIONS <<< "${PRECISIONS:-fp32 bf16}"
read -ra TRAIN_ARGS <<< "${TRAIN_ARGS:-}"

case "${1:-}" in
  run)
    for precision in "${PRECISIONS[@]}"; do
      nice -n 10 "$BIN/franka-composer" sweep --out "$RUNS/$precision" --tasks push \
        --algos sac --seeds 0 1 2 --steps "$STEPS" --num-cpus 1 --refresh 600 -- \
        --precision "$precision" --checkpoint-every 10000 --threads 1 --device cpu \
        ${TRAIN_ARGS[@]+"${TRAIN_ARGS[@]}"} >"$RUNS-$precision.log" 2>&1 &
    done
    wait
    ;;
  table)
    arms=(); for precision in "${PRECISIONS[@]}"; do arms+=(--arm "$precision" "$RUNS/$precision/*"); done
    "$BIN/python" benchmarks/compare_arms.py "${arms[@]}" --marks ${MARKS:-10000 20000 30000 40000} \
      ${WINDOW:+--window $WINDOW}
    ;;
  sync)
    for dir in "$RUNS"/*/*/; do
      cell=$(basename "$(dirname "$dir")")/$(basename "$dir")
      mkdir -p "$KEPT/$cell"
      for file in config.json eval.csv outcome.json; do
        if [ -f "$dir/$file" ]; then cp "$dir/$file" "$KEPT/$cell/"; fi
      done
    done
    ;;
  *) sed -n '2,16p' "$0"; exit 2 ;;
esac
