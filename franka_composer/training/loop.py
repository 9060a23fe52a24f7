"""A training run from start (or from its last checkpoint) to its total step count.

Interrupting it (Ctrl-C, or SIGTERM from a scheduler) writes a checkpoint at the episode's
end first, so `resume` continues with the same step counter, replay buffer and eval.csv,
exactly as the uninterrupted run would (`exact_resume`); a second Ctrl-C or SIGTERM stops
it at once, with a checkpoint from which the run goes on with a fresh episode stream.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import importlib.util
import os
import pathlib
import shutil
import warnings

from stable_baselines3.common.callbacks import CallbackList, ProgressBarCallback
from stable_baselines3.common.vec_env import DummyVecEnv

from franka_composer.atomic_files import remove_empty, replace_atomically
from franka_composer.signals import held, stop_requests, stop_signals
from franka_composer.training import demos, exact_resume, machine
from franka_composer.training.callbacks import (Evaluation, LatestCheckpoint,
                                                StoppedAtCheckpoint, StoppedByTheRuleAtStart,
                                                StoppingRule, WallClock)
from franka_composer.training.models import build_model, load_model, make_env, quiet_logger
from franka_composer.training.policy_file import save_policy
from franka_composer.training.precision import GradientStepPrecision, warn_if_emulated
from franka_composer.training.run_config import RunConfig
from franka_composer.training.run_files import (check_file_digests, checked_model,
                                                unpickling)
from franka_composer.training.runs import (DEFAULT_CHECKPOINT_EVERY, RunDir, run_finished,
                                          write_eval_rows)
from franka_composer.training.target_bounds import clip_target_critic

#: The evaluation env's seed is offset from the training seed so they never share episodes.
EVAL_SEED_OFFSET = 10_000
#: A fresh training stream's seed (a resume that cannot go on exactly) is the run's seed plus
#: this and the step: above the evaluation's, so the two never share episodes (a fresh
#: stream at step 10,000 took the evaluation's seed when it was the seed plus the step).
FRESH_STREAM_SEED_OFFSET = 2 * EVAL_SEED_OFFSET


def _skip_evaluated_episodes(eval_env, evaluations: int, episodes: int) -> None:
    """Moves the evaluation env's episode stream past `evaluations` evaluations: each one
    (SB3's `evaluate_policy`) resets once and then after each of its `episodes` episodes,
    and which episodes a reset draws depends only on the seed, not on the policy. Without
    this a resumed run would evaluate the episodes of its first evaluations again."""
    for _ in range(evaluations * (episodes + 1)):
        eval_env.reset()


def _resume(run: RunDir, config: RunConfig, state: dict, env, device: str, goes_on: bool):
    """The model and the training env's episode stream at the run's checkpoint: exactly as
    the run left them where the checkpoint allows (`exact_resume`), else with a fresh
    episode stream, seeded by the run's seed and step, said with a warning where the run
    `goes_on` training from there; and whether it trains on a fresh stream."""
    check_file_digests(run.checkpoint, state.get("sha256"))  # Before anything is unpickled.
    exact = bool(state.get("exact")) and run.checkpoint_generators.is_file()
    model = load_model(config.algo, checked_model(run.checkpoint_model), env=env,
                       device=device, backend=config.backend, force_reset=not exact)
    with unpickling(run.checkpoint_buffer), warnings.catch_warnings():
        # SB3's advice for a buffer saved inside an episode (truncate_last_trajectory) is
        # no option of train's: such a resume goes on with a fresh stream, warned below.
        warnings.filterwarnings("ignore", message="The last trajectory in the replay buffer "
                                "will be truncated")
        model.load_replay_buffer(run.checkpoint_buffer)
    stream = exact_resume.restore(model, run.checkpoint_generators) if exact else None
    fresh = stream is None and goes_on
    if fresh:
        why = ("its training env did not come back as its checkpoint saw it" if exact else
               f"its checkpoint at step {state['steps']:,} was not written where a resume "
               "goes on exactly (an episode's end, with the random generators saved)")
        warnings.warn(f"{run.root}: {why}; the run goes on with a fresh episode stream and "
                      "from here is not the run an uninterrupted one would be (recorded as "
                      "fresh_streams in its checkpoint's state.json and its outcome.json)",
                      RuntimeWarning, stacklevel=2)
    if stream is None:
        model._last_obs = None  # SB3 resets the env, with the new stream's seed.
        stream = exact_resume.EpisodeStream(
            config.seed + FRESH_STREAM_SEED_OFFSET + int(state["steps"]), model._episode_num)
        model.set_random_seed(stream.seed)
    return model, stream, fresh


def start(root: pathlib.Path, config: RunConfig) -> RunDir:
    """Creates a run directory for `config` where `check_can_start` lets one begin."""
    run = check_can_start(root)
    run.write_config(config)
    return run


def check_can_start(root: pathlib.Path) -> RunDir:
    """The run directory a new run at `root` would be; a folder that already holds a run, or
    anything else, is a ValueError (a failed start removes what it made: nothing else may be
    there). `train` asks before it loads --demos or builds an env."""
    run = RunDir(pathlib.Path(root))
    if run.config_path.exists() and run.is_kept_copy():
        raise ValueError(f"{run.root} holds a kept copy of a finished run (nothing to "
                         "resume): choose another --out")
    if run.config_path.exists():
        raise ValueError(f"{run.root} already holds a run; pass --resume to continue it "
                         "or choose another --out")
    if run.holds_other_things():
        raise ValueError(f"{run.root} is not empty and holds no run: give a new or empty "
                         "folder as --out")
    return run


@contextlib.contextmanager
def removed_if_it_fails_before_a_checkpoint(run: RunDir, *, new: bool,
                                             made: list[pathlib.Path]):
    """Where a `new` run fails or is stopped before its first checkpoint (while it records
    its expert's demonstrations, say), what it wrote is removed, and the folders `start`
    made for it (`made`: its own and those above it that were not there, deepest first): a
    second try with the same --out then starts afresh instead of being refused as a run
    without a checkpoint. A run stopped once training began has checkpointed."""
    try:
        yield
    except BaseException:
        if new and not run.read_state():
            with held():  # A second signal would leave half of it.
                for path in run.root.iterdir():
                    if path.is_dir():
                        shutil.rmtree(path)
                    else:
                        path.unlink()
                remove_empty(made)
        raise


def train(run: RunDir, *, resume: bool = False, total_steps: int | None = None,
          device: str = "auto", checkpoint_every: int | None = None,
          threads: int | None = None, progress: bool = True):
    """Trains `run` up to its total steps (`total_steps` overrides and is saved); returns the
    model. With `resume`, starts from the latest checkpoint. `checkpoint_every` defaults to
    the cadence the run's checkpoints were written at (DEFAULT_CHECKPOINT_EVERY for a new
    run), so a resumed run does not quietly checkpoint less often than it was started to.
    `threads`: the CPU threads the caller limited the networks to (None: not limited),
    recorded in the checkpoints for a resume to compute with. One process at a time trains
    a run: a second is refused (`RunDir.training_lock`). A resume with nothing to resume
    from is refused before the lock, and any resume refused leaves the run's files as
    they were."""
    if resume:
        run.check_resumable()
    with run.training_lock():
        return _train(run, resume=resume, total_steps=total_steps, device=device,
                      checkpoint_every=checkpoint_every, threads=threads, progress=progress)


def _train(run: RunDir, *, resume: bool, total_steps: int | None, device: str,
           checkpoint_every: int | None, threads: int | None, progress: bool):
    run.recover_checkpoint()
    if resume:  # A checkpoint just linked: checked as `check_resumable` checks a linked one.
        run.check_config_checkpointed()
        run.check_checkpoint_whole()
    config = run.read_config()
    if total_steps is not None:  # Saved once the run goes on with it (below).
        config = dataclasses.replace(
            config, hyperparameters=config.hyperparameters.replace(total_steps=total_steps))
    hp = config.hyperparameters
    env = make_env(config.task, **config.env_options)
    eval_env = DummyVecEnv([lambda: make_env(config.task, **config.env_options)])
    eval_env.seed(config.seed + EVAL_SEED_OFFSET)
    tensorboard = str(run.tensorboard) if importlib.util.find_spec("tensorboard") else None

    state = run.read_state()
    outcome = run.read_outcome()
    if resume:  # `train` has checked it is resumable.
        rows = run.kept_evaluations()
        if run_finished(run, hp.total_steps):
            # It has ended, by the stopping rule or at this budget: nothing to train, and
            # its files stay as they are.
            return _trained_model(config, env, eval_env, device, run.best_model())
        if StoppingRule.over(rows, hp.eval_every, hp.stop_success_rate,
                             hp.stop_after_evaluations).met:
            # It met the stopping rule and was stopped before it wrote its outcome: it ends
            # there, as it would have.
            model = _trained_model(config, env, eval_env, device, run.checkpoint_model)
            _finish(run, model, True, state["wall_time_s"], state.get("cpu_time_s"),
                    state.get("fresh_streams"), state.get("machines"))
            return model
        # Checkpoints written before CPU time was recorded have none: the run's stays unknown.
        clock = WallClock(state["wall_time_s"], state.get("cpu_time_s"))
        model, stream, fresh = _resume(run, config, state, env, device,
                                       goes_on=hp.total_steps > state["steps"])
        if outcome:
            # A raised budget: it has not ended now. Its final model and policy go with its
            # outcome (the checkpoint it resumed from is the same model, and `evaluate`
            # would otherwise score them after it trains on), and so does an evaluation off
            # the grid where it ended, which the uninterrupted run at this budget has not.
            for path in (run.final_model, run.policy_file, run.outcome_path):
                path.unlink(missing_ok=True)
            if rows and rows[-1]["steps"] % hp.eval_every:
                rows = rows[:-1]
        # Where the run left the uninterrupted run's course, carried from checkpoint to
        # checkpoint into outcome.json; unknown (None) for a run whose checkpoints began
        # before it was recorded.
        fresh_streams = state.get("fresh_streams")
        if fresh_streams is not None:
            fresh_streams = [*fresh_streams, *([state["steps"]] if fresh else [])]
        machines = _machines_on_resume(run, state)
        write_eval_rows(run.eval_csv, rows)
        # The evaluations go on with the episodes an uninterrupted run would see next.
        _skip_evaluated_episodes(eval_env, sum(r["steps"] % hp.eval_every == 0 for r in rows),
                                 hp.eval_episodes)
    else:
        clock = WallClock()  # Before the expert's demonstrations: they are the run's time.
        model = build_model(config.algo, hp, env, seed=config.seed,
                            device=device, tensorboard_log=tensorboard,
                            backend=config.backend)
        if config.demos is not None:
            episodes = demos.load_episodes(config.demos, env)[:config.demo_episodes]
            demos.prefill(model, episodes, hp.total_steps)
        if config.expert_demos is not None:
            dataset = demos.record_expert(run.expert_demos, config)
            demos.prefill(model, demos.load_episodes(dataset, env), hp.total_steps)
        stream = exact_resume.EpisodeStream(config.seed)  # SB3 seeds the env's first reset.
        fresh_streams = []
        machines = [{"from_steps": 0, **machine.fingerprint()}]
    if total_steps is not None:
        run.write_config(config)
    if hp.clip_q_targets:
        clip_target_critic(model, hp.gamma)
    if tensorboard:
        model.tensorboard_log = tensorboard
    else:
        model.set_logger(quiet_logger())

    evaluation = Evaluation(eval_env, run, clock, every=hp.eval_every,
                            episodes=hp.eval_episodes, stop_success_rate=hp.stop_success_rate,
                            stop_after=hp.stop_after_evaluations)
    if checkpoint_every is None:
        checkpoint_every = state.get("checkpoint_every", DEFAULT_CHECKPOINT_EVERY) if resume \
            else DEFAULT_CHECKPOINT_EVERY
    checkpoint = LatestCheckpoint(run, clock, every=checkpoint_every, stream=stream,
                                  config=config, threads=threads,
                                  fresh_streams=fresh_streams, machines=machines)
    warn_if_emulated(config.precision, model.device)
    precision = GradientStepPrecision(config.precision)
    # The loop's own bar, not learn(progress_bar=True)'s: an interrupt skips SB3's closing
    # of it, and a bar left open is closed at interpreter shutdown, where rich fails.
    bar = ProgressBarCallback() if progress else None
    callbacks = CallbackList([precision, evaluation, checkpoint, *([bar] if bar else [])])
    remaining = hp.total_steps - model.num_timesteps
    try:
        with stop_requests(functools.partial(_stop_at_episode_end, checkpoint, evaluation),
                           *stop_signals()), \
                contextlib.suppress(StoppedByTheRuleAtStart):  # It ends where it starts.
            # Also where nothing is left to train (a resume at its checkpoint's step): the
            # callbacks' end of training evaluates where the run ends, as it would have.
            model.learn(total_timesteps=remaining, callback=callbacks,
                        reset_num_timesteps=not resume, tb_log_name="run")
        if remaining > 0:
            # Where training ended: exact at an episode's end, unless the stopping rule ended
            # it inside a step (before SB3 stored the transition). Before the envs close: a
            # checkpoint may read its training env (experiments/reference_env_runs.py).
            checkpoint.save(exact=checkpoint.episode_ended and not evaluation.stopped_early)
    except KeyboardInterrupt as interrupt:
        precision.close()
        # Nothing trained where nothing was left to (the evaluation at the end of a resume
        # at its checkpoint's step): the exact checkpoint there stays as it is.
        trained = getattr(checkpoint, "model", None) is not None and remaining > 0
        if trained and not isinstance(interrupt, StoppedAtCheckpoint):  # Stopped at once.
            checkpoint.save(exact=False)
        raise
    finally:
        precision.close()
        if bar is not None and hasattr(bar, "pbar"):
            bar.pbar.close()  # Closed already where training ended; a second close is none.
        env.close()
        eval_env.close()
    _finish(run, model, evaluation.stopped_early, clock(), clock.cpu(), fresh_streams,
            machines)
    return model


def _stop_at_episode_end(checkpoint: LatestCheckpoint, evaluation: Evaluation,
                         signum: int) -> None:
    """A stop asked for (the first Ctrl-C or SIGTERM, `signum`): the run checkpoints at its
    episode's end and stops there, and says so at once, with what it waits for: an
    evaluation under way finishes first (its row belongs to the exact course), which with
    many episodes or long steps takes a while, and nothing else showed that the stop had
    been heard."""
    checkpoint.stop_requested_by = signum
    first = (f" (first the evaluation under way: {evaluation.n_eval_episodes} episodes at "
             f"step {evaluation.num_timesteps:,})" if evaluation.evaluating else "")
    # os.write: a signal handler may run inside another write to stderr.
    os.write(2, (f"stopping at the episode's end, where its checkpoint resumes exactly{first}; "
                 "Ctrl-C or SIGTERM again stops at once\n").encode())


def _machines_on_resume(run: RunDir, state: dict) -> list[dict]:
    """The machines the run has trained on (`machine`), this one added where it differs
    from the last: said with a warning, since the run's course from here can differ from
    the one that machine would have trained. A checkpoint written before machines were
    recorded starts the list at its step."""
    now = machine.fingerprint()
    machines = state.get("machines")
    if not machines:
        return [{"from_steps": state["steps"], **now}]
    changed = machine.differences(machines[-1], now)
    if not changed:
        return machines
    warnings.warn(f"{run.root}: resumed from its checkpoint at step {state['steps']:,} on "
                  f"{machine.another_machine(changed)} (recorded as machines in its "
                  "checkpoint's state.json and its outcome.json)", RuntimeWarning,
                  stacklevel=2)
    return [*machines, {"from_steps": state["steps"], **now}]


def _trained_model(config: RunConfig, env, eval_env, device: str, path):
    """The model at `path` of a run that trains no further, its envs closed."""
    try:
        return load_model(config.algo, checked_model(path), env=env, device=device,
                          backend=config.backend)
    finally:
        env.close()
        eval_env.close()


def _finish(run: RunDir, model, stopped_early: bool, wall_time_s: float,
            cpu_time_s: float | None, fresh_streams, machines) -> None:
    """What an ended run writes: its final model, its policy and, last, its outcome."""
    replace_atomically(run.final_model, model.save)
    replace_atomically(run.policy_file, lambda path: save_policy(model, path))
    run.write_outcome(int(model.num_timesteps), stopped_early, wall_time_s, cpu_time_s,
                      fresh_streams, machines)
