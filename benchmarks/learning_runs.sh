#!/usr/bin/env bash
# The single-seed learning runs of RESULTS.md, two at a time (one per core), each stopped
# by SIGTERM at its time budget and resumed once (the run checkpoints first; `franka-composer
# train --resume --out DIR` continues it with the same step counter, buffer and eval.csv),
# then the final test and the curves. The push run (SAC, 40 min) was an earlier session's:
#   franka-composer train --task push --algo sac --seed 0 --out runs/learn/push-sac-seed0 \
#     --update-schedule episode --checkpoint-every 10000 --threads 1
set -uo pipefail
cd "$(dirname "$0")/.."
export OMP_NUM_THREADS=1
BIN=${BIN:-.venv/bin}
mkdir -p runs/learn2
train() {  # MINUTES OUT [OPTIONS...]: one leg of a run, stopped by SIGTERM after MINUTES.
  local minutes=$1 out=$2; shift 2
  timeout -s TERM "${minutes}m" "$BIN/franka-composer" train --out "$out" --threads 1 \
    --no-progress --device cpu "$@" >>"$out.log" 2>&1
  echo "$(date +%T) $out stopped at $(tail -n 1 "$out/eval.csv")"
}
PICK=runs/learn2/pick_and_place-sac-seed0
SLIDE=runs/learn2/slide-sac-seed0
(train 65 $PICK --task pick_and_place --algo sac --seed 0 --update-schedule episode \
   --checkpoint-every 10000 && train 52 $PICK --resume) &
sleep 1500  # The slide run started 25 minutes later, when the machine's other job ended.
(train 52 $SLIDE --task slide --algo sac --seed 0 --update-schedule episode \
   --checkpoint-every 10000 --net-arch 256,256,256 --batch-size 512 \
   && train 40 $SLIDE --resume) &
wait
for run in $PICK $SLIDE; do
  mkdir -p "results/$(basename "$run")"
  cp "$run/config.json" "$run/eval.csv" "results/$(basename "$run")/"
done
"$BIN/franka-composer" evaluate $PICK $SLIDE --episodes 20 --out results/table.md
"$BIN/franka-composer" plot results/push-sac-seed0 results/pick_and_place-sac-seed0 \
  results/slide-sac-seed0 --out results/curves.png
