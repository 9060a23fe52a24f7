#!/usr/bin/env bash
# Whether this tree trains as an older one does (a campaign's frozen tree, RESULTS.md), at any
# settings: the same `train` run with the older tree on PYTHONPATH and with this one; their
# eval.csv (less wall times) and the actor in policy.pt must be identical.
#
#   OLD=~/franka_runs/code-4704db9 benchmarks/trees_check.sh [train options]
#                        (default: push, SAC in bf16, Table I, 1500 steps, evaluated every 500)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-.venv/bin}
: "${OLD:?OLD=path of the older tree (a git worktree)}"
export OMP_NUM_THREADS=1 MENAGERIE_ROOT=${MENAGERIE_ROOT:-$(cd .. && pwd)/shared/menagerie}
args=("$@")
[ ${#args[@]} -gt 0 ] || args=(--task push --algo sac --seed 7 --precision bf16
  --total-steps 1500 --eval-every 500 --eval-episodes 5)
args+=(--threads 1 --device cpu --no-progress)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
PYTHONPATH=$OLD "$BIN/python" -m franka_composer train "${args[@]}" --out "$work/old" > "$work/old.log"
PYTHONPATH=$PWD "$BIN/python" -m franka_composer train "${args[@]}" --out "$work/new" > "$work/new.log"
cut -d, -f1,3,4 "$work/old/eval.csv" > "$work/old.csv"
cut -d, -f1,3,4 "$work/new/eval.csv" > "$work/new.csv"
echo "evaluations: $(($(wc -l < "$work/old.csv") - 1)), to $(tail -1 "$work/old.csv" | cut -d, -f1) steps"
diff "$work/old.csv" "$work/new.csv" && echo "eval.csv: identical"
"$BIN/python" benchmarks/same_actor.py "$work/old/policy.pt" "$work/new/policy.pt"
