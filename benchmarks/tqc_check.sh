#!/usr/bin/env bash
# Does TQC learn the same on sbx (1.5x SB3-bf16's steps/s here) as on SB3 in bf16 (issue 15),
# and SB3 in bf16 as SB3 in fp32 (the paper's)? TQC + HER on push, Table I settings, the
# campaign's stopping rule, seeds 0, 1, 2 to 1e5 steps in each arm, at low priority, runs
# outside the work tree (each resumes: run it again). The sb3 arm (bf16) was the campaign's
# push-tqc cells brought forward, moved to tqc-check/ when the check sent TQC to sbx: the
# campaign's push-tqc cells went on from copies of the sbx arm's runs (RESULTS.md).
#
#   benchmarks/tqc_check.sh run sbx|sb3|fp32 [SEED ...]   train (or resume) an arm's seeds
#   benchmarks/tqc_check.sh sync     copy each run's config.json, eval.csv (up to 1e5 steps)
#                                    and outcome.json (at 1e5) into results/tqc-check/<arm>/
#   benchmarks/tqc_check.sh table    success at 50k-100k and mean over 60k-100k per arm,
#                                    from results/tqc-check/
#   benchmarks/tqc_check.sh final    the final test: EPISODES (default 100) per model, the
#                                    same episodes for all
set -uo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-$HOME/franka_runs}
BIN=${BIN:-.venv/bin}
STEPS=100000
export OMP_NUM_THREADS=1 MENAGERIE_ROOT=${MENAGERIE_ROOT:-$(cd .. && pwd)/shared/menagerie}

ARMS=(sb3 sbx fp32)
run_dir() { echo "$RUNS/tqc-check/push-tqc-seed$2-$1"; }  # run_dir ARM SEED

case "${1:-}" in
  run)
    arm=${2:?sbx, sb3 or fp32}; shift 2
    case "$arm" in sbx) setup=(--backend sbx) ;; sb3) setup=(--precision bf16) ;; fp32) setup=() ;;
      *) echo "tqc_check.sh run: arm must be sbx, sb3 or fp32, not '$arm'" >&2; exit 2 ;; esac
    seeds=("$@"); [ ${#seeds[@]} -gt 0 ] || seeds=(0 1 2)
    for seed in "${seeds[@]}"; do
      out=$(run_dir "$arm" "$seed")
      if [ -f "$out/checkpoint/state.json" ]; then
        args=(--resume)
      else
        rm -rf "$out"
        args=(--task push --algo tqc --seed "$seed" ${setup[@]+"${setup[@]}"} --stop-at-success 0.95
              --stop-after 5)
      fi
      nice -n 10 "$BIN/franka-composer" train --out "$out" --total-steps "$STEPS" --no-progress \
        "${args[@]}" --checkpoint-every 10000 --threads 1 --device cpu || exit 1
    done
    ;;
  sync)
    for arm in "${ARMS[@]}"; do
      for seed in 0 1 2; do
        run=$(run_dir "$arm" "$seed"); kept=results/tqc-check/$arm/push-tqc-seed$seed
        [ -f "$run/config.json" ] || continue
        mkdir -p "$kept"
        cp "$run/config.json" "$kept/"
        # The check's first 1e5 steps, and of a run stopped between checkpoints only what a
        # resume keeps.
        "$BIN/python" - "$run" "$kept" "$STEPS" <<'PY'
import pathlib
import shutil
import sys
from franka_composer.training.runs import RunDir, write_eval_rows
run, kept = (RunDir(pathlib.Path(path)) for path in sys.argv[1:3])
steps = int(sys.argv[3])
write_eval_rows(kept.eval_csv, [row for row in run.kept_evaluations() if row["steps"] <= steps])
if run.read_outcome().get("steps", steps + 1) <= steps:
    shutil.copy(run.outcome_path, kept.outcome_path)
PY
      done
    done
    ;;
  table)
    arms=(--arm "sb3 bf16" "results/tqc-check/sb3/*" --arm sbx "results/tqc-check/sbx/*")
    if [ -d results/tqc-check/fp32 ]; then arms+=(--arm "sb3 fp32" "results/tqc-check/fp32/*"); fi
    "$BIN/python" benchmarks/compare_arms.py "${arms[@]}" \
      --marks 50000 60000 70000 80000 90000 100000 --window 60000 100000
    ;;
  final)
    runs=()
    for arm in "${ARMS[@]}"; do
      for seed in 0 1 2; do
        run=$(run_dir "$arm" "$seed")
        if ! grep -q "\"steps\": $STEPS," "$run/outcome.json" 2>/dev/null; then
          echo "tqc_check.sh final: $run has not ended at $STEPS steps" >&2; exit 1
        fi
        runs+=("$run")
      done
    done
    "$BIN/franka-composer" evaluate "${runs[@]}" --episodes "${EPISODES:-100}"
    ;;
  *) sed -n '2,14p' "$0"; exit 2 ;;
esac
