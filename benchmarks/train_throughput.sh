#!/usr/bin/env bash
# Training throughput (env steps/s) of Table I settings, one short run per spec, back to back.
#
#   benchmarks/train_throughput.sh "push sac step 1 600" "push sac episode 1 600" ...
#
# Each spec is "TASK ALGO SCHEDULE TRAIN_EVERY STEPS". A run takes SB3's 100 random steps,
# then learns; it evaluates once at the start and once at the end (1 episode), so
# steps/s = (STEPS - 100) / (wall time of eval.csv's last row - its first row).
# Runs land in runs/throughput/ (not committed); each prints one line with the load average.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMP_NUM_THREADS=1
BIN=${BIN:-.venv/bin}
for spec in "$@"; do
  read -r task algo schedule every steps <<<"$spec"
  out=runs/throughput/$task-$algo-$schedule-every$every
  rm -rf "$out"
  "$BIN/franka-composer" train --task "$task" --algo "$algo" --seed 0 --out "$out" \
    --total-steps "$steps" --eval-every "$steps" --eval-episodes 1 \
    --update-schedule "$schedule" --train-every "$every" --threads 1 --no-progress --device cpu \
    >/dev/null
  python3 - "$out/eval.csv" "$steps" "$spec" <<'PY'
import csv, os, sys
rows = list(csv.DictReader(open(sys.argv[1])))
steps = int(sys.argv[2])
seconds = float(rows[-1]["wall_time_s"]) - float(rows[0]["wall_time_s"])
print(f"{sys.argv[3]}: {(steps - 100) / seconds:.1f} steps/s (load {os.getloadavg()[0]:.2f})")
PY
done
