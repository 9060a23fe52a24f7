#!/usr/bin/env bash
# The paper's Table II on this suite (issue 15): every cell an ordinary resumable
# `franka-composer train` run, Table I settings, sparse reward, the paper's episode
# termination, and the early-stopping rule (5 consecutive evaluations >= 95 %).
#
#   benchmarks/table2.sh run [CELL...]   train the cells (default: all, in the order below),
#                                        WORKERS at a time (default 1), each resumed from
#                                        its checkpoint if it has one, skipped if finished
#   benchmarks/table2.sh sync            copy each cell's config.json, eval.csv and
#                                        outcome.json into results/table2/<cell>/
#   benchmarks/table2.sh list            the cells and their budgets
#
# Runs and their checkpoints live in $RUNS (default ~/franka_runs/table2), outside the work
# tree, so an interrupted cell resumes in a later session. A cell is TASK-ALGO-seedN.
set -uo pipefail
cd "$(dirname "$0")/.."
RUNS=${RUNS:-$HOME/franka_runs/table2}
BIN=${BIN:-.venv/bin}
WORKERS=${WORKERS:-1}
export OMP_NUM_THREADS=1 MENAGERIE_ROOT=${MENAGERIE_ROOT:-$(cd .. && pwd)/shared/menagerie}

# Budgets per cell (issue 15): task algo seeds steps. Slide uses [256]^3 and batch 512
# instead of Table I's [512]^3 and 2048 (~6x the cost per step on this CPU).
CELLS=(
  "push sac 0,1,2 250000"
  "push tqc 0,1,2 250000"
  "pick_and_place tqc 0,1,2 400000"
  "pick_and_place sac 0,1,2 400000"
  "slide sac 0,1,2 200000"
  "slide tqc 0,1,2 200000"
  "push ddpg 0,1,2 150000"
  "pick_and_place ddpg 0 200000"
  "slide ddpg 0 200000"
)

all_cells() {
  for spec in "${CELLS[@]}"; do
    read -r task algo seeds steps <<<"$spec"
    for seed in ${seeds//,/ }; do echo "$task-$algo-seed$seed $steps"; done
  done
}

train_cell() {  # CELL STEPS
  local cell=$1 steps=$2 out="$RUNS/$1"
  local task=${cell%%-*} rest=${cell#*-}
  local algo=${rest%%-*} seed=${cell##*seed}
  if [ -f "$out/outcome.json" ]; then echo "$cell: finished"; return 0; fi
  local extra=()
  [ "$task" = slide ] && extra=(--net-arch 256,256,256 --batch-size 512)
  mkdir -p "$RUNS"
  if [ -f "$out/checkpoint/state.json" ]; then
    nice -n 10 "$BIN/franka-composer" train --resume --out "$out" --total-steps "$steps" \
      --threads 1 --no-progress --device cpu >>"$out.log" 2>&1
  else
    rm -rf "$out"
    nice -n 10 "$BIN/franka-composer" train --task "$task" --algo "$algo" --seed "$seed" \
      --out "$out" --total-steps "$steps" --stop-at-success 0.95 --stop-after 5 \
      --checkpoint-every 10000 --threads 1 --no-progress --device cpu "${extra[@]}" \
      >>"$out.log" 2>&1
  fi
  echo "$(date +%F\ %T) $cell: exit $? at $(tail -n 1 "$out/eval.csv" 2>/dev/null)"
}

case "${1:-}" in
  run)
    shift
    if [ $# -gt 0 ]; then
      queue=$(all_cells | grep -E "^($(IFS='|'; echo "$*")) ")
    else
      queue=$(all_cells)
    fi
    while read -r cell steps; do
      while [ "$(jobs -rp | wc -l)" -ge "$WORKERS" ]; do sleep 10; done
      train_cell "$cell" "$steps" &
      sleep 5
    done <<<"$queue"
    wait
    ;;
  sync)
    for dir in "$RUNS"/*/; do
      cell=$(basename "$dir")
      mkdir -p "results/table2/$cell"
      for file in config.json eval.csv outcome.json; do
        [ -f "$dir/$file" ] && cp "$dir/$file" "results/table2/$cell/"
      done
    done
    ls results/table2
    ;;
  list) all_cells ;;
  *) sed -n '2,16p' "$0"; exit 2 ;;
esac
