# Sourced by the scripts that run a `franka-composer sweep` in the background here
# (benchmarks/table2.sh, benchmarks/reference_timing.sh): on a frozen tree if asked, at
# low priority, stopped with its cells checkpointed.

source benchmarks/tools.sh

# sweep_settings DEFAULT_RUNS: what every such script reads from its environment, in the
# repository's root: RUNS (where the cells train; default DEFAULT_RUNS), WORKERS (cells at
# a time, default 1), and BIN and MENAGERIE_ROOT (`use_tools`).
sweep_settings() {
  RUNS=$(realpath -m "${RUNS:-$1}")
  WORKERS=${WORKERS:-1}
  use_tools
}

# use_frozen_tree COMMIT RUNS: from here on, COMMIT's code (a worktree beside RUNS, made
# where missing). The sweep imports it (PYTHONPATH) and its cells train what it imported
# (training/sweep.py, cell_environment); the tree is the working directory too, because on
# Python 3.10 each cell's `python -m franka_composer` puts that first on sys.path.
use_frozen_tree() {
  local tree
  tree=$(dirname "$2")/code-$1
  [ -d "$tree" ] || git worktree add --detach "$tree" "$1" >/dev/null || return 1
  export PYTHONPATH=$tree
  cd "$tree" || return 1
}

# machine_log note|changes FOLDER: the machines that ran FOLDER's runs, one line each time
# one was started there (FOLDER/machines.jsonl, `franka_composer.training.machine`): runs
# on frozen trees from before checkpoints recorded their machine keep it here. `note` adds
# this machine and says, on stderr, what differs from the machine noted last
# (`machine.another_machine`: what that means for the runs resumed there);
# `changes` prints a line for each change the log holds. Run with the repository's own
# package, before a frozen tree is put on PYTHONPATH.
machine_log() {
  "$BIN/python" - "$@" <<'PY'
import datetime
import json
import pathlib
import sys
from franka_composer.training import machine
action, log = sys.argv[1], pathlib.Path(sys.argv[2]) / "machines.jsonl"
noted = [json.loads(line) for line in log.read_text().splitlines()] if log.is_file() else []
if action == "note":
    now = {"noted": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
           **machine.fingerprint()}
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as handle:
        handle.write(json.dumps(now) + "\n")
    noted = noted[-1:] + [now]
for before, after in zip(noted, noted[1:]):
    changed = machine.differences(before, after)
    if changed:
        print(f"{log}: runs resumed from {after['noted']} on "
              f"{machine.another_machine(changed)}",
              file=sys.stderr if action == "note" else sys.stdout)
PY
}

# refuse_emulated_bf16 WHAT: fails, saying why, on a CPU without bf16 units
# (`machine.bf16_units`), where torch emulates bf16: WHAT (runs in bf16) would take many
# times their time on a machine with them (SAC's gradient step 17x fp32's on an AVX2 EPYC:
# `python benchmarks/precision.py`). Run with the repository's own package.
refuse_emulated_bf16() {
  "$BIN/python" -c 'import sys
from franka_composer.training.machine import bf16_units
sys.exit(bf16_units() is False)' && return 0
  echo "$1 train in bf16, and this CPU has no bf16 units (AVX512-BF16, AMX-BF16): torch" \
    "emulates them there, many times slower than fp32 (python benchmarks/precision.py" \
    "measures it); run them on a machine that has them" >&2
  return 1
}

# lower_session_priority: where Linux groups processes by session (autogroup), nice acts
# only within the group, and the group's own niceness is what leaves the machine to other
# work. Only a session of the script's own (`setsid SCRIPT run`), not the caller's terminal.
lower_session_priority() {
  if [ "$(ps -o sid= -p $$ | tr -d ' ')" = "$$" ]; then
    echo 19 2>/dev/null > /proc/self/autogroup || true
  fi
}

# stop_sweep PATTERN RUNS: SIGTERM to the sweep whose command line matches PATTERN; it
# cancels its cells, each run checkpoints before exiting, and the sweep exits after them
# (so it starts no other cell). Waits for both, up to 5 minutes; fails naming those still
# running.
stop_sweep() {
  local running="franka_composer train --out $2/|$1"
  pkill -TERM -f "$1" || true
  for _ in $(seq 300); do
    pgrep -f "$running" >/dev/null || break
    sleep 1
  done
  if pgrep -af "$running"; then
    echo "still running: the processes above" >&2
    return 1
  fi
}

# background_sweep ACTION KEPT: run, stop, status or sync (into $KEPT if set, else KEPT) the
# cells of the array `sweep` (`franka-composer sweep --out "$RUNS" ...`'s arguments), each
# trained with the array `train_options` (given to status and sync too: they read the cells
# as the sweep trains them); run starts on FROZEN's tree if set, at low priority.
background_sweep() {
  case "$1" in
    run)
      machine_log note "$RUNS" || return 1
      if [ -n "${FROZEN:-}" ]; then use_frozen_tree "$FROZEN" "$RUNS" || return 1; fi
      lower_session_priority
      nice -n 10 "$BIN/franka-composer" "${sweep[@]}" --num-cpus "$WORKERS" --refresh 600 -- \
        "${train_options[@]}"
      ;;
    stop)
      stop_sweep "franka-composer sweep --out $RUNS " "$RUNS" || return 1
      "$BIN/franka-composer" "${sweep[@]}" --status -- "${train_options[@]}"
      ;;
    status)
      "$BIN/franka-composer" "${sweep[@]}" --status -- "${train_options[@]}" || return 1
      machine_log changes "$RUNS"
      kept_ahead "$RUNS" "${KEPT:-$2}"
      ;;
    sync) "$BIN/franka-composer" "${sweep[@]}" --sync "${KEPT:-$2}" -- "${train_options[@]}" ;;
    *) return 2 ;;
  esac
}

# kept_ahead RUNS KEPT [NAME...]: a line for each unfinished run kept in KEPT (or each NAME)
# whose evaluations there go past its run's in RUNS: a run lost with its machine, begun
# again from zero (or not yet), which retraces them and is kept once it has passed them;
# and one for each run here that has left them (keeping it would refuse, hours later).
kept_ahead() {
  "$BIN/python" - "$@" <<'PY'
import pathlib
import sys
from franka_composer.training.keep import departure
from franka_composer.training.runs import RunDir, read_eval_rows
runs, kept = (pathlib.Path(arg) for arg in sys.argv[1:3])
names = sys.argv[3:] or sorted(path.name for path in kept.glob("*/"))
for name in names:
    ours = RunDir(kept / name)
    rows = read_eval_rows(ours.eval_csv)
    if not rows or ours.read_outcome():
        continue
    theirs = RunDir(runs / name).kept_evaluations()
    left = departure(rows, theirs)
    if left:
        row, other = left
        at = ("no evaluation" if other is None else f"success rate {other['success_rate']:g}, "
              f"mean reward {other['mean_reward']:g}")
        print(f"{name}: its run here has left the evaluations kept in {kept} at step "
              f"{row['steps']:,} ({at}; kept: {row['success_rate']:g}, "
              f"{row['mean_reward']:g}): it will not be kept there")
        continue
    last = rows[-1]["steps"]
    reached = max((row["steps"] for row in theirs), default=None)
    if reached is not None and reached >= last:
        continue
    here = ("no run here" if reached is None else
            f"its run here has retraced them to step {reached:,}")
    print(f"{name}: evaluations kept to step {last:,} in {kept}; {here} (a run begun again "
          "from zero retraces them, and is kept once it has passed them)")
PY
}

# report_cells KEPT NAME THRESHOLDS RUN...: the finished RUNs' test over 20 episodes
# (KEPT/NAME.md) and over 200 others (seed 100, KEPT/NAME-200-episodes.md: the 20 are one
# fixed set, +-5-9 points per model); from the RUNs (PARTIAL=1: from every run kept in
# KEPT, its evaluations so far), the curves (KEPT/curves.png) and the steps to THRESHOLDS
# (percent, e.g. "80 90") beside the paper's with the costs (KEPT/report.md).
report_cells() {
  local kept=$1 name=$2 thresholds curves
  read -ra thresholds <<< "$3"
  shift 3
  curves=("$@")
  [ "${PARTIAL:-0}" != 1 ] || curves=("$kept")
  "$BIN/franka-composer" evaluate "$@" --episodes 20 --device cpu --out "$kept/$name.md" \
    || return 1
  "$BIN/franka-composer" evaluate "$@" --episodes 200 --seed 100 --device cpu \
    --out "$kept/$name-200-episodes.md" || return 1
  "$BIN/franka-composer" plot "${curves[@]}" --out "$kept/curves.png" || return 1
  "$BIN/franka-composer" report "${curves[@]}" --thresholds "${thresholds[@]}" \
    --paper-curves results/paper-curves/curves.csv --out "$kept/report.md"
}
