#!/usr/bin/env bash
# Training throughput (env steps/s) of Table I settings, one short run per spec, back to back.
#
#   benchmarks/train_throughput.sh "push sac step 1 600" "push sac episode 1 600" ...
#   BIN=.venv-sbx/bin benchmarks/train_throughput.sh "push sac step 1 1100 sb3" \
#     "push sac step 1 1100 sbx"
#
# Each spec is "TASK ALGO SCHEDULE TRAIN_EVERY STEPS [BACKEND [PRECISION]]" (BACKEND: sb3, the
# default, or sbx, which needs sbx-rl in BIN's environment; PRECISION: fp32, the default, or
# bf16). TRAIN_ARGS adds options to every run, e.g. the Table II campaign's slide network:
#   TRAIN_ARGS="--net-arch 256,256,256 --batch-size 512" benchmarks/train_throughput.sh ...
# A run takes SB3's 100 random steps, then learns; it evaluates once at the start and once
# at the end (1 episode), so steps/s = (STEPS - 100) / (wall time of eval.csv's last row -
# its first row).
# Runs land in runs/throughput/ (not committed); each prints one line with the load average
# and the CPU seconds the whole process used per wall second (above 1: more than one core).
# With JAX_LOG_COMPILES=1 in the environment, sbx runs also print the seconds JAX spent
# tracing, lowering and compiling (summed from its log, which is kept in the run's stderr.log).
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
source benchmarks/tools.sh
use_tools
TIMEFORMAT='%R %U %S'
for spec in "$@"; do
  read -r task algo schedule every steps backend precision <<<"$spec"
  backend=${backend:-sb3} precision=${precision:-fp32}
  out=runs/throughput/$task-$algo-$schedule-every$every
  [[ $backend == sb3 ]] || out=$out-$backend
  [[ $precision == fp32 ]] || out=$out-$precision
  rm -rf "$out"
  mkdir -p "$out"
  times=$( { time "$BIN/franka-composer" train --task "$task" --algo "$algo" --seed 0 \
    --out "$out" --total-steps "$steps" --eval-every "$steps" --eval-episodes 1 \
    --update-schedule "$schedule" --train-every "$every" --backend "$backend" \
    --precision "$precision" --threads 1 ${TRAIN_ARGS:-} \
    --no-progress --device cpu >/dev/null 2>"$out/stderr.log"; } 2>&1 )
  python3 - "$out" "$steps" "$spec" "$times" <<'PY'
import csv, os, re, sys
out, steps, spec, times = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4].split()
rows = list(csv.DictReader(open(f"{out}/eval.csv")))
seconds = float(rows[-1]["wall_time_s"]) - float(rows[0]["wall_time_s"])
wall, cpu = float(times[0]), float(times[1]) + float(times[2])
line = (f"{spec}: {(steps - 100) / seconds:.1f} steps/s (load {os.getloadavg()[0]:.2f}; "
        f"learning {seconds:.1f} s; process {wall:.1f} s wall, {cpu / wall:.2f} cpu/wall")
log = open(f"{out}/stderr.log").read()
compiles = re.findall(r"Finished .* in ([0-9.e-]+) sec", log)
if compiles:
    line += (f"; JAX compile {sum(map(float, compiles)):.1f} s, of which "
             f"{log.count('Compiling jit(_train)')} compilations of the update step")
print(line + ")")
PY
done
