"""A grid of training runs (tasks x algorithms x seeds, a step budget per cell), each an
ordinary resumable `franka-composer train` run in its own directory under the sweep's.

The grid is data (`Cell`s; `GRIDS` names the campaigns this project runs). `run_sweep`
runs the cells that are not finished as Ray tasks of one CPU each, on a local Ray or an
existing cluster; each task runs `train` in a process of its own (so a crash or a kill
costs one cell, and SIGTERM makes it checkpoint), resuming from the cell's checkpoint if it
has one. Running the same sweep again resumes what is unfinished and skips what is done.
What a cell has reached is read from its directory (`cell_status`), so the live table, a
second terminal and `evaluate`/`plot` all see the same thing.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import shlex
import shutil
import signal
import site
import socket
import subprocess
import sys
import time
import warnings
from typing import Any

from franka_composer.signals import interrupt_on
from franka_composer.training.report import with_variant
from franka_composer.training.keep import check_kept_apart, files_to_keep, keep_run
from franka_composer.training.runs import (RESUME_OPTIONS, RunDir, read_eval_rows,
                                          run_finished)
from franka_composer.validation import repeated
from franka_composer.wording import counted


@dataclasses.dataclass(frozen=True)
class Cell:
    """One run of a sweep: `train --task TASK --algo ALGO --seed SEED --total-steps STEPS`,
    plus `options` (further `train` arguments, e.g. a smaller network for one task)."""

    task: str
    algo: str
    seed: int
    steps: int
    options: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return f"{self.task}-{self.algo}-seed{self.seed}"


def grid(tasks, algos, seeds, steps, options: tuple[str, ...] = ()) -> list[Cell]:
    """Every (task, algorithm, seed); `steps` is one budget or {task: budget}. A value given
    twice is refused: its cells would train at once into one directory."""
    for kind, values in (("task", tasks), ("algorithm", algos), ("seed", seeds)):
        twice = repeated(values)
        if twice:
            raise ValueError(f"{kind}(s) {', '.join(twice)} given more than once: each "
                             "cell is one run directory")
    budget = steps if isinstance(steps, dict) else dict.fromkeys(tasks, steps)
    return [Cell(task, algo, int(seed), int(budget[task]), options)
            for task in tasks for algo in algos for seed in seeds]


#: The campaign's budgets for the paper's Table II (Table I settings otherwise). Slide uses
#: [256]^3 and batch 512 instead of Table I's [512]^3 and 2048 (~6x the cost per step on a
#: CPU): the one deviation of the networks, stated with the results. How each algorithm's
#: networks are computed is the fastest way that learned as SB3 in fp32 (the paper's) does,
#: 3 seeds to 1e5 steps on push (docs/experiments/computation-checks.md): SAC's gradient
#: steps in bf16 (2x fp32's speed here); TQC on sbx in fp32 (1.5x SB3-bf16's), because TQC
#: in bf16 learned slower than in fp32; DDPG, not checked in bf16, as the paper computed it.
#: Cells in the order they are run.
_SAC = ("--precision", "bf16")
_TQC = ("--backend", "sbx")
_DDPG = ()
_SLIDE_NETWORK = ("--net-arch", "256,256,256", "--batch-size", "512")
GRIDS = {
    "table2": (grid(["push"], ["sac"], [0, 1, 2], 250_000, _SAC)
               + grid(["push"], ["tqc"], [0, 1, 2], 250_000, _TQC)
               + grid(["pick_and_place"], ["tqc"], [0, 1, 2], 400_000, _TQC)
               + grid(["pick_and_place"], ["sac"], [0, 1, 2], 400_000, _SAC)
               + grid(["slide"], ["sac"], [0, 1, 2], 200_000, _SLIDE_NETWORK + _SAC)
               + grid(["slide"], ["tqc"], [0, 1, 2], 200_000, _SLIDE_NETWORK + _TQC)
               + grid(["push"], ["ddpg"], [0, 1, 2], 150_000, _DDPG)
               + grid(["pick_and_place"], ["ddpg"], [0], 200_000, _DDPG)
               + grid(["slide"], ["ddpg"], [0], 200_000, _SLIDE_NETWORK + _DDPG)),
}
#: The early-stopping rule of the campaigns: 5 consecutive evaluations >= 95 %.
STOPPING_RULE = ("--stop-at-success", "0.95", "--stop-after", "5")


def train_command(cell: Cell, root: pathlib.Path, train_args: tuple[str, ...], *,
                  resume: bool = False) -> list[str]:
    """The `train` command that starts the cell, or resumes it from its checkpoint (run in
    `cell_environment()`)."""
    return [sys.executable, "-m", "franka_composer", "train",
            *train_arguments(cell, root, train_args, resume=resume)]


def train_arguments(cell: Cell, root: pathlib.Path, train_args: tuple[str, ...], *,
                    resume: bool = False) -> list[str]:
    """`train_command`'s arguments to `train`."""
    arguments = ["--out", str(root / cell.name), "--total-steps", str(cell.steps),
                 "--no-progress"]
    if resume:
        return arguments + ["--resume", *_resume_args(train_args)]
    return arguments + ["--task", cell.task, "--algo", cell.algo, "--seed", str(cell.seed),
                        *cell.options, *train_args]


def cell_environment() -> dict[str, str]:
    """The environment a cell's `python -m franka_composer train` runs in, so that it trains
    the franka_composer this process imported, wherever the sweep's working directory is:
    `-m` would put that directory first on sys.path, and a checkout there would be trained
    instead (PYTHONSAFEPATH, Python 3.11+, leaves it out; 3.10 ignores it). The directory
    this franka_composer came from goes first on PYTHONPATH, unless it is a site-packages
    directory, which the cell searches in its place anyway (on PYTHONPATH it would come
    before the standard library)."""
    import franka_composer

    tree = os.path.realpath(pathlib.Path(franka_composer.__file__).parent.parent)
    sites = {os.path.realpath(path) for path in [*site.getsitepackages(),
                                                  site.getusersitepackages()]}
    environment = {**os.environ, "PYTHONSAFEPATH": "1"}
    if tree not in sites:
        given = os.environ.get("PYTHONPATH", "").split(os.pathsep)
        environment["PYTHONPATH"] = os.pathsep.join(
            [tree, *(path for path in given if path and path != tree)])
    return environment


#: The `train` options a cell's resume passes on from the sweep's (`RESUME_OPTIONS`: the rest
#: is in the run's config.json), by flag, each with the one value it takes: all but the
#: budget and --no-progress, which the sweep gives every cell itself (`train_arguments`).
_RESUMABLE = {"--" + name.replace("_", "-"): 1 for name in RESUME_OPTIONS
              if name not in ("total_steps", "progress")}


def _resume_args(train_args: tuple[str, ...]) -> list[str]:
    kept, args = [], list(train_args)
    while args:
        arg = args.pop(0)
        name = arg.split("=", 1)[0]
        if name in _RESUMABLE:
            kept.append(arg)
            if "=" not in arg:
                kept += args[:_RESUMABLE[name]]
                del args[:_RESUMABLE[name]]
    return kept


def run_cell(cell: Cell, root: pathlib.Path, train_args: tuple[str, ...]) -> tuple[str, int]:
    """Trains one cell to its budget in a process of its own; (cell name, exit code). A run
    without a checkpoint (stopped before its first one) starts again; a folder there that
    holds no run is left as it is, for train to refuse. Cancelled (Ctrl-C on the sweep), it
    passes SIGTERM on, so the run checkpoints first."""
    run = RunDir(root / cell.name)
    if cell_finished(run, cell):
        return cell.name, 0
    if run.config_path.is_file():
        with run.training_lock():  # Not from under a process training it.
            run.recover_checkpoint()
            if not run.read_state():
                shutil.rmtree(run.root)
    run.root.parent.mkdir(parents=True, exist_ok=True)
    with open(cell_log(cell, root), "a") as log:
        command = train_command(cell, root, train_args, resume=bool(run.read_state()))
        # The line also tells the sweep's table that the cell left the queue.
        log.write(f"{time.strftime('%Y-%m-%dT%H:%M:%S')} {shlex.join(command)}\n")
        log.flush()
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                                   env=cell_environment())
        try:
            # Ray cancels a task by a simulated SIGINT: Python acts on it between bytecodes
            # (so not inside a blocking wait) and not at all where the worker inherited
            # SIG_IGN from a sweep started in the background.
            with interrupt_on(signal.SIGINT):
                while process.poll() is None:
                    time.sleep(0.5)
            return cell.name, process.returncode
        except BaseException:
            process.terminate()
            process.wait()
            raise


def cell_log(cell: Cell, root: pathlib.Path) -> pathlib.Path:
    """Where the cell's `train` output goes, beside its run directory (appended to)."""
    return root / f"{cell.name}.log"


def _started_since(cell: Cell, root: pathlib.Path, since: float) -> bool:
    log = cell_log(cell, root)
    return log.exists() and log.stat().st_mtime >= since


def cell_finished(run: RunDir, cell: Cell) -> bool:
    """Whether `run` has ended at `cell`'s budget, or before it by the stopping rule."""
    return run_finished(run, cell.steps)


def sync_cells(cells: list[Cell], root: pathlib.Path, kept: pathlib.Path) -> list[str]:
    """Copies into `kept`/<cell> what each cell's run under `root` has kept (`keep_run`, at
    the cell's budget), once every run has been checked; the names of the cells that have a
    run."""
    check_kept_apart([root / cell.name for cell in cells], kept, "--sync")
    runs = {cell: RunDir(root / cell.name) for cell in cells}
    files = {cell: files_to_keep(run, RunDir(kept / cell.name), cell.steps)
             for cell, run in runs.items() if run.config_path.is_file()}
    for cell, kept_files in files.items():
        keep_run(kept_files, RunDir(kept / cell.name))
    return [cell.name for cell in files]


def finished_in(kept: pathlib.Path, cells: list[Cell]) -> list[Cell]:
    """The `cells` finished (`cell_finished`) in `kept`, where `sync_cells` copies them: done,
    even where their run directory is gone, as on a machine handed back bare."""
    return [cell for cell in cells if cell_finished(RunDir(kept / cell.name), cell)]


@dataclasses.dataclass(frozen=True)
class CellStatus:
    """What a cell's directory says it has reached."""

    name: str
    #: "done", "stopped early", "running" (in this sweep, or training elsewhere: its lock is
    #: held), "queued" (waiting for a CPU), "failed" (this sweep's), "unfinished" (started,
    #: not training now) or "waiting" (not started); followed by the steps where it went on
    #: with a fresh episode stream, if it did (`RunDir.read_outcome`'s fresh_streams), and
    #: where it went on on another machine, if it did (its machines).
    state: str
    steps: int
    budget: int
    steps_per_s: float | None
    success_rate: float | None


def cell_status(cell: Cell, root: pathlib.Path, failed: bool = False,
                running: bool = False, queued: bool = False) -> CellStatus:
    run = RunDir(root / cell.name)
    rows = read_eval_rows(run.eval_csv)
    steps = rows[-1]["steps"] if rows else 0
    rate = None
    if len(rows) >= 2 and rows[-1]["wall_time_s"] > rows[-2]["wall_time_s"]:
        rate = ((rows[-1]["steps"] - rows[-2]["steps"])
                / (rows[-1]["wall_time_s"] - rows[-2]["wall_time_s"]))
    if cell_finished(run, cell):
        outcome = run.read_outcome()
        state = "stopped early" if outcome["stopped_early"] else "done"
        fresh, machines = outcome.get("fresh_streams"), outcome.get("machines")
    else:
        running = running or run.trainer() is not None  # Also another sweep's, or a train.
        state = ("failed" if failed else "running" if running else "queued" if queued
                 else "unfinished" if run.config_path.exists() else "waiting")
        state_file = run.read_state()
        fresh, machines = state_file.get("fresh_streams"), state_file.get("machines")
    if fresh:  # Not the run an uninterrupted one would be, from there: said where it shows.
        state += f" (fresh episode stream from {', '.join(f'{s:,}' for s in fresh)})"
    if machines and len(machines) > 1:  # Its course from there is that machine's.
        began = ", ".join(f"{stretch['from_steps']:,}" for stretch in machines[1:])
        state += f" (another machine from {began})"
    return CellStatus(cell.name, state, steps, cell.steps, rate,
                      rows[-1]["success_rate"] if rows else None)


def status_table(statuses: list[CellStatus]) -> str:
    """The live table: one row per cell."""
    lines = ["| cell | state | steps | budget | steps/s | latest success |",
             "|---|---|---|---|---|---|"]
    for s in statuses:
        rate = "–" if s.steps_per_s is None else f"{s.steps_per_s:.1f}"
        success = "–" if s.success_rate is None else f"{100 * s.success_rate:.0f} %"
        lines.append(f"| {s.name} | {s.state} | {s.steps:,} | {s.budget:,} | {rate} | "
                     f"{success} |")
    return "\n".join(lines)


#: Seconds to wait for a Ray cluster's head to accept a connection.
RAY_CONNECT_TIMEOUT_S = 5.0


def check_ray_address(address: str) -> None:
    """A ValueError unless something answers at a HOST:PORT (or ray://HOST:PORT) address:
    Ray itself retries an unreachable head for minutes. "auto" and "local" are Ray's to
    find."""
    if address in ("auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    host = host.removeprefix("[").removesuffix("]")  # An IPv6 address: [::1]:6379.
    if not host or not port.isdigit():
        raise ValueError(f"--address {address!r} is not HOST:PORT, ray://HOST:PORT, auto or "
                         "local")
    try:
        socket.create_connection((host, int(port)), timeout=RAY_CONNECT_TIMEOUT_S).close()
    except OSError as error:
        raise ValueError(f"no Ray cluster answers at --address {address} ({error}): start "
                         "one there (`ray start --head`), or leave --address out for a "
                         "local Ray") from None


def run_sweep(cells: list[Cell], root: pathlib.Path, train_args: tuple[str, ...] = (), *,
              address: str | None = None, num_cpus: int | None = None,
              refresh_s: float = 30.0, show=print) -> list[CellStatus]:
    """Runs every unfinished cell as a Ray task of one CPU; shows the table every
    `refresh_s` seconds and at the end; returns the final statuses. SIGTERM or SIGINT (also
    in the background) stops it as Ctrl-C does: each running cell checkpoints first, however
    long that takes, and a second signal stops them at once; `SweepStopped` says which cells
    ended without a checkpoint."""
    import ray

    twice = repeated([cell.name for cell in cells])
    if twice:
        raise ValueError(f"a sweep's cells must differ: {', '.join(twice)} repeat")
    if address is not None:
        check_ray_address(address)
    todo = [cell for cell in cells if not cell_finished(RunDir(root / cell.name), cell)]
    for cell in todo:  # Before anything starts (a cell's task found it, and the sweep ended).
        trainer = RunDir(root / cell.name).trainer()
        if trainer is not None:
            raise ValueError(f"{root / cell.name} is being trained by {trainer}: let it end, "
                             "or stop it (SIGTERM checkpoints it) before the sweep resumes "
                             "it")
    failed: set[str] = set()
    if todo:
        started = not ray.is_initialized()
        pending: dict = {}
        # At a stop: what stopped it, and each running cell's checkpoint then
        # (`_checkpoint_link`).
        stop: KeyboardInterrupt | None = None
        stopped: dict[str, str | None] = {}
        submitted = time.time()
        try:
            # Signals stop it from here, Ray's start included: a stop while Ray starts
            # shuts down what it started (it left Ray's agents running, and no message).
            with interrupt_on(signal.SIGTERM, signal.SIGINT):  # Stops with checkpoints.
                if started:
                    # A cluster of its own listens on loopback only: Ray's ports take no
                    # authentication, and a sweep on a laptop need not open them to its
                    # network.
                    local: dict[str, Any] = (
                        {} if address else dict(num_cpus=num_cpus, _node_ip_address="127.0.0.1"))
                    try:
                        ray.init(address=address, include_dashboard=False,
                                 log_to_driver=False, **local)
                    except (OSError, ValueError):
                        raise  # Said in one line already ("no running Ray instance").
                    except Exception as error:  # Ray's bare Exception: a traceback.
                        raise RayStartError(address, error) from error
                # Ray's start put its own SIGTERM handler in (it exits): the sweep's again.
                with interrupt_on(signal.SIGTERM, signal.SIGINT):
                    root.mkdir(parents=True, exist_ok=True)  # Once Ray is there: none, no folder.
                    remote = ray.remote(num_cpus=1, max_retries=0)(run_cell)
                    pending = {remote.remote(cell, root, tuple(train_args)): cell
                               for cell in todo}
                    _wait_for_cells(pending, cells, root, failed, submitted, refresh_s, show)
        except BaseException as error:
            running = [cell for cell in pending.values()
                       if _started_since(cell, root, submitted)]
            if isinstance(error, KeyboardInterrupt):
                stop = error
                stopped = {cell.name: _checkpoint_link(root / cell.name) for cell in running}
            for ref in pending:
                ray.cancel(ref)  # KeyboardInterrupt in the task: its run checkpoints.
            if running:
                show("stopping: each running cell saves a checkpoint at its episode's end "
                     "(a second Ctrl-C or SIGTERM stops them at once, without one)")
            _wait_for_stopped_cells(list(pending))
            if stop is None:
                raise
        finally:
            if started:
                ray.shutdown()
        if stop is not None:
            raise SweepStopped(stop, list(stopped),
                               _stopped_without_a_checkpoint(stopped, root))
    statuses = [cell_status(cell, root, cell.name in failed) for cell in cells]
    show(status_table(statuses))
    return statuses


class RayStartError(OSError):
    """Ray could not start or join its cluster, for a reason only its logs hold (its own
    `Exception`: a raylet that could not map its object store, ~30 % of the machine's memory
    by default, under a memory limit; a full /tmp or /dev/shm)."""

    def __init__(self, address: str | None, error: Exception) -> None:
        what = (f"join the Ray cluster at {address}" if address
                else "start a local Ray cluster")
        reason = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
        super().__init__(
            f"the sweep could not {what}: {reason} Ray's logs say why "
            "(/tmp/ray/session_latest/logs/raylet.err): an object store larger than the "
            "memory this process may map (RAY_DEFAULT_OBJECT_STORE_MEMORY_PROPORTION=0.05 "
            "asks for 5 % of the machine's memory), or a full /tmp or /dev/shm")


class SweepStopped(KeyboardInterrupt):
    """A sweep stopped by Ctrl-C or a signal (`stop`, whose signal it names: the sweep's
    exit status, `exit_status`): `running`, the cells that were training; `unsaved`, those
    of them that wrote no checkpoint at the stop (a second signal stops them at once; a run
    that failed meanwhile), each with where it resumes from."""

    def __init__(self, stop: KeyboardInterrupt, running: list[str],
                 unsaved: dict[str, str]) -> None:
        super().__init__(*stop.args)
        self.running, self.unsaved = running, unsaved


def _wait_for_stopped_cells(refs: list) -> None:
    """Waits for the cancelled cells' tasks to end, each after its run has checkpointed at
    its episode's end (however long that takes: a 1e6-step replay buffer is written in
    minutes on a loaded machine; a minute's limit killed such a run before it had saved
    it); a second Ctrl-C or SIGTERM ends the wait, and the shutdown then stops them."""
    import ray

    try:
        with interrupt_on(signal.SIGTERM, signal.SIGINT):
            while refs:
                _, refs = ray.wait(refs, num_returns=len(refs), timeout=1.0)
    except KeyboardInterrupt:
        pass


def _checkpoint_link(root: pathlib.Path) -> str | None:
    """Which folder the run's checkpoint link names (each checkpoint is a new one), None
    where there is none; never an error (read in a stop, before the cells are stopped)."""
    try:
        return os.readlink(RunDir(root).checkpoint)
    except OSError:
        return None


def _stopped_without_a_checkpoint(stopped: dict[str, str | None],
                                  root: pathlib.Path) -> dict[str, str]:
    """Of the cells running at a stop (`stopped`: each one's checkpoint then), those that
    wrote none since and have not finished, each with where it resumes from, once their
    train processes have let go of their runs (stopped at once, they do within seconds; a
    further signal ends the wait)."""
    deadline = time.monotonic() + 60
    try:
        while (any(_trainer(root / name) for name in stopped)
               and time.monotonic() < deadline):
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    unsaved = {}
    for name, link in stopped.items():
        run = RunDir(root / name)
        try:
            if _checkpoint_link(run.root) != link or run.read_outcome():
                continue
            state = run.read_state()
        except (ValueError, OSError) as error:
            unsaved[name] = f"its checkpoint cannot be read: {error}"
            continue
        unsaved[name] = (f"resumes from its checkpoint at step {state['steps']:,}" if state
                         else "resumes from zero: it had none")
    return unsaved


def _trainer(root: pathlib.Path) -> str | None:
    try:
        return RunDir(root).trainer()
    except OSError:
        return None


def _wait_for_cells(pending: dict, cells: list[Cell], root: pathlib.Path, failed: set[str],
                    submitted: float, refresh_s: float, show) -> None:
    """Collects the cells' tasks as they end, showing the table every `refresh_s` seconds."""
    import ray

    last = 0.0
    while pending:
        done, _ = ray.wait(list(pending), timeout=1.0)
        for ref in done:
            name, code = ray.get(ref)
            if code != 0:
                failed.add(name)
            del pending[ref]
        if time.monotonic() - last >= refresh_s and pending:
            queued = {cell.name for cell in pending.values()}
            running = {cell.name for cell in pending.values()
                       if _started_since(cell, root, submitted)}
            show(status_table([cell_status(c, root, c.name in failed, c.name in running,
                                           c.name in queued) for c in cells]))
            last = time.monotonic()


def run_directories(paths) -> list[pathlib.Path]:
    """Run directories from paths that are runs or sweeps (directories of runs). Each seed
    of a cell once: the same run given twice (a sweep and one of its runs, or a copy kept
    elsewhere) would count as two seeds."""
    runs = []
    for path in map(pathlib.Path, paths):
        if RunDir(path).config_path.is_file():
            runs.append(path)
            continue
        if not path.exists():
            raise ValueError(f"{path} does not exist")
        inside = sorted(p.parent for p in path.glob("*/config.json"))
        # Sweeps a level further down (a folder of sweeps, `results/`) are not read: named,
        # not passed over (a report of `results/` read its six runs alone, without a word).
        below = sorted({p.parent.parent for p in path.glob("*/*/config.json")} - set(inside))
        sweeps = ", ".join(str(sweep) for sweep in below[:3]) + (
            f" and {len(below) - 3} more" if len(below) > 3 else "")
        if not inside and below:
            raise ValueError(f"{path} is neither a training run nor a sweep of runs: it holds "
                             f"{counted(len(below), 'sweep')} ({sweeps}): give a sweep "
                             "itself")
        if not inside:
            raise ValueError(f"{path} is neither a training run nor a sweep of runs "
                             "(no config.json in it or in its subdirectories)")
        if below:
            warnings.warn(f"{path}: its runs alone are read, not those of the "
                          f"{counted(len(below), 'sweep')} in it ({sweeps}): give a sweep "
                          "itself to read its runs", stacklevel=2)
        runs += inside
    seen: dict[tuple, pathlib.Path] = {}
    for run in runs:
        config = RunDir(run).read_config()
        seed = (config.task, config.variant, config.algo, config.seed)
        if seed in seen:
            raise ValueError(
                f"{seen[seed]} and {run} are both seed {config.seed} of "
                f"{with_variant(f'{config.task} {config.algo.upper()}', config.variant)}: "
                "give each run once (a cell's seeds are different runs)")
        seen[seed] = run
    return runs


def split_evaluated(runs) -> tuple[list[pathlib.Path], list[pathlib.Path]]:
    """`runs` split into those with evaluations and those with none yet (a sweep under way
    has cells not begun, or begun and not yet evaluated); none with any is a ValueError
    naming them. A damaged eval.csv is a ValueError too, not a run waiting, and so is one
    that does not fit the run's end (`RunDir.recorded_evaluations`)."""
    evaluated: list[pathlib.Path] = []
    waiting: list[pathlib.Path] = []
    for run in runs:
        (evaluated if RunDir(run).recorded_evaluations() else waiting).append(run)
    if not evaluated:
        raise ValueError(f"no evaluations yet in {', '.join(map(str, waiting))}")
    return evaluated, waiting
