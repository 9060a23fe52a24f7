"""A training run on disk: what it was asked to do, its evaluations and its checkpoints.

    RUN_DIR/config.json          task, algorithm, seed, backend, options, hyperparameters
    RUN_DIR/eval.csv             one row per evaluation (appended across resumes)
    RUN_DIR/model.zip            the final model (written when training completes)
    RUN_DIR/outcome.json         how it ended: steps, and whether it stopped early (none
                                 while a resume with a raised budget trains)
    RUN_DIR/evaluations.npz      SB3's per-episode log of this session's evaluations
    RUN_DIR/training.lock        held (flock) by the process training the run
    RUN_DIR/checkpoint           the latest complete checkpoint: a link to
                                 checkpoint-STEPS-*/ (model.zip, replay_buffer.pkl,
                                 generators.pkl, state.json), switched to a new one in one
                                 step once it is written whole (a folder in runs from before)
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import os
import pathlib
import shutil
import socket
import uuid
import warnings

from franka_composer.controllers import CONTROLS
from franka_composer.randomization import PRESETS
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.training.hyperparams import (ALGOS, BACKENDS, PRECISIONS,
                                                  Hyperparameters, hyperparameters)
from franka_composer.validation import check_choice

EVAL_COLUMNS = ("steps", "wall_time_s", "success_rate", "mean_reward")
#: Steps between checkpoints of a new run (model and replay buffer: hundreds of MB each);
#: state.json records a run's own, which a resume keeps.
DEFAULT_CHECKPOINT_EVERY = 50_000

#: Hyperparameters that leave what is learned alone: the budget, evaluation and stopping.
NOT_LEARNING = ("total_steps", "eval_every", "eval_episodes", "stop_success_rate",
                "stop_after_evaluations")


def variant_label(setup: str, computation: str) -> str:
    """A run's variant (`RunConfig.variant`) from its setup and computation labels."""
    return ", ".join(part for part in (setup, computation) if part)


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """What a run trains: enough to rebuild its model and environments on resume.

    `demos` is the dataset the replay buffer was filled from before learning (its first
    `demo_episodes` episodes, or all), or None.

    `backend` is one of `BACKENDS`: a checkpoint can only be loaded by the library that
    wrote it, so resume and evaluate read it from here. `precision` (one of `PRECISIONS`)
    is how the networks' passes are computed while training; the weights are fp32 either
    way, so evaluation and loading do not depend on it.
    """

    task: str
    algo: str
    seed: int
    hyperparameters: Hyperparameters
    terminate_on_success: bool = True
    backend: str = "sb3"
    control: str = "mocap"
    precision: str = "fp32"
    randomization: str | None = None
    demos: str | None = None
    demo_episodes: int | None = None

    def __post_init__(self) -> None:
        check_choice("task", self.task, tuple(TASK_CONFIGS))
        check_choice("algorithm", self.algo, ALGOS)
        check_choice("backend", self.backend, BACKENDS)
        check_choice("control", self.control, CONTROLS)
        check_choice("precision", self.precision, PRECISIONS)
        if self.randomization is not None:
            check_choice("randomization", self.randomization, tuple(PRESETS), also="None")
        if self.precision != "fp32" and self.backend != "sb3":
            raise ValueError(f"precision {self.precision} runs the networks under "
                             f"torch.autocast: it needs backend sb3, not {self.backend} "
                             "(which trains in JAX)")
        if self.hyperparameters.clip_q_targets and self.backend != "sb3":
            raise ValueError(f"clip_q_targets clamps a PyTorch target critic: it needs "
                             f"backend sb3, not {self.backend}")
        self._check_first_update()

    def _check_first_update(self) -> None:
        """HER samples from finished episodes only, and SB3 stops a run whose first gradient
        step comes before one has ended (after its directory is made). With an update
        every step, that step follows step `learning_starts` + 1, and the first episode may
        last its whole horizon."""
        hp = self.hyperparameters
        horizon = TASK_CONFIGS[self.task].max_episode_steps
        if hp.update_schedule == "step" and self.demos is None \
                and hp.learning_starts + 1 < horizon:
            raise ValueError(
                f"learning_starts must be >= {horizon - 1} for {self.task} with an update "
                f"every step, got {hp.learning_starts}: the first gradient step would come "
                f"before the first episode ends (it may last {horizon} steps), and HER "
                "samples from ended episodes only; or use update_schedule 'episode' or demos")

    def to_dict(self) -> dict:
        return {"task": self.task, "algo": self.algo, "seed": self.seed,
                "terminate_on_success": self.terminate_on_success, "backend": self.backend,
                "control": self.control, "precision": self.precision,
                "randomization": self.randomization, "demos": self.demos,
                "demo_episodes": self.demo_episodes,
                "hyperparameters": self.hyperparameters.to_dict()}

    @property
    def setup(self) -> str:
        """What this run learns that the paper's setup does not (Table I for its task and
        algorithm, mocap, terminating on success, nothing added), as a label; "" for none."""
        table_i = hyperparameters(self.task, self.algo).to_dict()
        parts = [f"{name} {','.join(map(str, value)) if isinstance(value, tuple) else value}"
                 for name, value in self.hyperparameters.to_dict().items()
                 if name not in NOT_LEARNING and value != table_i[name]]
        parts += [label for differs, label in (
            (self.control != "mocap", f"{self.control} control"),
            (self.randomization is not None, f"randomization {self.randomization}"),
            (self.demos is not None, f"demos {pathlib.Path(self.demos or '').name}"
             + (f"[:{self.demo_episodes}]" if self.demo_episodes else "")),
            (not self.terminate_on_success, "no termination on success")) if differs]
        return ", ".join(parts)

    @property
    def computation(self) -> str:
        """How its networks were computed, where not as the paper's (SB3, fp32): "bf16",
        "sbx" or ""."""
        return ", ".join(label for differs, label in (
            (self.precision != "fp32", self.precision),
            (self.backend != "sb3", self.backend)) if differs)

    @property
    def variant(self) -> str:
        """Its setup and computation: runs with different variants are not seeds of one
        cell (`evaluate`, `plot` and `report` keep them apart)."""
        return variant_label(self.setup, self.computation)

    def differing(self, other: "RunConfig") -> dict[str, tuple]:
        """What makes `other` a different run from this one: {setting: (ours, theirs)};
        the step budget is not among them (a run may go on to a larger one)."""
        def settings(config: RunConfig) -> dict:
            flat = {**config.to_dict(), **config.hyperparameters.to_dict()}
            del flat["hyperparameters"], flat["total_steps"]
            return flat
        ours, theirs = settings(self), settings(other)
        return {name: (ours[name], theirs[name]) for name in ours if ours[name] != theirs[name]}

    def differences(self, other: "RunConfig") -> list[str]:
        """`differing` as "name: ours, not theirs"."""
        return [f"{name}: {ours}, not {theirs}"
                for name, (ours, theirs) in self.differing(other).items()]

    @property
    def env_options(self) -> dict:
        """The options its environments are made with (`models.make_env`)."""
        return dict(terminate_on_success=self.terminate_on_success, control=self.control,
                    randomization=self.randomization)

    @classmethod
    def from_dict(cls, data: dict) -> "RunConfig":
        # Runs written before the JAX backend, the controllers, bf16 or randomisation existed
        # have no "backend", "control", "precision" or "randomization": they are SB3's,
        # mocap, fp32, not randomised.
        return cls(task=data["task"], algo=data["algo"], seed=int(data["seed"]),
                   terminate_on_success=bool(data["terminate_on_success"]),
                   backend=data.get("backend", "sb3"), control=data.get("control", "mocap"),
                   precision=data.get("precision", "fp32"),
                   randomization=data.get("randomization"), demos=data.get("demos"),
                   demo_episodes=data.get("demo_episodes"),
                   hyperparameters=Hyperparameters.from_dict(data["hyperparameters"]))


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

    def read_outcome(self) -> dict:
        """{"steps", "stopped_early", "wall_time_s", "cpu_time_s"} of a finished run (CPU
        time None or absent where it was not recorded throughout); {} before it ends."""
        if not self.outcome_path.is_file():
            return {}
        return json.loads(self.outcome_path.read_text())

    def write_outcome(self, steps: int, stopped_early: bool, wall_time_s: float,
                      cpu_time_s: float | None = None) -> None:
        self.outcome_path.write_text(json.dumps(
            {"steps": steps, "stopped_early": stopped_early,
             "wall_time_s": round(wall_time_s, 2),
             "cpu_time_s": None if cpu_time_s is None else round(cpu_time_s, 2)}) + "\n")

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
        with open(self.root / "training.lock", "a+") as handle:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                handle.seek(0)
                holder = handle.read().strip() or "another process"
                raise ValueError(f"{self.root} is being trained by {holder}: let it end, or "
                                 "stop it (SIGTERM checkpoints it) before resuming") from None
            except OSError as error:  # A file system without locks (some network ones).
                warnings.warn(f"{self.root}: no lock against a second trainer ({error})",
                              RuntimeWarning, stacklevel=3)
            handle.seek(0)
            handle.truncate()
            handle.write(f"process {os.getpid()} on {socket.gethostname()}\n")
            handle.flush()
            yield

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
        (a link replaced by rename), then removes the one it replaces."""
        link = self.root / "checkpoint.next"
        link.unlink(missing_ok=True)
        link.symlink_to(written.name)
        if self.checkpoint.is_dir() and not self.checkpoint.is_symlink():  # A run from before.
            self.checkpoint.rename(self._unused_checkpoint_name(0))
        os.replace(link, self.checkpoint)
        self._remove_unpublished_checkpoints()

    def recover_checkpoint(self) -> None:
        """Where a run stopped between moving a checkpoint folder of a run from before
        aside and linking its successor, links the newest complete one again."""
        if self.checkpoint.exists():
            return
        complete = [path for path in self.root.glob("checkpoint-*")
                    if (path / "state.json").is_file()]
        if complete:
            newest = max(complete, key=lambda p: json.loads((p / "state.json").read_text())[
                "steps"])
            self.checkpoint.unlink(missing_ok=True)  # A link to nothing.
            self.checkpoint.symlink_to(newest.name)

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
        if not self.config_path.is_file():
            raise ValueError(f"{self.root} is not a training run (no config.json)")
        try:
            return RunConfig.from_dict(json.loads(self.config_path.read_text()))
        except KeyError as error:
            raise ValueError(f"{self.config_path} is not a run's config: it has no "
                             f"{error}") from None
        except (TypeError, ValueError) as error:  # json's JSONDecodeError is a ValueError.
            raise ValueError(f"{self.config_path} is not a run's config: {error}") from None

    def write_config(self, config: RunConfig) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        self.config_path.write_text(json.dumps(config.to_dict(), indent=2) + "\n")

    def read_state(self) -> dict:
        """The latest checkpoint's {"steps", "wall_time_s", "cpu_time_s", "checkpoint_every",
        "exact", "threads"} (no CPU time in checkpoints written before it was recorded, no
        "exact" or "threads" in those written before resumes could be exact); {} without a
        checkpoint."""
        if not self.checkpoint_state.is_file():
            return {}
        return json.loads(self.checkpoint_state.read_text())

    def evaluations(self) -> list[dict[str, float]]:
        """eval.csv's rows; a run with no evaluations yet is a ValueError."""
        rows = read_eval_rows(self.eval_csv)
        if not rows:
            raise ValueError(f"{self.root} has no evaluations yet (no eval.csv rows)")
        return rows

    def kept_evaluations(self) -> list[dict[str, float]]:
        """eval.csv's rows that a resume keeps: of a run stopped between checkpoints, those
        up to its checkpoint (the steps after it are redone, their evaluations with them);
        all of a run that has ended."""
        rows = read_eval_rows(self.eval_csv)
        state = self.read_state()
        if state and not self.read_outcome():
            rows = [row for row in rows if row["steps"] <= state["steps"]]
        return rows

    def best_model(self) -> pathlib.Path:
        """The final model, else the latest checkpoint (a run that was interrupted)."""
        for path in (self.final_model, self.checkpoint_model):
            if path.is_file():
                return path
        raise ValueError(f"{self.root} has no model yet (neither model.zip nor a checkpoint)")


def success_curve(rows: list[dict[str, float]]) -> dict[int, float]:
    """{evaluated step: success rate} of eval.csv's rows."""
    return {row["steps"]: row["success_rate"] for row in rows}


def read_eval_rows(path: pathlib.Path) -> list[dict[str, float]]:
    """The rows of an eval.csv as floats (steps as int); [] when it does not exist."""
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        if tuple(reader.fieldnames or ()) != EVAL_COLUMNS:
            raise ValueError(f"{path} is not an eval.csv: its columns are "
                             f"{', '.join(reader.fieldnames or ()) or 'none'}, not "
                             f"{', '.join(EVAL_COLUMNS)}")
        rows = []
        for line, row in enumerate(reader, start=2):
            try:
                rows.append({k: (int(float(v)) if k == "steps" else float(v))
                             for k, v in row.items()})
            except (TypeError, ValueError):
                raise ValueError(f"{path}, line {line}: expected numbers for "
                                 f"{', '.join(EVAL_COLUMNS)}, got {row}") from None
        return rows


def write_eval_rows(path: pathlib.Path, rows: list[dict[str, float]]) -> None:
    """Rewrites an eval.csv with `rows` (used to drop rows past a checkpoint on resume)."""
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=EVAL_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)


def append_eval_row(path: pathlib.Path, row: dict[str, float]) -> None:
    new = not path.is_file()
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=EVAL_COLUMNS)
        if new:
            writer.writeheader()
        writer.writerow(row)
