#!/usr/bin/env bash
# The single-seed learning runs of RESULTS.md, one after another, each stopped by SIGTERM at
# its time budget (the run checkpoints first; `franka-composer train --resume --out DIR`
# continues it), then the final test and the curves.
set -uo pipefail
cd "$(dirname "$0")/.."
export OMP_NUM_THREADS=1
BIN=${BIN:-.venv/bin}
run() {  # MINUTES TASK ALGO [EXTRA OPTIONS...]
  local minutes=$1 task=$2 algo=$3; shift 3
  local out=runs/learn/$task-$algo-seed0
  mkdir -p runs/learn
  echo "$(date +%T) start $task $algo $*"
  timeout -s TERM "${minutes}m" "$BIN/franka-composer" train --task "$task" --algo "$algo" \
    --seed 0 --out "$out" --update-schedule episode --checkpoint-every 10000 --threads 1 \
    --no-progress "$@" >"$out.log" 2>&1
  echo "$(date +%T) end $task rc=$? last eval: $(tail -1 "$out/eval.csv")"
}
run 40 push sac
run 20 pick_and_place tqc
run 10 slide sac --net-arch 256,256,256 --batch-size 512
"$BIN/franka-composer" evaluate runs/learn/*-seed0 --episodes 20 --out results/table.md
"$BIN/franka-composer" plot runs/learn/*-seed0 --out results/curves.png
"$BIN/franka-composer" plot runs/learn/push-sac-seed0 --out results/push_curve.png
