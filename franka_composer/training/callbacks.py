"""What happens around SB3's `learn` loop: evaluations to CSV, a progress bar, checkpoints."""

from __future__ import annotations

import json
import sys
import time

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback
from tqdm import tqdm

from franka_composer.training.evaluation import evaluate_policy
from franka_composer.training.runs import RunDir, append_eval_row, read_eval_rows


class WallClock:
    """Training seconds across resumes: the checkpoint's elapsed time plus this session's."""

    def __init__(self, elapsed_before: float = 0.0) -> None:
        self._before = elapsed_before
        self._start = time.perf_counter()

    def __call__(self) -> float:
        return self._before + time.perf_counter() - self._start


def save_checkpoint(model, run: RunDir, clock: WallClock) -> None:
    """Model, replay buffer and step count; the state file is written last, so a checkpoint
    whose state exists is complete."""
    run.checkpoint.mkdir(parents=True, exist_ok=True)
    run.checkpoint_state.unlink(missing_ok=True)
    model.save(run.checkpoint_model)
    model.save_replay_buffer(run.checkpoint_buffer)
    run.checkpoint_state.write_text(json.dumps(
        {"steps": int(model.num_timesteps), "wall_time_s": clock()}) + "\n")


class EvaluationCallback(BaseCallback):
    """Every `every` steps, `episodes` deterministic episodes on a separate env -> a row of
    eval.csv (and TensorBoard's eval/success_rate when a TensorBoard logger is set).

    With `stop_success_rate`, training stops once `stop_after` consecutive evaluations (those
    already in eval.csv when resuming included) all reach it; `stopped_early` says so."""

    def __init__(self, env: gym.Env, run: RunDir, clock: WallClock, *, every: int,
                 episodes: int, seed: int, stop_success_rate: float | None = None,
                 stop_after: int = 5) -> None:
        super().__init__()
        self._env, self._run, self._clock = env, run, clock
        self._every, self._episodes, self._seed = every, episodes, seed
        self._stop_success_rate, self._stop_after = stop_success_rate, stop_after
        self._next = 0
        self._last_evaluated = -1
        self._streak = 0
        self.stopped_early = False
        self.last_success_rate: float | None = None

    def _on_training_start(self) -> None:
        # A fresh run evaluates the untrained policy at step 0; a resumed one continues.
        for row in read_eval_rows(self._run.eval_csv):
            self._count(row["success_rate"])
        if self.num_timesteps == 0:
            self.evaluate()
        self._next = (self.num_timesteps // self._every + 1) * self._every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self.evaluate()
            self._next += self._every
        return not self.stopped_early

    def _count(self, success_rate: float) -> None:
        """Extends or breaks the streak of evaluations at or above the stopping rate."""
        if self._stop_success_rate is None:
            return
        self._streak = self._streak + 1 if success_rate >= self._stop_success_rate else 0
        self.stopped_early = self._streak >= self._stop_after

    def _on_training_end(self) -> None:
        # The curve ends where training ended, even off the evaluation grid.
        if self._last_evaluated != self.num_timesteps:
            self.evaluate()

    def evaluate(self) -> None:
        self._last_evaluated = self.num_timesteps
        seed = self._seed if self.last_success_rate is None else None
        result = evaluate_policy(self.model, self._env, self._episodes, seed=seed)
        self.last_success_rate = result.success_rate
        self._count(result.success_rate)
        append_eval_row(self._run.eval_csv, {
            "steps": self.num_timesteps, "wall_time_s": round(self._clock(), 2),
            "success_rate": result.success_rate, "mean_reward": result.mean_reward})
        self.logger.record("eval/success_rate", result.success_rate)
        self.logger.record("eval/mean_reward", result.mean_reward)
        self.logger.dump(self.num_timesteps)


class CheckpointCallback(BaseCallback):
    """A checkpoint every `every` steps (the latest only: replay buffers are large)."""

    def __init__(self, run: RunDir, clock: WallClock, *, every: int) -> None:
        super().__init__()
        self._run, self._clock, self._every = run, clock, every
        self._next = 0

    def _on_training_start(self) -> None:
        self._next = (self.num_timesteps // self._every + 1) * self._every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            save_checkpoint(self.model, self._run, self._clock)
            self._next += self._every
        return True


class ProgressCallback(BaseCallback):
    """A tqdm bar over the run's total steps, with the last success rate and steps/s."""

    def __init__(self, total_steps: int, evaluation: EvaluationCallback,
                 enabled: bool = True) -> None:
        super().__init__()
        self._total, self._evaluation, self._enabled = total_steps, evaluation, enabled
        self._bar: tqdm | None = None
        self._window_start = (0, 0.0)

    def _on_training_start(self) -> None:
        interactive = sys.stderr.isatty()
        self._bar = tqdm(total=self._total, initial=self.num_timesteps, unit="step",
                         disable=not self._enabled, mininterval=0.5 if interactive else 30,
                         dynamic_ncols=True)
        self._window_start = (self.num_timesteps, time.perf_counter())

    def _on_step(self) -> bool:
        self._bar.update(self.num_timesteps - self._bar.n)
        steps, start = self._window_start
        now = time.perf_counter()
        if now - start >= 5.0:
            rate = (self.num_timesteps - steps) / (now - start)
            success = self._evaluation.last_success_rate
            self._bar.set_postfix({"success": "-" if success is None else f"{success:.2f}",
                                   "steps/s": f"{rate:.1f}"}, refresh=False)
            self._window_start = (self.num_timesteps, now)
        return True

    def _on_training_end(self) -> None:
        self._bar.close()
