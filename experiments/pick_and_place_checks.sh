#!/usr/bin/env bash
# Issue 37's checks of what keeps TQC from lifting at the reference timing: each one run,
# TQC (sbx) seed 0 (or SEED) with the reference-timing cell's settings and one thing
# changed, on the frozen tree it began on (a worktree beside its run), at low priority, in
# the background, its run outside the work tree; resumed from its checkpoint where it has
# one, else begun from zero (a run lost with its machine retraces its kept evaluations,
# and `keep` refuses it until it has passed them).
#
#   experiments/pick_and_place_checks.sh run CHECK    train (or resume) it in the background
#   experiments/pick_and_place_checks.sh stop CHECK   checkpoint it and stop (waits)
#   experiments/pick_and_place_checks.sh keep CHECK   what it has kept, into results/
#   experiments/pick_and_place_checks.sh status CHECK whether it runs, its checkpoint, its
#                                                     last evaluation, kept ones to retrace
#
# CHECK: damped_block (the reference code's block damping), unguarded (the surface guard
# let go), reference_physics (every difference experiments/env_differences.py undoes, undone
# together), reference_env (the reference code's own env: REFERENCE_PATH, default
# ~/franka_runs/reference-code, a checkout of panda_mujoco_gym at e9881d9), reference_env_sb3
# (the same on SB3 in fp32, the paper's computation, in place of sbx), learning_starts (1e5
# random steps first), reference_env_learning_starts (both: the reference code's own env,
# 1e5 random steps first), reference_physics_learning_starts (reference_physics, 1e5 random
# steps first), damped_block_learning_starts (the block damped as there, 1e5 random steps
# first: options of `train` alone). SEED (default 0) picks the seed; RUNS (default
# ~/franka_runs) holds the runs and the trees, RESULTS (default results/) what `keep` kept.
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
ROOT=$PWD
case "${1:-}:${2:-}" in
  run:?*|stop:?*|keep:?*|status:?*) ;;
  *) sed -n '2,24p' "$0"; exit 2 ;;
esac
SEED=${SEED:-0}
[[ $SEED =~ ^[0-9]+$ ]] || { echo "SEED must be a whole number, not $SEED" >&2; exit 2; }
RUNS=$(realpath -m "${RUNS:-$HOME/franka_runs}")
RESULTS=$(realpath -m "${RESULTS:-results}")
source benchmarks/background_sweep.sh
use_tools
cell=(--task pick_and_place --algo tqc --backend sbx --seed "$SEED" --total-steps 500000
      --stop-at-success 0.95 --stop-after 5 --checkpoint-every 10000 --threads 1 --device cpu
      --no-progress)
# CHECK: its frozen tree, its folder under RUNS and results/, the train command, and what
# it changes in the cell's options.
changed=()
case "$2" in
  damped_block) tree=42d36b4 folder=damped-block
    train=(python experiments/altered_runs.py damped_block train --timing reference) ;;
  unguarded) tree=42d36b4 folder=unguarded
    train=(python experiments/altered_runs.py unguarded train --timing reference) ;;
  reference_physics) tree=ee552b6 folder=reference-physics
    train=(python experiments/altered_runs.py reference_physics train --timing reference) ;;
  reference_physics_learning_starts) tree=56ad82b folder=reference-physics-learning-starts
    train=(python experiments/altered_runs.py reference_physics train --timing reference)
    changed=(--learning-starts 100000) ;;
  reference_env|reference_env_sb3|reference_env_learning_starts) tree=369ca2c
    folder=reference-env
    train=(python experiments/reference_env_runs.py --reference-path
           "${REFERENCE_PATH:-$HOME/franka_runs/reference-code}" train)
    # After the cell's options, so that they replace its backend.
    [ "$2" = reference_env_sb3 ] && folder=reference-env-sb3 \
      changed=(--backend sb3 --precision fp32)
    [ "$2" = reference_env_learning_starts ] && folder=reference-env-learning-starts \
      changed=(--learning-starts 100000) ;;
  learning_starts) tree=1816633 folder=learning-starts
    train=(python -m franka_composer train --timing reference --learning-starts 100000) ;;
  damped_block_learning_starts) tree=56ad82b folder=damped-block-learning-starts
    train=(python -m franka_composer train --timing reference --learning-starts 100000
           --object-damping 0.01) ;;
  *) echo "CHECK must be damped_block, unguarded, reference_physics, reference_env," \
          "reference_env_sb3, learning_starts, reference_env_learning_starts," \
          "reference_physics_learning_starts or damped_block_learning_starts, not $2" >&2
     exit 2 ;;
esac
out=$RUNS/$folder/pick_and_place-tqc-seed$SEED
case "$1" in
  run)
    if pgrep -f -- "--out $out( |$)" >/dev/null; then echo "$2 is running already" >&2; exit 1; fi
    worktree=$RUNS/code-$tree
    [ -d "$worktree" ] || git worktree add --detach "$worktree" "$tree" >/dev/null || exit 1
    resume=(); [ -d "$out/checkpoint" ] && resume=(--resume)
    mkdir -p "$RUNS/$folder"
    machine_log note "$RUNS/$folder" || exit 1
    # Its own session, whose autogroup's niceness leaves the machine to other work.
    (cd "$worktree" && PYTHONPATH=$worktree setsid nohup bash -c \
      'echo 19 > /proc/self/autogroup 2>/dev/null; exec nice -n 10 "$@"' run \
      "$BIN/${train[0]}" "${train[@]:1}" "${cell[@]}" "${changed[@]}" --out "$out" \
      "${resume[@]}" >> "$RUNS/$folder/seed$SEED.log" 2>&1 &)
    echo "$2: training in the background into $out (log: $RUNS/$folder/seed$SEED.log)"
    ;;
  stop)
    pkill -TERM -f -- "--out $out( |$)" || { echo "$2 is not running" >&2; exit 1; }
    for _ in $(seq 300); do
      pgrep -f -- "--out $out( |$)" >/dev/null || break
      sleep 1
    done
    if pgrep -af -- "--out $out( |$)"; then echo "still running: the process above" >&2; exit 1; fi
    cat "$out/checkpoint/state.json"; echo
    ;;
  keep) "$BIN/franka-composer" keep "$out" --into "$RESULTS/$folder" ;;
  status)
    if [ ! -d "$out" ]; then
      echo "$2: not started ($out)"
    else
      state=stopped; pgrep -f -- "--out $out( |$)" >/dev/null && state=running
      steps=none
      [ -f "$out/checkpoint/state.json" ] && steps=$(sed -n \
        's/.*"steps": *\([0-9]*\).*/\1/p' "$out/checkpoint/state.json")
      last=$(tail -n 1 "$out/eval.csv" 2>/dev/null | cut -d, -f1,3)
      echo "$2: $state; checkpoint at step ${steps:-none}; last evaluation (step,success):" \
           "${last:-none}"
    fi
    machine_log changes "$RUNS/$folder"
    kept_ahead "$RUNS/$folder" "$RESULTS/$folder" "$(basename "$out")"
    ;;
esac
