"""A training run on disk: what it was asked to do, its evaluations and its checkpoints.

    RUN_DIR/config.json          task, algorithm, seed, backend, options, hyperparameters
                                 (`run_config.RunConfig`)
    RUN_DIR/eval.csv             one row per evaluation (appended across resumes)
    RUN_DIR/expert-demos.npz     the demonstrations its expert recorded at its start, if asked
    RUN_DIR/model.zip            the final model (written when training completes)
    RUN_DIR/policy.pt            its actor alone, what `keep` copies and a repository commits
    RUN_DIR/outcome.json         how it ended: steps, and whether it stopped early (none
                                 while a resume with a raised budget trains)
    RUN_DIR/evaluations.npz      SB3's per-episode log of this session's evaluations
    RUN_DIR/training.lock        held (flock) by the process training the run
    RUN_DIR/tensorboard/         TensorBoard's logs, where the tensorboard package is installed
    RUN_DIR/checkpoint           the latest complete checkpoint: a link to
                                 checkpoint-STEPS-*/ (model.zip, replay_buffer.pkl,
                                 generators.pkl, state.json), switched to a new one in one
                                 step once it is written whole (a folder in runs from before)
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import math
import os
import pathlib
import shutil
import socket
import time
import uuid
import warnings
from typing import Iterator, TypedDict

from franka_composer.atomic_files import replace_atomically, sync_to_disk
from franka_composer.training.run_config import RunConfig
from franka_composer.training.run_files import (checked_model, model_damage, read_json,
                                                  saved_steps, steps_of)

#: Steps between checkpoints of a new run (model and replay buffer: hundreds of MB each);
#: state.json records a run's own, which a resume keeps.
DEFAULT_CHECKPOINT_EVERY = 50_000
#: The `train` options (argparse dests) a --resume may change; every other option describes
#: the run, which keeps its own (its config.json).
RESUME_OPTIONS = ("total_steps", "device", "checkpoint_every", "threads", "progress")


class EvalRow(TypedDict):
    """An eval.csv row as `read_eval_rows` reads it: steps as an int, the rest floats."""

    steps: int
    wall_time_s: float
    success_rate: float
    mean_reward: float


#: eval.csv's columns, in its order.
EVAL_COLUMNS = tuple(EvalRow.__annotations__)


@dataclasses.dataclass(frozen=True)
class RunDir:
    """Paths inside one run directory."""

    root: pathlib.Path

    @property
    def config_path(self) -> pathlib.Path:
        return self.root / "config.json"

    @property
    def eval_csv(self) -> pathlib.Path:
        return self.root / "eval.csv"

    @property
    def outcome_path(self) -> pathlib.Path:
        return self.root / "outcome.json"

    @property
    def evaluations_npz(self) -> pathlib.Path:
        """SB3's `EvalCallback` log, written where the run's evaluations go (`log_path`)."""
        return self.root / "evaluations.npz"

    def read_outcome(self) -> dict:
        """{"steps", "stopped_early", "wall_time_s", "cpu_time_s", "fresh_streams",
        "machines"} of a finished run (CPU time None or absent where it was not recorded
        throughout; fresh_streams, the steps at which a resume went on with a fresh episode
        stream, None or absent for runs begun before it was recorded; machines, each machine
        it trained on from the step it began there (`machine.fingerprint`), absent for runs
        that ended before it was recorded, its first from a later step than 0 for runs
        resumed then); {} before it ends."""
        if not self.outcome_path.is_file():
            return {}
        outcome = read_json(self.outcome_path, "a run's outcome")
        if not (isinstance(outcome.get("steps"), int) and outcome["steps"] >= 0
                and isinstance(outcome.get("stopped_early"), bool)):
            raise ValueError(f"{self.outcome_path} is not a run's outcome: it needs a whole "
                             "number of steps, 0 or more, and stopped_early true or false")
        for name in ("wall_time_s", "cpu_time_s"):  # (CPU time: None where not recorded.)
            seconds = outcome.get(name)
            if seconds is not None and not _is_seconds(seconds):
                raise ValueError(f"{self.outcome_path} is not a run's outcome: its {name} "
                                 f"must be a number of seconds, 0 or more, got {seconds!r}")
        return outcome

    def write_outcome(self, steps: int, stopped_early: bool, wall_time_s: float,
                      cpu_time_s: float | None = None,
                      fresh_streams: list[int] | None = None,
                      machines: list[dict] | None = None) -> None:
        replace_atomically(self.outcome_path, lambda path: path.write_text(json.dumps(
            {"steps": steps, "stopped_early": stopped_early,
             "wall_time_s": round(wall_time_s, 2),
             "cpu_time_s": None if cpu_time_s is None else round(cpu_time_s, 2),
             "fresh_streams": fresh_streams, "machines": machines}) + "\n"))

    @property
    def expert_demos(self) -> pathlib.Path:
        """The episodes its expert recorded at its start (`RunConfig.expert_demos`)."""
        return self.root / "expert-demos.npz"

    @property
    def final_model(self) -> pathlib.Path:
        return self.root / "model.zip"

    @property
    def policy_file(self) -> pathlib.Path:
        """The final model's actor alone (`policy_file.save_policy`): what is committed."""
        return self.root / "policy.pt"

    @property
    def checkpoint(self) -> pathlib.Path:
        """The latest complete checkpoint (`publish_checkpoint`)."""
        return self.root / "checkpoint"

    @contextlib.contextmanager
    def training_lock(self):
        """Held while a process trains this run, and let go when it ends however it ends
        (an flock): a second process would write the same checkpoints and eval.csv, so it
        is refused, naming the first. Where there is no fcntl (Windows), nothing is held."""
        try:
            import fcntl
        except ImportError:
            yield
            return
        self.root.mkdir(parents=True, exist_ok=True)
        if self.lock_path.is_dir():  # Else open's IsADirectoryError, naming nothing of it.
            raise ValueError(f"{self.lock_path} is a folder, where the run keeps its lock "
                             "file (made by hand?): remove it to train the run")
        with open(self.lock_path, "a+") as handle:
            try:
                _take_lock(handle)
            except BlockingIOError:
                raise ValueError(f"{self.root} is being trained by {_holder(handle)}: let it "
                                 "end, or stop it (SIGTERM checkpoints it) before resuming"
                                 ) from None
            except OSError as error:  # A file system without locks (some network ones).
                warnings.warn(f"{self.root}: no lock against a second trainer ({error})",
                              RuntimeWarning, stacklevel=3)
            handle.seek(0)
            handle.truncate()
            handle.write(f"process {os.getpid()} on {socket.gethostname()}\n")
            handle.flush()
            yield

    @property
    def lock_path(self) -> pathlib.Path:
        return self.root / "training.lock"

    def holds(self, path: pathlib.Path) -> bool:
        """Whether `path` is one of the run's own files (or inside its checkpoints or its
        TensorBoard folder): what a command writing elsewhere must not write over."""
        path, root = pathlib.Path(path).resolve(), self.root.resolve()
        if path.parent != root and root not in path.parents:
            return False
        top = path.relative_to(root).parts[0]
        own = {p.name for p in (self.config_path, self.eval_csv, self.outcome_path,
                                self.evaluations_npz, self.expert_demos, self.final_model,
                                self.policy_file, self.lock_path, self.checkpoint,
                                self.tensorboard)}
        return top in own or top.startswith(f"{self.checkpoint.name}-")

    def trainer(self) -> str | None:
        """Who is training this run now ("process PID on HOST"), or None: `training_lock`
        tried in passing (shared, not waited for, let go at once; a trainer taking it
        meanwhile waits that moment out)."""
        try:
            import fcntl
        except ImportError:
            return None
        try:
            with open(self.lock_path) as handle:
                try:
                    fcntl.flock(handle, fcntl.LOCK_SH | fcntl.LOCK_NB)
                except BlockingIOError:
                    return _holder(handle)
                except OSError:  # No locks on this file system: nothing to tell.
                    return None
                fcntl.flock(handle, fcntl.LOCK_UN)
        except (FileNotFoundError, IsADirectoryError):  # No trainer could hold either.
            pass
        return None

    def new_checkpoint(self, steps: int) -> pathlib.Path:
        """A new folder, beside the latest checkpoint, to write the one at `steps` into
        before `publish_checkpoint`; the latest stays whole until then, so a run stopped
        while writing (killed, out of memory, a lost machine) resumes from it."""
        self.recover_checkpoint()
        self._remove_unpublished_checkpoints()
        path = self._unused_checkpoint_name(steps)
        path.mkdir()
        return path

    def publish_checkpoint(self, written: pathlib.Path) -> None:
        """Makes `written` (from `new_checkpoint`) the latest checkpoint in one atomic step
        (a link replaced by rename), then removes the one it replaces. Its files are on the
        disk first, and the link before the old one goes: a machine that crashes in between
        comes back with one whole checkpoint, not an empty new one and no old one."""
        for path in written.iterdir():
            sync_to_disk(path)
        sync_to_disk(written)
        link = self.root / "checkpoint.next"
        link.unlink(missing_ok=True)
        link.symlink_to(written.name)
        if self.checkpoint.is_dir() and not self.checkpoint.is_symlink():  # A run from before.
            self.checkpoint.rename(self._unused_checkpoint_name(0))
        os.replace(link, self.checkpoint)
        sync_to_disk(self.root)
        self._remove_unpublished_checkpoints()

    def recover_checkpoint(self) -> None:
        """Where a run stopped between moving a checkpoint folder of a run from before
        aside and linking its successor, links the newest complete one again."""
        if self.checkpoint.exists():
            return
        complete = self._complete_checkpoints()
        if complete:
            newest = max(complete, key=complete.__getitem__)
            self.checkpoint.unlink(missing_ok=True)  # A link to nothing.
            self.checkpoint.symlink_to(newest.name)

    def _complete_checkpoints(self) -> dict[pathlib.Path, int]:
        """The checkpoint folders whose state was written, with their steps."""
        steps = {path: steps_of(path / "state.json") for path in self.root.glob("checkpoint-*")}
        return {path: count for path, count in steps.items() if count is not None}

    def _unused_checkpoint_name(self, steps: int) -> pathlib.Path:
        return self.root / f"checkpoint-{steps}-{uuid.uuid4().hex[:8]}"

    def _remove_unpublished_checkpoints(self) -> None:
        latest = self.checkpoint.resolve() if self.checkpoint.exists() else None
        for path in self.root.glob("checkpoint-*"):
            if path.resolve() != latest:
                shutil.rmtree(path)

    @property
    def checkpoint_model(self) -> pathlib.Path:
        return self.checkpoint / "model.zip"

    @property
    def checkpoint_buffer(self) -> pathlib.Path:
        return self.checkpoint / "replay_buffer.pkl"

    @property
    def checkpoint_generators(self) -> pathlib.Path:
        """The random generators' states and the episode stream (`exact_resume`)."""
        return self.checkpoint / "generators.pkl"

    @property
    def checkpoint_state(self) -> pathlib.Path:
        return self.checkpoint / "state.json"

    @property
    def tensorboard(self) -> pathlib.Path:
        return self.root / "tensorboard"

    def read_config(self) -> RunConfig:
        if not self.root.exists():
            raise ValueError(f"{self.root} does not exist")
        if not self.config_path.is_file():
            raise ValueError(f"{self.root} is not a training run (no config.json)")
        recorded = read_json(self.config_path, "a run's config")
        try:
            return RunConfig.from_dict(recorded)
        except KeyError as error:
            raise ValueError(f"{self.config_path} is not a run's config: it has no "
                             f"{error}") from None
        except (TypeError, ValueError) as error:
            raise ValueError(f"{self.config_path} is not a run's config: {error}") from None

    def write_config(self, config: RunConfig) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        replace_atomically(self.config_path, lambda path: path.write_text(
            json.dumps(config.to_dict(), indent=2) + "\n"))

    def check_resumable(self) -> None:
        """Refuses (ValueError) to resume a run with no complete checkpoint (counting one a
        stop left unlinked, which `recover_checkpoint` links; a finished run's kept copy is
        named as one, not as a run to delete), without its eval.csv, or whose config.json was
        edited since its checkpoint (`check_config_checkpointed`)."""
        recoverable = not self.checkpoint.exists() and self._complete_checkpoints()
        if not self.checkpoint_state.is_file() and not recoverable:
            if self.checkpoint.is_symlink() and not self.checkpoint.exists():
                # It had one ("delete it to start again" would have lost a finished model).
                raise ValueError(f"{self.checkpoint} links to {os.readlink(self.checkpoint)}, "
                                 "which is missing (removed?): put it back to resume; the "
                                 "run's other files are as they were")
            trainer = self.trainer()
            if trainer is not None:  # Not stopped: training, before its first checkpoint.
                raise ValueError(f"{self.root} is being trained by {trainer} (no checkpoint "
                                 "yet): let it end, or stop it (SIGTERM checkpoints it) "
                                 "before resuming")
            if self.is_kept_copy():
                kept = ("its policy.pt kept" if self.policy_file.is_file() else
                        "its outcome.json kept, no policy.pt")
                raise ValueError(f"{self.root} is a kept copy of a finished run ({kept}, no "
                                 "checkpoint to resume from): resume the run it was kept "
                                 "from, or start a new one")
            raise ValueError(f"{self.root} has no complete checkpoint to resume from "
                             "(it stopped before its first one): delete it to start again")
        if not self.eval_csv.is_file():
            raise ValueError(f"{self.eval_csv} is missing: the run's evaluations up to its "
                             "checkpoint would be lost; put it back to resume")
        self.check_config_checkpointed()
        self.check_checkpoint_whole()

    def holds_other_things(self) -> bool:
        """Whether its folder holds files but no run (no config.json, which a run writes
        first): nothing a run may be begun over, nor removed as one stopped early."""
        return (self.root.is_dir() and not self.config_path.exists()
                and any(self.root.iterdir()))

    def is_kept_copy(self) -> bool:
        """Whether this is what `keep` copies of a finished run: its outcome.json, with
        no model.zip or checkpoint to train on from (its policy.pt, where it was kept)."""
        return (not self.final_model.is_file() and not self.checkpoint.exists()
                and not self._complete_checkpoints() and bool(self.read_outcome()))

    def check_checkpoint_whole(self) -> None:
        """Refuses (ValueError) to resume from a checkpoint whose state.json has no
        wall-clock time or says other steps than its model was saved at, or whose run's
        eval.csv lacks an evaluation the checkpoint's steps passed (every eval_every steps
        from 0; the one at the checkpoint's own step may be missing, cut short by a second
        stop signal, and is made as the run resumes): the resumed run's evaluation episodes
        follow the count of evaluations kept, and went on shifted, its curve with a gap."""
        state = self.read_state()
        if not state:
            return
        if "wall_time_s" not in state:  # Every checkpoint `train` writes records it.
            raise ValueError(f"{self.checkpoint_state} is not a checkpoint's state (edited or "
                             "damaged?): it has no wall_time_s")
        steps = state["steps"]
        saved = saved_steps(self.checkpoint_model) if self.checkpoint_model.is_file() else None
        if saved is not None and saved != steps:
            raise ValueError(f"{self.checkpoint_state} says {steps:,} steps, and the model "
                             f"beside it was saved at step {saved:,}: edited, or another "
                             "checkpoint's?")
        if not self.eval_csv.is_file():
            return  # `check_resumable` names it.
        every = self.read_config().hyperparameters.eval_every
        expected = range(0, steps + 1, every)
        kept = [row["steps"] for row in self.kept_evaluations() if row["steps"] % every == 0]
        if kept in (list(expected), list(expected[:-1]) if expected[-1] == steps else None):
            return
        missing = [step for step in expected if step not in kept]
        raise ValueError(
            f"{self.eval_csv} lacks the evaluation{'s' if len(missing) > 1 else ''} at step"
            f"{'s' if len(missing) > 1 else ''} {', '.join(f'{step:,}' for step in missing)} "
            f"(one every {every:,} steps from 0 to the checkpoint's {steps:,}): the resumed "
            "run's evaluations would go on with other episodes than the run's, and its curve "
            "with a gap; put them back (edited or cut?), or start the run again")

    def check_config_checkpointed(self) -> None:
        """Refuses (ValueError) to resume a run whose config.json says other than the
        settings its checkpoint was trained with (a hand edit: the checkpoint's networks,
        buffer and env would not fit them, or the run would go on as another while its files
        say one), naming what differs; the step budget may differ (--total-steps raises
        it). A checkpoint written before it recorded the settings is not checked."""
        state = self.read_state()
        recorded = state.get("config")
        if recorded is None:
            return
        try:
            trained = RunConfig.from_dict(recorded)
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"{self.checkpoint_state}'s config is not a run's config "
                             f"(damaged?): {error!r}") from None
        differences = self.read_config().differences(trained)
        if differences:
            raise ValueError(f"{self.config_path} says other than the settings the run's "
                             f"checkpoint at step {state['steps']:,} was trained "
                             f"with ({'; '.join(differences)}): a run goes on with its own; "
                             "put them back, or start a new run with the new ones")

    def read_state(self) -> dict:
        """The latest checkpoint's {"steps", "wall_time_s", "cpu_time_s", "checkpoint_every",
        "exact", "threads", "fresh_streams", "machines", "config", "sha256"} (no CPU time in
        checkpoints written before it was recorded, no "exact" or "threads" in those written
        before resumes could be exact, no "fresh_streams", "machines", "config" or "sha256"
        in those written before each was recorded); {} without a checkpoint."""
        if not self.checkpoint_state.is_file():
            return {}
        state = read_json(self.checkpoint_state, "a checkpoint's state")
        problem = _state_problem(state)
        if problem is not None:
            raise ValueError(f"{self.checkpoint_state} is not a checkpoint's state (edited or "
                             f"damaged?): {problem}")
        return state

    def recorded_evaluations(self) -> list[EvalRow]:
        """eval.csv's rows (`read_eval_rows`: [] before the first), checked against the
        run's end where it has ended (outcome.json): none at all (its eval.csv lost or
        emptied), one past its last step (edited, or another run's: `keep` copied it, and
        `report` counted it), or none at its last step, where an ended run evaluates last
        (cut short: `report` read the curve as ending there, and `plot` drew it so), is a
        ValueError naming the file."""
        rows = read_eval_rows(self.eval_csv)
        outcome = self.read_outcome()
        if not outcome:
            return rows
        if not rows:
            raise ValueError(f"{self.root} has ended and has no evaluations (its eval.csv lost "
                             "or emptied?)")
        for line, row in enumerate(rows, start=2):
            if row["steps"] > outcome["steps"]:
                raise ValueError(
                    f"{self.eval_csv}, line {line}: an evaluation at step {row['steps']:,}, "
                    f"past the run's end at step {outcome['steps']:,} "
                    f"({self.outcome_path.name}): edited, or another run's?")
        if rows[-1]["steps"] != outcome["steps"]:
            raise ValueError(
                f"{self.eval_csv} ends at step {rows[-1]['steps']:,}, and the run ended at "
                f"step {outcome['steps']:,} ({self.outcome_path.name}), where it evaluated "
                "last: cut short, or another run's?")
        return rows

    def evaluations(self) -> list[EvalRow]:
        """eval.csv's rows (`recorded_evaluations`); a run with no evaluations yet is a
        ValueError."""
        rows = self.recorded_evaluations()
        if not rows:
            raise ValueError(f"{self.root} has no evaluations yet (no eval.csv rows)")
        return rows

    def kept_evaluations(self) -> list[EvalRow]:
        """eval.csv's rows that a resume keeps: of a run stopped between checkpoints, those
        up to its checkpoint (the steps after it are redone, their evaluations with them);
        all of a run that has ended (`recorded_evaluations`)."""
        rows = self.recorded_evaluations()
        state = self.read_state()
        if state and not self.read_outcome():
            rows = [row for row in rows if row["steps"] <= state["steps"]]
        return rows

    def best_model(self) -> pathlib.Path:
        """The final model, else the latest checkpoint (a run that was interrupted, or whose
        model.zip is damaged: the checkpoint written at the end of training is the same
        model, and a warning says which file was passed over)."""
        if self.final_model.is_file():
            damage = model_damage(self.final_model)
            if damage is None:
                return self.final_model
            if not self.checkpoint_model.is_file():
                raise ValueError(f"{self.final_model} is damaged ({damage}), and the run has "
                                 "no checkpoint to use instead")
            warnings.warn(f"{self.final_model} is damaged ({damage}): using the latest "
                          f"checkpoint, {self.checkpoint_model}", RuntimeWarning, stacklevel=2)
        if self.checkpoint_model.is_file():
            return checked_model(self.checkpoint_model)
        raise ValueError(f"{self.root} has no model yet (neither model.zip nor a checkpoint)")


def _is_seconds(value) -> bool:
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and value >= 0)


def _is_count(value, least: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= least


def _state_problem(state: dict) -> str | None:
    """What is wrong with a checkpoint's state (`RunDir.read_state`'s keys), or None."""
    if not _is_count(state.get("steps"), 0):
        return f"its steps must be a whole number, 0 or more, got {state.get('steps')!r}"
    if "wall_time_s" in state and not _is_seconds(state["wall_time_s"]):
        return ("its wall_time_s must be a number of seconds, 0 or more, got "
                f"{state['wall_time_s']!r}")
    # CPU time: absent, or null after a resume from such a checkpoint, where not recorded.
    if state.get("cpu_time_s") is not None and not _is_seconds(state["cpu_time_s"]):
        return f"its cpu_time_s must be a number of seconds, 0 or more, got {state['cpu_time_s']!r}"
    for name in ("checkpoint_every", "threads"):
        if state.get(name) is not None and not _is_count(state[name], 1):
            return f"its {name} must be a whole number, 1 or more, got {state[name]!r}"
    if "exact" in state and not isinstance(state["exact"], bool):
        return f"its exact must be true or false, got {state['exact']!r}"
    fresh = state.get("fresh_streams")
    if fresh is not None and not (isinstance(fresh, list)
                                  and all(_is_count(step, 0) for step in fresh)):
        return f"its fresh_streams must be a list of steps, got {fresh!r}"
    machines = state.get("machines")
    if machines is not None and not (isinstance(machines, list) and all(
            isinstance(entry, dict) and _is_count(entry.get("from_steps"), 0)
            for entry in machines)):
        return ("its machines must be a list of objects, each with its from_steps, got "
                f"{machines!r}")
    if state.get("config") is not None and not isinstance(state["config"], dict):
        return f"its config must be an object, got {type(state['config']).__name__}"
    digests = state.get("sha256")
    if digests is not None and not (isinstance(digests, dict) and all(
            isinstance(name, str) and pathlib.Path(name).name == name
            and isinstance(digest, str) for name, digest in digests.items())):
        return f"its sha256 must map the checkpoint's file names to digests, got {digests!r}"
    return None


#: How long a trainer waits for a run's lock held by another: a look (`RunDir.trainer`)
#: holds it for microseconds; a trainer holds it for its whole run.
LOCK_WAIT_S = 1.0


def run_finished(run: RunDir, budget: int | None = None) -> bool:
    """Whether `run` has ended at `budget` steps (None: its own, config.json's total_steps),
    or before it by the stopping rule. Its config is read either way: a run whose
    config.json is damaged is named, not counted as finished."""
    outcome = run.read_outcome()
    if not outcome:
        return False
    config = run.read_config()
    if budget is None:
        budget = config.hyperparameters.total_steps
    return bool(outcome["stopped_early"] or outcome["steps"] >= budget)


def _take_lock(handle) -> None:
    """An exclusive flock, tried again for up to `LOCK_WAIT_S` while another holds it; then
    BlockingIOError."""
    import fcntl

    deadline = time.monotonic() + LOCK_WAIT_S
    while True:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() >= deadline:
                raise
            time.sleep(0.02)


def _holder(lock_file) -> str:
    """Who holds a run's lock, as its holder wrote it in the lock file."""
    lock_file.seek(0)
    return lock_file.read().strip() or "another process"


def success_curve(rows: list[EvalRow]) -> dict[int, float]:
    """{evaluated step: success rate} of eval.csv's rows."""
    return {row["steps"]: row["success_rate"] for row in rows}


def read_eval_rows(path: pathlib.Path) -> list[EvalRow]:
    """The rows of an eval.csv as floats (steps as int); [] when it does not exist. A row no
    run writes (steps not whole or not increasing, a wall time not finite and >= 0, a
    success rate outside [0, 1]) is a ValueError naming the file and its line."""
    if not path.is_file():
        return []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path} is not an eval.csv (damaged?): it is not UTF-8 text "
                         f"({error})") from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    if tuple(reader.fieldnames or ()) != EVAL_COLUMNS:
        raise ValueError(f"{path} is not an eval.csv: its columns are "
                         f"{', '.join(reader.fieldnames or ()) or 'none'}, not "
                         f"{', '.join(EVAL_COLUMNS)}")
    rows: list[EvalRow] = []
    for line, row in enumerate(reader, start=2):
        try:
            values = {name: float(value) for name, value in row.items()}
        except (TypeError, ValueError):
            raise ValueError(f"{path}, line {line}: expected numbers for "
                             f"{', '.join(EVAL_COLUMNS)}, got {row}") from None
        problem = _eval_row_problem(values, rows[-1]["steps"] if rows else None)
        if problem:
            raise ValueError(f"{path}, line {line}: {problem}")
        rows.append(EvalRow(steps=int(values["steps"]), wall_time_s=values["wall_time_s"],
                            success_rate=values["success_rate"],
                            mean_reward=values["mean_reward"]))
    return rows


def _eval_row_problem(row: dict[str, float], previous_steps: int | None) -> str | None:
    """What makes `row` (an eval.csv row's numbers) no evaluation a run writes, after the one
    at `previous_steps`; None if nothing does."""
    steps, wall_time, success_rate = row["steps"], row["wall_time_s"], row["success_rate"]
    if not (steps >= 0 and steps.is_integer()):
        return f"steps must be a whole number >= 0, got {steps}"
    if previous_steps is not None and steps <= previous_steps:
        return (f"steps must increase from row to row, got {steps:.0f} after "
                f"{previous_steps}")
    if not 0.0 <= wall_time < math.inf:
        return f"wall_time_s must be a finite number >= 0, got {wall_time}"
    if not 0.0 <= success_rate <= 1.0:
        return f"success_rate must be within [0, 1], got {success_rate}"
    if not math.isfinite(row["mean_reward"]):
        return f"mean_reward must be a finite number, got {row['mean_reward']}"
    return None


def write_eval_rows(path: pathlib.Path, rows: list[EvalRow]) -> None:
    """Rewrites an eval.csv with `rows` (used to drop rows past a checkpoint on resume),
    in one step."""
    def write(partial: pathlib.Path) -> None:
        with partial.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=EVAL_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)

    replace_atomically(path, write)


def append_eval_row(path: pathlib.Path, row: EvalRow) -> None:
    """Appends `row` to an eval.csv (with its header, where new) in one write, flushed to
    the disk: a run killed there leaves the rows it had, and this one whole or not at all."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=EVAL_COLUMNS)
    if not path.is_file():
        writer.writeheader()
    writer.writerow(row)
    with path.open("a", newline="") as f:
        f.write(text.getvalue())
        f.flush()
        os.fsync(f.fileno())


def check_out_apart(out: pathlib.Path | None, roots) -> None:
    """A ValueError where `out` (a command's --out) is one of the files of the runs at
    `roots`, or of any run it lies in: `evaluate RUN --out RUN/eval.csv` wrote its table
    over the run's evaluations, and `--out OTHER_RUN/config.json` over another run's
    config, which nothing could then read."""
    if out is None:
        return
    inside = list(runs_holding(out))
    for root in [*map(pathlib.Path, roots), *inside]:
        if RunDir(root).holds(out):
            raise ValueError(f"--out {out} is one of the run {root}'s own files: give "
                             "another file")


def check_not_inside_a_run(out: pathlib.Path) -> None:
    """A ValueError where a new run's folder `out` lies inside another run, whose next
    checkpoint (it replaces checkpoint-*/ folders) or `keep` would take it along."""
    folder = next(runs_holding(out), None)
    if folder is not None:
        raise ValueError(f"--out {out} is inside the run {folder}: give a folder outside it")


def runs_holding(path) -> Iterator[pathlib.Path]:
    """The runs `path` lies inside, nearest first (read lazily: each folder on the way is
    a config.json read)."""
    return (folder for folder in pathlib.Path(path).resolve().parents if is_run(folder))


def is_run(folder: pathlib.Path) -> bool:
    """Whether `folder` holds a run: a config.json that reads as a run's (a project's own
    config.json does not)."""
    try:
        RunDir(folder).read_config()  # No config.json at all is a ValueError too.
    except ValueError:
        return False
    return True
