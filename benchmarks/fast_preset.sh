#!/usr/bin/env bash
# The fast preset against its targets (docs/experiments/fast-preset.md): `train --preset
# fast` on TASK for each seed in turn, one process on one core, to a step budget (push 62k
# steps, ~33 minutes at ~32 ms a step, past its 30-minute target; pick-and-place 60k, ~32
# minutes of its 60; stack and flip, which Table I's recipe does not learn, 300k) or 5
# evaluations at 95 %, runs outside the work tree; a run already there resumes, STEPS=N
# raising its budget.
#
#   benchmarks/fast_preset.sh TASK [SEED ...]   default seeds 0 1 2
#   benchmarks/fast_preset.sh sync              the runs' config.json, eval.csv and, once
#                                               finished, outcome.json and policy.pt into
#                                               results/fast-preset/ (`franka-composer keep`;
#                                               stack's and flip's into
#                                               results/fast-preset-stack-flip/)
#
# RUNS (default ~/franka_runs/fast-preset); FROZEN=COMMIT trains that commit's code (a
# worktree beside $RUNS). Read the runs with
#   franka-composer report results/fast-preset/push-seed* --wall-clock
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
source benchmarks/background_sweep.sh
sweep_settings "$HOME/franka_runs/fast-preset"
task=${1:-}
case "$task" in
  push) steps=${STEPS:-62000} ;;
  pick_and_place) steps=${STEPS:-60000} ;;
  stack|flip) steps=${STEPS:-300000} ;;
  sync)
    shopt -s nullglob
    for lane in "push pick_and_place:results/fast-preset" "stack flip:results/fast-preset-stack-flip"; do
      runs=()
      for name in ${lane%%:*}; do runs+=("$RUNS/$name"-seed*/); done
      [ ${#runs[@]} -eq 0 ] || "$BIN/franka-composer" keep "${runs[@]}" --into "${lane#*:}" || exit 1
    done
    exit 0 ;;
  *) sed -n '2,18p' "$0"; exit 2 ;;
esac
shift
read -ra seeds <<< "${*:-0 1 2}"
# Every seed as train takes it (its own check), before the first trains.
"$BIN/python" - "${seeds[@]}" <<'PY' || exit 2
import argparse
import sys
from franka_composer.cli.options import training_seed
for seed in sys.argv[1:]:
    try:
        training_seed(seed)
    except argparse.ArgumentTypeError as error:
        sys.exit(f"a seed {error}")
PY
refuse_emulated_bf16 "The fast preset's runs" || exit 1
if [ -n "${FROZEN:-}" ]; then use_frozen_tree "$FROZEN" "$RUNS" || exit 1; fi
mkdir -p "$RUNS"
for seed in "${seeds[@]}"; do
  out=$RUNS/$task-seed$seed
  resume=()
  if [ -f "$out/config.json" ]; then resume=(--resume); fi
  "$BIN/franka-composer" train --preset fast --task "$task" --seed "$seed" --out "$out" \
    ${resume[@]+"${resume[@]}"} --total-steps "$steps" --stop-at-success 0.95 --stop-after 5 \
    --checkpoint-every 10000 --threads 1 --device cpu --no-progress || exit 1
done
