#!/usr/bin/env bash
# Whether this tree trains as older ones do (the trees a campaign's cells ran on:
# docs/experiments/table2-campaign.md),
# at any settings: the same `train` run with this tree and with each older tree on
# PYTHONPATH; their eval.csv (less wall times) and the actor in policy.pt must be identical.
#
#   OLD="TREE ..." experiments/trees_check.sh [train options]      (TREE: a git worktree;
#                   default options: push, SAC in bf16, Table I, 1500 steps, evaluated every 500)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
source benchmarks/tools.sh
use_tools
: "${OLD:?OLD=\"TREE ...\", the older trees (git worktrees)}"
args=("$@")
[ ${#args[@]} -gt 0 ] || args=(--task push --algo sac --seed 7 --precision bf16
  --total-steps 1500 --eval-every 500 --eval-episodes 5)
args+=(--threads 1 --device cpu --no-progress)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

train() {  # TREE NAME: trains with TREE's franka_composer into $work/NAME.
  # From a directory without a franka_composer: `python -m` puts the working directory on
  # sys.path before PYTHONPATH.
  (cd "$work" && export PYTHONPATH=$1 &&
   "$BIN/python" -c '
import sys, franka_composer
if not franka_composer.__file__.startswith(sys.argv[1] + "/"):
    sys.exit(f"{sys.argv[1]}: franka_composer came from {franka_composer.__file__}")' "$1" &&
   "$BIN/python" -m franka_composer train "${args[@]}" --out "$2" > "$2.log" 2>&1)
  cut -d, -f1,3,4 "$work/$2/eval.csv" > "$work/$2.csv"
}

train "$PWD" this
echo "this tree: $(($(wc -l < "$work/this.csv") - 1)) evaluations, to $(tail -1 "$work/this.csv" | cut -d, -f1) steps"
status=0
for tree in $OLD; do
  tree=$(cd "$tree" && pwd)
  train "$tree" old
  evaluations=identical actor=
  cmp -s "$work/this.csv" "$work/old.csv" || { evaluations=differs; status=1; }
  if [ -f "$work/old/policy.pt" ]; then
    actor=$("$BIN/python" experiments/same_actor.py "$work/this/policy.pt" "$work/old/policy.pt") || status=1
  else
    actor="no policy.pt (that tree did not write one for this run)"
  fi
  echo "$tree: eval.csv $evaluations, $actor"
  rm -rf "$work/old" "$work/old.csv" "$work/old.log"
done
exit $status
