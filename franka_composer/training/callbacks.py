"""What happens around SB3's `learn` loop, on SB3's own callbacks.

- `Evaluation` is SB3's `EvalCallback`, kept on the run's step grid across resumes and run
  at the first and last step as well; `RecordEvaluation`, its `callback_after_eval`,
  appends each evaluation to eval.csv (the whole run's record, across resumes) and stops
  training by the run's early-stopping rule.
- `LatestCheckpoint` is SB3's `CheckpointCallback` (model and replay buffer), keeping only
  the latest under fixed names, taken at episode ends with the generators' states so that
  `--resume` continues exactly (`exact_resume`), with a state file written last.
- The progress bar is SB3's (`learn(progress_bar=True)`).
"""

from __future__ import annotations

import json
import time
from typing import cast

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback

from franka_composer.signals import interrupt_message
from franka_composer.training import exact_resume
from franka_composer.training.exact_resume import EpisodeStream
from franka_composer.training.run_config import RunConfig
from franka_composer.training.run_files import file_digests
from franka_composer.training.runs import RunDir, append_eval_row, read_eval_rows


class WallClock:
    """Training seconds across resumes: the checkpoint's elapsed time plus this session's;
    called, wall-clock seconds; `cpu()`, the CPU seconds of the training processes (every
    thread: network passes, simulation, evaluations), what a run costs on a shared machine.
    """

    def __init__(self, elapsed_before: float = 0.0, cpu_before: float | None = 0.0) -> None:
        self._before, self._cpu_before = elapsed_before, cpu_before
        self._start, self._cpu_start = time.perf_counter(), time.process_time()

    def __call__(self) -> float:
        return self._before + time.perf_counter() - self._start

    def cpu(self) -> float | None:
        """None when the run resumed from a checkpoint that did not record CPU time."""
        if self._cpu_before is None:
            return None
        return self._cpu_before + time.process_time() - self._cpu_start


class StoppingRule:
    """The early-stopping rule: `after` consecutive evaluations on the run's grid of `every`
    steps all reach `success_rate` (None: never). An evaluation off the grid (where a run
    ended at a budget between two) is not one of them: the uninterrupted run at a larger
    budget has none there, and a run that reached its budget did not stop early."""

    def __init__(self, every: int, success_rate: float | None, after: int) -> None:
        self._every, self._success_rate, self._after = every, success_rate, after
        self._streak = 0
        self.met = False

    def count(self, steps: int, success_rate: float) -> None:
        if self._success_rate is None or steps % self._every:
            return
        self._streak = self._streak + 1 if success_rate >= self._success_rate else 0
        self.met = self._streak >= self._after

    @classmethod
    def over(cls, rows, every: int, success_rate: float | None, after: int) -> StoppingRule:
        """The rule after the evaluations `rows` (eval.csv's)."""
        rule = cls(every, success_rate, after)
        for row in rows:
            rule.count(row["steps"], row["success_rate"])
        return rule


class RecordEvaluation(BaseCallback):
    """After each of its parent `Evaluation`'s evaluations: a row of eval.csv, and the
    early-stopping rule (`StoppingRule`, those already in eval.csv when resuming
    included)."""

    def __init__(self, run: RunDir, clock: WallClock, *, every: int,
                 stop_success_rate: float | None, stop_after: int) -> None:
        super().__init__()
        self._run, self._clock = run, clock
        self._rule = StoppingRule(every, stop_success_rate, stop_after)
        self.last_steps = -1
        self.last_success_rate: float | None = None

    @property
    def stopped_early(self) -> bool:
        return self._rule.met

    def restore(self) -> None:
        """The streak so far, from eval.csv (a resumed run)."""
        for row in read_eval_rows(self._run.eval_csv):
            self._rule.count(row["steps"], row["success_rate"])
            self.last_steps = row["steps"]

    def _on_step(self) -> bool:
        # SB3's EvalCallback, with log_path set, keeps its results.
        evaluation = cast(EvalCallback, self.parent)
        success_rate = float(np.mean(evaluation.evaluations_successes[-1]))
        mean_reward = float(np.mean(evaluation.evaluations_results[-1]))
        append_eval_row(self._run.eval_csv, {
            "steps": self.num_timesteps, "wall_time_s": round(self._clock(), 2),
            "success_rate": success_rate, "mean_reward": mean_reward})
        self.last_steps, self.last_success_rate = self.num_timesteps, success_rate
        self._rule.count(self.num_timesteps, success_rate)
        return not self.stopped_early


class Evaluation(EvalCallback):
    """SB3's EvalCallback: `episodes` deterministic episodes every `every` steps, on the
    run's grid of steps (also after a resume from any step) and at its first and last step.
    Its per-episode log of this session is RUN_DIR/evaluations.npz."""

    def __init__(self, eval_env, run: RunDir, clock: WallClock, *, every: int, episodes: int,
                 stop_success_rate: float | None = None, stop_after: int = 5) -> None:
        self.record = RecordEvaluation(run, clock, every=every,
                                       stop_success_rate=stop_success_rate,
                                       stop_after=stop_after)
        # log_path: SB3 writes its evaluations.npz there (`RunDir.evaluations_npz`).
        super().__init__(eval_env, callback_after_eval=self.record, n_eval_episodes=episodes,
                         eval_freq=every, log_path=str(run.root),
                         deterministic=True, warn=False, verbose=0)

    #: Whether an evaluation is under way: a stop asked for meanwhile waits for it.
    evaluating = False

    def _on_step(self) -> bool:
        self.evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
        try:
            return super()._on_step()
        finally:
            self.evaluating = False

    def _on_training_start(self) -> None:
        # SB3 evaluates when its call count is a multiple of eval_freq: count from the
        # run's step, not from this session's start.
        self.n_calls = self.num_timesteps
        self.record.restore()
        if self.num_timesteps % self.eval_freq == 0 and \
                self.record.last_steps < self.num_timesteps:
            # The untrained policy at step 0; after a resume, the evaluation on the grid
            # that a stop at once (a second signal) cut short, where its checkpoint is.
            self._evaluate_now()
            if self.stopped_early:  # SB3 takes no answer from here: the run ends here.
                raise StoppedByTheRuleAtStart

    def _on_training_end(self) -> None:
        # The curve ends where training ended, even off the grid.
        if self.record.last_steps != self.num_timesteps and not self.record.stopped_early:
            self._evaluate_now()

    def _evaluate_now(self) -> None:
        calls, self.n_calls = self.n_calls, 0  # 0 is on every grid.
        self._on_step()
        self.n_calls = calls

    @property
    def stopped_early(self) -> bool:
        return self.record.stopped_early


class StoppedByTheRuleAtStart(Exception):
    """The evaluation a run makes as it starts (`Evaluation._on_training_start`) met the
    early-stopping rule: it ends at that step, before its first, as the uninterrupted run
    ended where that evaluation was made inside a step."""


class StoppedAtCheckpoint(KeyboardInterrupt):
    """A stop that was asked for (SIGTERM, Ctrl-C) and waited for an episode's end, where
    the checkpoint it wrote resumes exactly; it names the signal (`interrupt_message`)."""


class LatestCheckpoint(CheckpointCallback):
    """SB3's CheckpointCallback of model and replay buffer, keeping only the latest:
    model.zip, replay_buffer.pkl, generators.pkl and state.json are written into a new
    folder, which then becomes RUN_DIR/checkpoint in one step (`RunDir.publish_checkpoint`),
    so the checkpoint there is always whole.

    It is written at the first episode end at or after each multiple of `every` steps (the
    run's grid, after a resume too), and at the first episode end after `stop_requested_by`
    is set (the signal that asked for it), which then stops the run (`StoppedAtCheckpoint`,
    saying which signal, for the command's exit status): there, with the step's transition
    stored and its gradient steps done, a resume goes on exactly (`exact_resume`). The
    episode stream (`exact_resume.EpisodeStream`) is the training env's, set by the loop;
    `threads`, the CPU threads the networks are computed with, recorded for a resume;
    `fresh_streams`, the steps at which the run went on with a fresh episode stream, and
    `machines`, those it has trained on (`machine`), carried on (`RunDir.read_state`; None
    where unknown); `config`, the run's settings, recorded so that a resume can tell a
    config.json edited since (`RunDir.check_config_checkpointed`)."""

    n_calls: int  # SB3's, for a type checker that does not read SB3.

    def __init__(self, run: RunDir, clock: WallClock, *, every: int, stream: EpisodeStream,
                 config: RunConfig, threads: int | None = None,
                 fresh_streams: list[int] | None = None,
                 machines: list[dict] | None = None) -> None:
        super().__init__(every, str(run.root), name_prefix="model", save_replay_buffer=True)
        self._writing = run.checkpoint  # The folder a checkpoint is being written into.
        self._run, self._clock, self.stream, self._threads = run, clock, stream, threads
        self._fresh_streams, self._machines = fresh_streams, machines
        self._config = config.to_dict()
        self.stop_requested_by: int | None = None
        self.episode_ended = False  # Whether the latest step ended an episode.

    def _checkpoint_path(self, checkpoint_type: str = "", extension: str = "") -> str:
        return str(self._writing / f"{checkpoint_type.rstrip('_') or 'model'}.{extension}")

    def _on_training_start(self) -> None:
        self._set_next_due()

    def _set_next_due(self) -> None:
        """The next multiple of `every` after this step (the run's grid)."""
        self._due = (self.num_timesteps // self.save_freq + 1) * self.save_freq

    def _on_step(self) -> bool:
        # Before SB3 stores the step's transition and trains on it: the checkpoint waits
        # for the next rollout's start.
        self.episode_ended = bool(self.locals["dones"][0])
        return True

    def _on_rollout_start(self) -> None:
        if not self.episode_ended:
            return
        if self.num_timesteps >= self._due or self.stop_requested_by is not None:
            self.save(exact=True)
            self._set_next_due()
        if self.stop_requested_by is not None:
            raise StoppedAtCheckpoint(interrupt_message(self.stop_requested_by))

    def save(self, *, exact: bool) -> None:
        """Writes the checkpoint now, into a new folder: SB3 saves the model and the replay
        buffer, then the generators and the state file; then it becomes the run's
        checkpoint. `exact`: whether this is a point a resume goes on from exactly (see the
        class)."""
        run = self._run
        self._writing = run.new_checkpoint(int(self.model.num_timesteps))
        calls, self.n_calls = self.n_calls, 0  # 0 is on every grid.
        super()._on_step()
        self.n_calls = calls
        if exact:
            exact_resume.save(self.model, self.stream,
                              self._writing / run.checkpoint_generators.name)
        (self._writing / run.checkpoint_state.name).write_text(json.dumps(
            {"steps": int(self.model.num_timesteps), "wall_time_s": self._clock(),
             "cpu_time_s": self._clock.cpu(), "checkpoint_every": self.save_freq,
             "exact": exact, "threads": self._threads,
             "fresh_streams": self._fresh_streams, "machines": self._machines,
             "config": self._config, "sha256": file_digests(self._writing)}) + "\n")
        run.publish_checkpoint(self._writing)
