#!/usr/bin/env bash
# Pick-and-place at the paper's code's timing (`--timing reference`: 0.5 s of physics per
# step, velocities multiplied by 0.05 s) and the paper's budget (5e5 steps): Table II's
# cells' settings (Table I, the campaign's stopping rule) with TQC (sbx fp32), SAC (bf16)
# or DDPG (SB3 fp32), seeds 0, 1, 2, at low priority, runs outside the work tree.
# TIMING=default trains the same cells at this suite's 0.05 s: Table II's pick-and-place
# cells (4e5 steps; DDPG one seed at 2e5) at the paper's budget.
#
#   benchmarks/reference_timing.sh run      train (or resume) the cells, WORKERS at a time
#                                           (default 1), but those sync kept as finished;
#                                           FROZEN=COMMIT runs that commit's code (a
#                                           worktree beside $RUNS)
#   benchmarks/reference_timing.sh stop     checkpoint the running cells and stop
#   benchmarks/reference_timing.sh status   the table of cells, evaluations to retrace
#   benchmarks/reference_timing.sh sync     what the cells kept, into $KEPT
#   benchmarks/reference_timing.sh report   from what sync kept in $KEPT, the algorithms
#                                           whose every seed has finished (the others
#                                           named, not reported): the test over 20 episodes
#                                           (table.md) and 200 others (seed 100,
#                                           table-200-episodes.md), the curves (curves.png)
#                                           and the steps to 50/80/90 % beside the paper's with
#                                           the costs (report.md), into $KEPT; PARTIAL=1
#                                           makes the tables of every finished cell and
#                                           the rest of every cell's evaluations so far
#
# ALGO (default tqc), SEEDS (default "0 1 2") and TIMING (reference, the default, or
# default) pick the cells; RUNS (default ~/franka_runs/TIMING-timing), KEPT (default
# results/TIMING-timing).
set -uo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"; exit 0 ;; esac
cd "$(dirname "$0")/.."
case "${1:-}" in run|stop|status|sync|report) ;; *) sed -n '2,28p' "$0"; exit 2 ;; esac
source benchmarks/background_sweep.sh
TIMING=${TIMING:-reference}
case "$TIMING" in
  reference) timing=(--timing reference) ;;
  default) timing=() ;;
  *) echo "TIMING must be reference or default, not $TIMING" >&2; exit 2 ;;
esac
sweep_settings "$HOME/franka_runs/$TIMING-timing"
read -ra seeds <<< "${SEEDS:-0 1 2}"
ALGO=${ALGO:-tqc}
KEPT=${KEPT:-results/$TIMING-timing}
# Each algorithm on the computation Table II's cells validated.
case "$ALGO" in
  tqc) computation=(--backend sbx) ;;
  sac) computation=(--precision bf16) ;;
  ddpg) computation=() ;;
  *) echo "ALGO must be tqc, sac or ddpg, not $ALGO" >&2; exit 2 ;;
esac
BUDGET=500000

# finished_algorithms: three lines from the runs sync kept in $KEPT, by name: the runs of
# the algorithms whose every seed (SEEDS) has finished at BUDGET, the finished runs of all,
# and for each other algorithm what it waits for. This checkout's code reads them (before
# use_frozen_tree).
finished_algorithms() {
  "$BIN/python" - "$KEPT" "$BUDGET" "${seeds[@]}" <<'PY'
import pathlib
import sys
from franka_composer.training.runs import RunDir, run_finished
kept, budget, seeds = pathlib.Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
runs = {path.name: path for path in sorted(kept.glob("pick_and_place-*-seed*/"))
        if (path / "config.json").is_file()}
finished = [name for name, path in runs.items() if run_finished(RunDir(path), budget)]
complete, waiting = [], []
for algo in dict.fromkeys(name.split("-")[1] for name in runs):
    cells = [f"pick_and_place-{algo}-seed{seed}" for seed in seeds]
    if all(cell in finished for cell in cells):
        complete += cells
        continue
    unfinished = [cell for cell in cells if cell in runs and cell not in finished]
    absent = [f"seed {seed} not kept"
              for seed, cell in zip(seeds, cells) if cell not in runs]
    waiting.append(f"{algo} ({', '.join(unfinished + absent)})")
print(" ".join(complete))
print(" ".join(finished))
print("; ".join(waiting))
PY
}

if [ "$1" = run ]; then  # A cell sync kept as finished is done (its runs may be gone).
  [ "$ALGO" != sac ] || refuse_emulated_bf16 "SAC's cells (--precision bf16)" || exit 1
  by_algorithm=$(finished_algorithms) || exit 1
  { read -r _; read -r finished; } <<< "$by_algorithm"
  unfinished=()
  for seed in "${seeds[@]}"; do
    [[ " $finished " == *" pick_and_place-$ALGO-seed$seed "* ]] || unfinished+=("$seed")
  done
  [ ${#unfinished[@]} -gt 0 ] || { echo "every cell has finished ($KEPT)"; exit 0; }
  seeds=("${unfinished[@]}")
fi
sweep=(sweep --out "$RUNS" --tasks pick_and_place --algos "$ALGO" --seeds "${seeds[@]}"
       --steps "$BUDGET")
train_options=(${computation[@]+"${computation[@]}"} ${timing[@]+"${timing[@]}"}
               --stop-at-success 0.95 --stop-after 5 --checkpoint-every 10000 --threads 1
               --device cpu)
if [ "$1" = report ]; then
  by_algorithm=$(finished_algorithms) || exit 1
  { read -r complete; read -r finished; read -r waiting; } <<< "$by_algorithm"
  [ -z "$waiting" ] || echo "not reported until every seed has finished: $waiting" >&2
  [ "${PARTIAL:-0}" = 1 ] || finished=$complete
  read -ra finished <<< "$finished"
  if [ ${#finished[@]} -eq 0 ]; then
    echo "no algorithm has finished its cells in $KEPT" >&2
    exit 1
  fi
  report_cells "$KEPT" table "50 80 90" "${finished[@]/#/$KEPT/}"
  exit
fi
background_sweep "$1" "$KEPT"
