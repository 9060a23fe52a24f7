#!/usr/bin/env bash
# Whether a run stopped by SIGTERM and resumed ends as the uninterrupted run does
# (docs/guide/training.md, `train --resume`), at any settings: the same `train` twice, one
# stopped once its evaluation at STOP_AT steps is written, then resumed; their eval.csv
# (less wall times) and the actor in policy.pt must be identical.
#
#   experiments/resume_check.sh [train options]       (default: push, SAC in bf16, Table I,
#                                                     1500 steps, evaluated every 200)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
source benchmarks/tools.sh
use_tools
STOP_AT=${STOP_AT:-800}
args=("$@")
[ ${#args[@]} -gt 0 ] || args=(--task push --algo sac --seed 7 --precision bf16
  --total-steps 1500 --eval-every 200 --eval-episodes 5)
args+=(--threads 1 --device cpu --no-progress --checkpoint-every 1000000)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN/franka-composer" train "${args[@]}" --out "$work/whole" > "$work/whole.log"
"$BIN/franka-composer" train "${args[@]}" --out "$work/stopped" > "$work/stopped.log" &
pid=$!
until grep -q "^$STOP_AT," "$work/stopped/eval.csv" 2>/dev/null; do
  kill -0 $pid 2>/dev/null || { echo "the run ended before $STOP_AT steps" >&2; exit 1; }
  sleep 0.2
done
kill -TERM $pid
wait $pid || true
echo "stopped at: $(cat "$work/stopped/checkpoint/state.json")"
"$BIN/franka-composer" train --resume --out "$work/stopped" > "$work/resumed.log"
cut -d, -f1,3,4 "$work/whole/eval.csv" > "$work/whole.csv"
cut -d, -f1,3,4 "$work/stopped/eval.csv" > "$work/resumed.csv"
echo "evaluations: $(($(wc -l < "$work/whole.csv") - 1)), to $(tail -1 "$work/whole.csv" | cut -d, -f1) steps"
diff "$work/whole.csv" "$work/resumed.csv" && echo "eval.csv: identical"
"$BIN/python" experiments/same_actor.py "$work/whole/policy.pt" "$work/stopped/policy.pt"
