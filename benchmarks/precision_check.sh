#!/usr/bin/env bash
# Does bf16 learn what fp32 learns (issue 15)? SAC + HER on push, Table I settings (an
# update every step), 3 seeds in each precision, 40k steps: two sweeps side by side, one
# core each, at low priority, runs outside the work tree (resumable: run it again).
#
#   benchmarks/precision_check.sh run      train (or resume) both sweeps
#   benchmarks/precision_check.sh table    success at 10k/20k/30k/40k, mean ± std per precision
#       (MARKS="50000 60000 ..." other steps; WINDOW="60000 100000" adds each run's mean
#       success over its evaluations in that range, mean ± std over the seeds)
#   benchmarks/precision_check.sh sync     copy config.json/eval.csv into results/precision/
set -uo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-$HOME/franka_runs/precision-check}
BIN=${BIN:-.venv/bin}
export OMP_NUM_THREADS=1 MENAGERIE_ROOT=${MENAGERIE_ROOT:-$(cd .. && pwd)/shared/menagerie}
PRECISIONS=(fp32 bf16)

case "${1:-}" in
  run)
    for precision in "${PRECISIONS[@]}"; do
      nice -n 10 "$BIN/franka-composer" sweep --out "$RUNS/$precision" --tasks push \
        --algos sac --seeds 0 1 2 --steps 40000 --num-cpus 1 --refresh 600 -- \
        --precision "$precision" --checkpoint-every 10000 --threads 1 --device cpu \
        >"$RUNS-$precision.log" 2>&1 &
    done
    wait
    ;;
  table)
    MARKS=${MARKS:-10000 20000 30000 40000} WINDOW=${WINDOW:-} \
      "$BIN/python" - "$RUNS" "${PRECISIONS[@]}" <<'PY'
import os, pathlib, sys
import numpy as np
from franka_composer.training.runs import read_eval_rows
root, precisions = pathlib.Path(sys.argv[1]), sys.argv[2:]
marks = [int(m) for m in os.environ["MARKS"].split()]
window = [int(m) for m in os.environ["WINDOW"].split()]
def cell(rates):
    return f"{100 * np.mean(rates):.0f} ± {100 * np.std(rates):.0f} % (n={len(rates)})" if rates else "–"
heads = [f"{m // 1000}k" for m in marks] + ([f"mean {window[0] // 1000}k–{window[1] // 1000}k"] if window else [])
print("| precision | " + " | ".join(heads) + " |")
print("|---|" + "---|" * len(heads))
for precision in precisions:
    runs = [read_eval_rows(run) for run in sorted((root / precision).glob("*/eval.csv"))]
    cells = [cell([row["success_rate"] for rows in runs for row in rows if row["steps"] == mark])
             for mark in marks]
    if window:  # A run counts once it has evaluations up to the window's end.
        cells.append(cell([np.mean([row["success_rate"] for row in rows
                                    if window[0] <= row["steps"] <= window[1]])
                           for rows in runs if rows and rows[-1]["steps"] >= window[1]]))
    print(f"| {precision} | " + " | ".join(cells) + " |")
PY
    ;;
  sync)
    for dir in "$RUNS"/*/*/; do
      cell=$(basename "$(dirname "$dir")")/$(basename "$dir")
      mkdir -p "results/precision/$cell"
      for file in config.json eval.csv outcome.json; do
        if [ -f "$dir/$file" ]; then cp "$dir/$file" "results/precision/$cell/"; fi
      done
    done
    ;;
  *) sed -n '2,9p' "$0"; exit 2 ;;
esac
