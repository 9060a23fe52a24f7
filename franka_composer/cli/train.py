"""`franka-composer train`: one DDPG / SAC / TQC + HER run with the paper's Table I settings."""

from __future__ import annotations

import argparse
import contextlib
import os
import pathlib
import shlex
import signal
import warnings

from franka_composer.atomic_files import missing_folders
from franka_composer.cli.options import (add_guard_ignores_carried, add_object_damping,
                                         add_timing, as_flags, non_negative_int, number,
                                         output_folder, positive_int, timing_options,
                                         training_seed)
from franka_composer.controllers import CONTROLS, DEFAULT_CONTROL
from franka_composer.randomization import PRESETS
from franka_composer.signals import exit_status, interrupt_on, jax_imported
from franka_composer.tasks import ALL_TASKS
from franka_composer.tasks.records import MAX_SUBSTEPS, PhysicsSettings
from franka_composer.training.hyperparams import ALGOS, BACKENDS, PRECISIONS, UPDATE_SCHEDULES
from franka_composer.training.models import DEVICES
from franka_composer.training.presets import TRAINING_PRESETS
from franka_composer.training.run_config import FIELD_DEFAULTS
from franka_composer.training.runs import (DEFAULT_CHECKPOINT_EVERY, RESUME_OPTIONS,
                                          check_not_inside_a_run, run_finished)
from franka_composer.validation import check_writable


#: The run's settings when their options are not given: filled in here, not by argparse, so
#: that a --resume can tell an option given from one left out. Beside the task, algorithm
#: and seed, which `RunConfig` must be given, they are its fields' defaults; a setting not
#: listed defaults to None, as its field does.
RUN_DEFAULTS = dict(task="push", algo="tqc", seed=0, **{
    name: FIELD_DEFAULTS[name] for name in ("control", "backend", "precision",
                                            "terminate_on_success", "object_damping")})
#: Options named otherwise than the setting they give (`run_config`).
_OPTION_OF_SETTING = {"stop_success_rate": "stop_at_success",
                      "stop_after_evaluations": "stop_after",
                      "velocity_timestep": "timing", "weld_time_constant": "timing"}
_FLAGS = {"terminate_on_success": "--no-terminate-on-success", "progress": "--no-progress"}


def _flag(option: str) -> str:
    """The command-line flag of option `option` (an argparse dest)."""
    return _FLAGS.get(option, "--" + option.replace("_", "-"))


#: RESUME_OPTIONS as a user types them.
RESUME_FLAGS = (", ".join(map(_flag, RESUME_OPTIONS[:-1]))
                + f" and {_flag(RESUME_OPTIONS[-1])}")


def _net_arch(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(n) for n in text.split(","))
    except ValueError:
        sizes = ()
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated layer sizes like "
                                         f"256,256,256, got {text!r}")
    return sizes


def _rate(text: str) -> float:
    value = number(text)
    if not 0.0 < value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be a success rate in (0, 1], got {text!r}")
    return value


def _check_demos(args: argparse.Namespace, config, total_steps: int) -> None:
    """Checks --demos before the run directory exists: they load as the task's, in the
    run's own env (`config`, its `RunConfig`: its termination and randomisation too), and
    the buffer keeps them."""
    if args.expert_demos is not None:  # (Beside --demos, RunConfig has refused them.)
        from franka_composer.policies import check_expert_control
        from franka_composer.tasks import TASK_CONFIGS

        check_expert_control(TASK_CONFIGS[args.task].replace(control=args.control).control)
    if args.demos is None and args.demo_episodes is not None:
        raise ValueError("--demo-episodes takes the first episodes of --demos DATASET, "
                         "and no --demos was given")
    if args.demos is None and args.expert_demos is None:
        return
    from franka_composer.training import demos

    demos.check_room(demos.transitions(args.task, args.expert_demos, args.demos,
                                       args.demo_episodes, config.env_options),
                     config.hyperparameters.buffer_size, total_steps)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train", help="train DDPG, SAC or TQC with HER on a sparse task (paper Table I)",
        description="Train one run with the paper's Table I hyperparameters (defaults per "
                    "task and algorithm; the options below override them). Writes "
                    "config.json, eval.csv (steps, wall time, success rate, mean reward), "
                    "checkpoints and the final model.zip to the run directory.")
    parser.add_argument("--preset", choices=tuple(TRAINING_PRESETS), default=None,
                        help="a named recipe instead of Table I's settings; options given "
                             "beside it override it. "
                             + " ".join(f"{name}: {preset.describe()} ({preset.why})"
                                        for name, preset in TRAINING_PRESETS.items()))
    parser.add_argument("--task", choices=ALL_TASKS, default=None,
                        help="task to learn (default: push)")
    parser.add_argument("--algo", choices=ALGOS, default=None,
                        help="learning algorithm (default: tqc)")
    parser.add_argument("--control", choices=CONTROLS, default=None,
                        help=f"how actions move the arm (default: {DEFAULT_CONTROL}, the "
                             "paper's)")
    physics_step = PhysicsSettings.timestep
    add_timing(parser, f"physics seconds per step, a whole number of {physics_step * 1000:g} "
                       f"ms physics steps up to {MAX_SUBSTEPS * physics_step:g} s (default: "
                       "the task's, 0.05); 0.5 is what the paper's code ran (10 x its stated "
                       "0.05 s: the arm at rest after each action); --timing reference is all "
                       "of that code's timing")
    add_object_damping(parser, "0, undamped")
    add_guard_ignores_carried(parser)
    parser.add_argument("--randomization", choices=tuple(PRESETS), default=None,
                        help="domain randomisation preset for training and evaluation "
                             "(default: none); docs/guide/randomization.md")
    parser.add_argument("--demos", type=pathlib.Path, default=None, metavar="DATASET",
                        help="fill the replay buffer with these demonstrations before "
                             "learning: a .npz, Minari or RLDS dataset of the same task "
                             "(franka-composer rollout)")
    parser.add_argument("--demo-episodes", type=positive_int, default=None, metavar="K",
                        help="take the dataset's first K episodes (default: all)")
    parser.add_argument("--expert-demos", type=positive_int, default=None, metavar="N",
                        help="instead of --demos: record N episodes of the task's scripted "
                             "expert at the run's start (RUN_DIR/expert-demos.npz; their "
                             "recording counts in the run's wall-clock) and fill the replay "
                             "buffer with them")
    parser.add_argument("--backend", choices=BACKENDS, default=None,
                        help="'sb3' (default, the paper's): Stable-Baselines3 on PyTorch; "
                             "'sbx': sbx-rl, SB3 ported to JAX (pip install sbx-rl), same "
                             "Table I settings (RESULTS.md compares their speed). A resumed "
                             "run keeps the backend it was started with")
    parser.add_argument("--precision", choices=PRECISIONS, default=None,
                        help="the networks' arithmetic while training (sb3): fp32 (the "
                             "paper's) or bf16 (torch.autocast; weights, optimiser state and "
                             "evaluations stay fp32). A resumed run keeps its precision")
    parser.add_argument("--seed", type=training_seed, default=None,
                        help="random seed of the run (0 to 2**31 - 1; default: 0)")
    parser.add_argument("--out", type=output_folder, default=None,
                        help="run directory (default runs/TASK-ALGO-seedSEED)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its latest checkpoint: same "
                             "step counter, replay buffer and eval.csv; its saved settings "
                             f"are used: only {RESUME_FLAGS} may change, and an option "
                             "that says otherwise is refused")
    parser.add_argument("--total-steps", type=positive_int, default=None,
                        help="environment steps to train (Table I: 5e5, slide 1e6)")
    parser.add_argument("--device", choices=DEVICES, default="auto",
                        help="where the networks run: auto picks cuda when torch sees a GPU")
    parser.add_argument("--no-terminate-on-success", dest="terminate_on_success",
                        action="store_false", default=None,
                        help="episodes always last the task's time limit (50 steps; stack "
                             "and flip 100: Fetch semantics). The paper's "
                             "ids end an episode on success, which makes HER relabelling "
                             "inexact: a relabelled transition keeps the stored done (the "
                             "success that ended an episode stays terminal under goals it "
                             "did not reach; reaching a relabelled goal ends nothing), and "
                             "'future' goals come only from the cut-short episode")
    parser.add_argument("--update-schedule", choices=UPDATE_SCHEDULES, default=None,
                        help="'step' (the paper's, default): one gradient step after each "
                             "env step; 'episode': collect an episode, then as many gradient "
                             "steps as steps collected: the same updates per step, 11-23 %% "
                             "more steps/s on CPU (RESULTS.md)")
    parser.add_argument("--train-every", type=positive_int, default=None,
                        help="env steps per gradient step with the 'step' schedule (paper: "
                             "1); 4 trains ~4x faster per env step on CPU but learns less "
                             "per step: a budget setting, not the paper's")
    parser.add_argument("--net-arch", type=_net_arch, default=None,
                        help="hidden layer sizes, e.g. 256,256,256 (Table I per task)")
    parser.add_argument("--batch-size", type=positive_int, default=None,
                        help="minibatch size (Table I: 512, slide 2048)")
    parser.add_argument("--buffer-size", type=positive_int, default=None,
                        help="replay buffer transitions (Table I: 1e6)")
    parser.add_argument("--learning-starts", type=non_negative_int, default=None,
                        help="random-action steps before learning (SB3's default 100; "
                             "Table I does not set it; the paper's curves imply 100000: "
                             "the training guide; with an update every step at least an "
                             "episode's steps less one)")
    parser.add_argument("--eval-every", type=positive_int, default=None,
                        help="steps between evaluations (Table I: 2000)")
    parser.add_argument("--eval-episodes", type=positive_int, default=None,
                        help="deterministic episodes per evaluation (Table I: 15)")
    parser.add_argument("--clip-q-targets", action=argparse.BooleanOptionalAction, default=None,
                        help="clamp the target critic's values to the returns the sparse "
                             "reward allows, [-1/(1-gamma), 0], as OpenAI baselines' HER "
                             "does (not Table I's; sb3 backend): keeps a critic trained on "
                             "--demos from diverging (RESULTS.md); --no-clip-q-targets "
                             "undoes a --preset's")
    parser.add_argument("--stop-at-success", type=_rate, default=None, metavar="RATE",
                        help="stop early once --stop-after consecutive evaluations all reach "
                             "this success rate in (0, 1] (default: never; the Table II "
                             "campaign uses 0.95); RUN_DIR/outcome.json records it")
    parser.add_argument("--stop-after", type=positive_int, default=None, metavar="N",
                        help="consecutive evaluations for --stop-at-success (default 5)")
    parser.add_argument("--checkpoint-every", type=positive_int, default=None,
                        help="steps between checkpoints of model and replay buffer, each "
                             "at the first episode end at or after a multiple "
                             f"(default {DEFAULT_CHECKPOINT_EVERY}; a --resume keeps the "
                             "run's own; one is also written on Ctrl-C / SIGTERM, at the "
                             "episode's end)")
    parser.add_argument("--threads", type=positive_int, default=None,
                        help="CPU threads for the networks (default: the library's, or "
                             "OMP_NUM_THREADS; a --resume keeps the run's own, since the "
                             "thread count changes the results' last bits). torch's thread "
                             "count with sb3; with sbx, "
                             "whose XLA CPU runtime has no thread-count setting, the process "
                             "is pinned to this many cores while XLA starts, which sizes "
                             "its thread pool so, and let go after")
    parser.add_argument("--no-progress", dest="progress", action="store_false",
                        help="no progress bar")
    parser.set_defaults(func=run)


@contextlib.contextmanager
def _limit_threads(threads: int | None, backend: str):
    """At most `threads` CPU threads for the networks. torch has a setting; XLA's CPU
    runtime sizes its thread pool from the cores the process may use when it starts, so
    for sbx the process is pinned while JAX starts it, then every thread (the pool's too)
    is let go to all the cores again. (Pinned for the whole run, every sbx run of a machine
    sat on its first core: two sweep cells went at half speed.)"""
    import torch

    if threads:
        torch.set_num_threads(threads)
        if backend == "sbx" and hasattr(os, "sched_setaffinity"):
            cores = os.sched_getaffinity(0)
            os.sched_setaffinity(0, sorted(cores)[:threads])
            try:
                jax_imported()
                import jax

                jax.devices("cpu")  # Starts XLA's CPU runtime: its pool is sized now.
            finally:
                _allow_every_thread(cores)
    yield


def _allow_every_thread(cores: set[int]) -> None:
    """Every thread of this process allowed on `cores` (`sched_setaffinity(0, ...)` sets the
    calling thread's alone)."""
    try:
        threads = [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:  # No /proc: the calling thread at least.
        threads = [0]
    for tid in threads:
        try:
            os.sched_setaffinity(tid, cores)
        except OSError:  # A thread that ended meanwhile.
            pass


def with_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """`args` with the run settings not given taken from its --preset, then `RUN_DEFAULTS`
    (the preset's hyperparameters come in through `run_config`)."""
    from franka_composer.training.presets import TRAINING_PRESETS

    preset = TRAINING_PRESETS[args.preset].run_fields() if args.preset else {}
    if args.demos is not None:  # The user's demonstrations in place of the preset's.
        preset.pop("expert_demos", None)
    defaults = {**RUN_DEFAULTS, **preset}
    return argparse.Namespace(**{**vars(args), **{
        name: value for name, value in defaults.items() if getattr(args, name) is None}})


def run_config(args: argparse.Namespace):
    """The run these `train` arguments start (what its config.json will hold)."""
    from franka_composer.training import hyperparameters
    from franka_composer.training.presets import TRAINING_PRESETS
    from franka_composer.training.run_config import RunConfig

    args = with_defaults(args)
    base = (TRAINING_PRESETS[args.preset].hyperparameters(args.task, args.algo)
            if args.preset else hyperparameters(args.task, args.algo))
    with as_flags("train", stop_success_rate="--stop-at-success",
                  stop_after_evaluations="--stop-after"):
        hp = base.replace(
            update_schedule=args.update_schedule, train_every=args.train_every,
            net_arch=args.net_arch,
            batch_size=args.batch_size, buffer_size=args.buffer_size,
            learning_starts=args.learning_starts, eval_every=args.eval_every,
            eval_episodes=args.eval_episodes, stop_success_rate=args.stop_at_success,
            stop_after_evaluations=args.stop_after, clip_q_targets=args.clip_q_targets)
        return RunConfig(args.task, args.algo, args.seed, hp, args.terminate_on_success,
                         args.backend, args.control, args.precision, args.randomization,
                         str(args.demos.resolve()) if args.demos else None,
                         args.demo_episodes, args.expert_demos, preset=args.preset,
                         object_damping=args.object_damping,
                         guard_ignores_carried=args.guard_ignores_carried,
                         **timing_options(args))



def check_new_run(args: argparse.Namespace):
    """The run these `train` arguments start, once everything that would refuse it has been
    found out, before its directory exists: a missing sbx, --device cuda without CUDA, a
    replay buffer smaller than two episodes, --demos that do not load or fit. `sweep` checks
    each cell's options with it before Ray starts."""
    from franka_composer.tasks import TASK_CONFIGS
    from franka_composer.training.models import algorithm_class, resolve_device

    settings = with_defaults(args)
    algorithm_class(settings.algo, settings.backend)
    resolve_device(args.device)
    config = run_config(args)
    hp = config.hyperparameters
    episode = TASK_CONFIGS[config.task].max_episode_steps
    if hp.buffer_size < 2 * episode - 1:
        # SB3's HER buffer drops an episode as it begins to overwrite it, and samples only
        # finished ones: with less, the episode being written drops the one before it, and
        # the next gradient step fails with no finished episode to sample (a run resumed
        # from a checkpoint meets the same).
        raise ValueError(f"--buffer-size {hp.buffer_size} holds less than two "
                         f"{config.task} episodes ({episode} steps each): HER samples "
                         "finished episodes, and one must stay whole while the next is "
                         f"written: give {2 * episode - 1} or more (Table I: 1e6)")
    if hp.batch_size > hp.buffer_size:
        raise ValueError(f"--batch-size {hp.batch_size} is larger than the replay buffer "
                         f"(--buffer-size {hp.buffer_size}) it is sampled from")
    total_steps = args.total_steps or hp.total_steps
    if args.stop_after is not None and hp.stop_success_rate is None:
        raise ValueError("--stop-after counts evaluations for --stop-at-success RATE, and "
                         "no --stop-at-success was given")
    _check_demos(settings, config, total_steps)
    if hp.learning_starts >= total_steps:
        warnings.warn(f"--learning-starts {hp.learning_starts} is not below --total-steps "
                      f"{total_steps}: the run takes random actions only and never updates "
                      "its networks", RuntimeWarning, stacklevel=2)
    return config


def _check_resumed_as_given(args: argparse.Namespace, run_dir) -> None:
    """A resumed run goes on with its own settings: an option given with --resume that says
    otherwise is refused, not ignored (one that agrees, such as the --task that names the
    default --out, is fine)."""
    given = {name for name, value in vars(args).items() if value is not None
             and name not in (*RESUME_OPTIONS, "out", "resume", "func")}
    if not given:
        return
    recorded = run_dir.read_config()
    own = _the_runs_options(recorded, given)
    try:
        ours = run_config(argparse.Namespace(**{**vars(args), **own, **{
            name: getattr(args, name) for name in given}}))
    except ValueError as error:  # (The run's own settings pass: a given one broke them.)
        changed = [name for name in sorted(given) if name in own and (
            args.demos.resolve() if name == "demos" else getattr(args, name)) != own[name]]
        raise ValueError(f"--resume goes on with the run's own settings, and "
                         f"{', '.join(map(_flag, changed or sorted(given)))} would change "
                         f"{run_dir.root}'s "
                         f"into ones no run takes ({error}): only {RESUME_FLAGS} may "
                         "change") from None
    differing = ours.differing(recorded)
    option_of = dict(_OPTION_OF_SETTING, **({"control_timestep": "timing"}
                                            if "timing" in given else {}))
    conflicts = [(option_of.get(name, name), name, ours, theirs)
                 for name, (ours, theirs) in differing.items()
                 if option_of.get(name, name) in given]
    if conflicts:
        raise ValueError(
            f"--resume goes on with the run's own settings, and {run_dir.root} has "
            + "; ".join(f"{name} {theirs}, not {_flag(option)}'s {ours}"
                        for option, name, ours, theirs in conflicts)
            + f": only {RESUME_FLAGS} may change")


#: The hyperparameters `train` sets by an option (named as `_OPTION_OF_SETTING` says).
_HYPERPARAMETER_OPTIONS = ("update_schedule", "train_every", "net_arch", "batch_size",
                           "buffer_size", "learning_starts", "eval_every", "eval_episodes",
                           "stop_success_rate", "stop_after_evaluations", "clip_q_targets")


def _the_runs_options(config, given: set) -> dict:
    """The `train` options that start the run of `config` (its timing as a control timestep,
    unless a --timing is `given`): what a resume's options are laid over, to be compared
    whole (laid over the defaults, they mixed another run's settings with the given ones,
    which no run may take: an update every step from 10 steps, say)."""
    hp = config.hyperparameters
    return dict(task=config.task, algo=config.algo, seed=config.seed, control=config.control,
                backend=config.backend, precision=config.precision,
                terminate_on_success=config.terminate_on_success,
                randomization=config.randomization,
                demos=None if config.demos is None else pathlib.Path(config.demos),
                demo_episodes=config.demo_episodes, expert_demos=config.expert_demos,
                preset=config.preset, object_damping=config.object_damping,
                guard_ignores_carried=config.guard_ignores_carried, timing=None,
                control_timestep=None if "timing" in given else config.control_timestep,
                **{_OPTION_OF_SETTING.get(name, name): getattr(hp, name)
                   for name in _HYPERPARAMETER_OPTIONS})


def check_threads(threads: int | None, run_dir=None) -> None:
    """More threads than this machine's CPUs only queue for them (thousands stall a
    gradient step, and with it the stop at the episode's end that SIGTERM waits for). With
    `run_dir`: the threads a resume takes from the run's checkpoint."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    if threads is None or not cpus or threads <= cpus:
        return
    if run_dir is None:
        raise ValueError(f"--threads {threads} is more than the {cpus} CPUs this process may "
                         "use")
    raise ValueError(f"{run_dir.root} was trained with {threads} threads (its checkpoint's "
                     f"state.json), more than the {cpus} CPUs this process may use: resume it "
                     f"where {threads} are free, or give --threads {cpus} (the thread count "
                     "changes the results' last bits)")


def _check_budget(args: argparse.Namespace, run_dir) -> None:
    """A resume's --total-steps may raise the run's budget, not go below what it trained,
    nor so far that the steps would overwrite its demonstrations in the replay buffer (its
    start checked its budget so: `_check_demos`); nor may a budget edited into config.json
    above its checkpoint's."""
    state = run_dir.read_state()
    steps = state.get("steps", 0)
    if args.total_steps is not None and args.total_steps < steps:
        raise ValueError(f"{run_dir.root} has trained {steps} steps already, more than "
                         f"--total-steps {args.total_steps}")
    config = run_dir.read_config()
    if config.demos is None and config.expert_demos is None:
        return
    budget = args.total_steps or config.hyperparameters.total_steps
    named = f"--total-steps {budget}"
    if args.total_steps is None:
        # config.json's budget, checked as the run began or was raised; unless it is more
        # than its checkpoint's (a hand edit), which is checked as a --total-steps would be.
        trained_to = state.get("config", {}).get("hyperparameters", {}).get("total_steps")
        if trained_to is None or budget <= trained_to:
            return
        named = (f"{run_dir.config_path}'s total_steps {budget} (its checkpoint's: "
                 f"{trained_to})")
    if config.demos is not None and not pathlib.Path(config.demos).exists():
        raise ValueError(f"{named}: {run_dir.root} keeps the demonstrations of "
                         f"{config.demos} in its replay buffer, and that dataset is not "
                         "there to count them (whether more steps would overwrite them): "
                         "put it back, or resume without --total-steps")
    from franka_composer.training import demos

    transitions = demos.transitions(config.task, config.expert_demos, config.demos,
                                    config.demo_episodes, config.env_options)
    buffer_size = config.hyperparameters.buffer_size
    if transitions + budget > buffer_size:
        raise ValueError(f"{named}: {run_dir.root}'s replay buffer holds {buffer_size} "
                         f"transitions, {transitions} of them for its demonstrations, so at "
                         f"most {buffer_size - transitions} steps keep them (more would "
                         "overwrite them)")


def run(args: argparse.Namespace) -> int:
    settings = with_defaults(args)
    # The default --out checked as a given one is (`output_folder`).
    out = args.out or check_writable(pathlib.Path("runs") / (
        f"{settings.task}-{settings.algo}-seed{settings.seed}"), folder=True)
    if not args.resume:
        check_not_inside_a_run(out)
    check_threads(args.threads)
    # SIGTERM before training begins (a scheduler, timeout) stops the run as Ctrl-C does, so
    # a new run leaves nothing; once it trains, the loop checkpoints on it.
    with interrupt_on(signal.SIGTERM):
        return _run(args, out)


def _run(args: argparse.Namespace, out: pathlib.Path) -> int:
    from franka_composer.training import loop
    from franka_composer.training.models import resolve_device
    from franka_composer.training.runs import RunDir

    # The folders on the way to --out (`..` taken out as parsed) that are not there yet:
    # made here, and removed with the run if it fails before its first checkpoint.
    made = missing_folders(out)
    try:  # The checks (seconds where they load --demos): stopped here, nothing is written.
        resolve_device(args.device)  # (Evaluation envs are built before the model.)
        if args.resume:
            run_dir = RunDir(out)
            # First: an edited config.json would otherwise be taken for the run's settings.
            # (A checkpoint a stop left unlinked is checked once recovered, in the loop.)
            run_dir.check_config_checkpointed()
            _check_resumed_as_given(args, run_dir)
            run_dir.recover_checkpoint()
            run_dir.check_checkpoint_whole()  # Before its steps are taken for the budget's.
            _check_budget(args, run_dir)
        else:
            loop.check_can_start(out)  # Before --demos are loaded, seconds.
            config = check_new_run(args)
    except KeyboardInterrupt as interrupt:
        print("interrupted before training: " + ("the run is as its checkpoint left it"
                                                 if args.resume else "nothing was written"))
        return exit_status(interrupt)
    if not args.resume:
        run_dir = loop.start(out, config)
    # Ended (by the stopping rule, or at the budget the resume gives it): it trains nothing.
    ended = args.resume and run_finished(run_dir, args.total_steps)
    threads = args.threads
    if threads is None and args.resume:
        threads = run_dir.read_state().get("threads")
        check_threads(threads, run_dir)
    try:
        # The removal outermost: a stop while the threads are limited (sbx starts JAX's
        # runtime there, seconds) leaves nothing of a new run either.
        with loop.removed_if_it_fails_before_a_checkpoint(
                run_dir, new=not args.resume, made=made), \
                _limit_threads(threads, run_dir.read_config().backend):
            loop.train(run_dir, resume=args.resume, total_steps=args.total_steps,
                       device=args.device, checkpoint_every=args.checkpoint_every,
                       threads=threads, progress=args.progress)
    except KeyboardInterrupt as interrupt:
        steps = run_dir.read_state().get("steps") if run_dir.config_path.exists() else None
        if ended:
            print(f"interrupted: {_has_ended(run_dir)}")
        elif steps is not None and run_finished(run_dir, args.total_steps):
            print(f"interrupted as it ended: {_trained(run_dir)}")
        elif steps is not None:
            # A budget given that config.json does not hold yet goes in the command: without
            # it, the resume of a run that had ended trains nothing.
            budget = "" if args.total_steps in (
                None, run_dir.read_config().hyperparameters.total_steps) else \
                f" --total-steps {args.total_steps}"
            print(f"interrupted: its checkpoint at step {steps:,} is kept; continue with "
                  f"franka-composer train --resume --out {shlex.quote(str(run_dir.root))}"
                  f"{budget}")
        elif not run_dir.config_path.exists():
            print("interrupted before its first checkpoint: nothing of the run is kept; the "
                  "same command starts it again")
        else:  # Not expected: the removal above takes a new run's files with it.
            print(f"interrupted before its first checkpoint: {run_dir.root} holds none; "
                  "delete it to start again")
        return exit_status(interrupt)
    if ended:
        print(_has_ended(run_dir))
        return 0
    print(_trained(run_dir))
    return 0


def _ended_at(run_dir) -> tuple[int, str]:
    """Where the run ended, and how: " (stopped early: ...)" by the rule, else ""."""
    outcome = run_dir.read_outcome()
    return outcome["steps"], (" (stopped early: the success rule was met)"
                              if outcome["stopped_early"] else "")


def _trained(run_dir) -> str:
    steps, early = _ended_at(run_dir)
    return f"trained {steps} steps{early} -> {run_dir.final_model}"


def _has_ended(run_dir) -> str:
    """What a resume of a run that has ended says: where, how, and whether a larger budget
    goes on."""
    steps, early = _ended_at(run_dir)
    more = "" if early else " (a larger --total-steps goes on)"
    return f"{run_dir.root} had ended at {steps} steps{early}: nothing to train{more}"
