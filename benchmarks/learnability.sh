#!/usr/bin/env bash
# Are stack and flip learnable as defined? One TQC+HER run each (sbx, Table I's push
# settings, which those tasks take), 5e5 steps or the campaign's stopping rule, at low
# priority, runs outside the work tree.
#
#   benchmarks/learnability.sh run      train (or resume) the runs, WORKERS at a time
#                                       (default 1); FROZEN=COMMIT runs that commit's code
#   benchmarks/learnability.sh stop     checkpoint the running runs and stop
#   benchmarks/learnability.sh status   the table of runs
#   benchmarks/learnability.sh sync     what they kept, into $KEPT
#
# TASKS (default "stack flip"), SEEDS (default 0); RUNS (default ~/franka_runs/learnability),
# KEPT (default results/learnability).
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
case "${1:-}" in run|stop|status|sync) ;; *) sed -n '2,13p' "$0"; exit 2 ;; esac
source benchmarks/background_sweep.sh
sweep_settings "$HOME/franka_runs/learnability"
read -ra tasks <<< "${TASKS:-stack flip}"
read -ra seeds <<< "${SEEDS:-0}"
sweep=(sweep --out "$RUNS" --tasks "${tasks[@]}" --algos tqc --seeds "${seeds[@]}"
       --steps 500000)
# Under v0's surface guard, as the campaign trained (on aba3e70, before stack's v1; flip's
# own is the same): told to this tree's code; a FROZEN tree from before v1 has no other.
guard=(--guard-ignores-carried false)
[ -z "${FROZEN:-}" ] || guard=()
train_options=(--backend sbx "${guard[@]}" --stop-at-success 0.95 --stop-after 5
               --checkpoint-every 10000 --threads 1 --device cpu)
background_sweep "$1" results/learnability
