"""Environments and Stable-Baselines3 (or sbx) models built from a run's settings.

One function turns (task, algorithm, `Hyperparameters`, backend) into a model, so a fresh
run, a resumed run and an evaluation all see the same construction.
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np

from franka_composer.adapters.registration import env_id
from franka_composer.controllers import DEFAULT_CONTROL
from franka_composer.signals import jax_imported
from franka_composer.training.hyperparams import ALGOS, BACKENDS, Hyperparameters
from franka_composer.training.run_files import saved_policy_module
from franka_composer.validation import check_choice

DEVICES = ("auto", "cpu", "cuda")

#: Other environments a run may train in (`RunConfig.environment`): {name: a builder taking
#: `make_env`'s arguments}. Empty in the package: the script that trains in one registers it
#: (experiments/reference_env_runs.py, experiments/altered_runs.py), and elsewhere such a
#: run is refused.
ENVIRONMENTS: dict = {}

#: What `--backend sbx` needs when sbx-rl is missing.
SBX_MISSING = ("--backend sbx needs sbx-rl (Stable-Baselines3 ported to JAX): "
               "pip install sbx-rl, or pip install 'franka_composer[jax]'")


def algorithm_class(algo: str, backend: str = "sb3"):
    """The class of `algo` in `backend`: SB3 / sb3-contrib, or sbx (imported lazily: training
    is an extra, and JAX takes seconds to import); a missing sbx is a ValueError."""
    check_choice("algorithm", algo, ALGOS)
    check_choice("backend", backend, BACKENDS)
    if backend == "sbx":
        jax_imported()
        try:
            import sbx
        except ImportError as error:
            raise ValueError(SBX_MISSING) from error
        return {"ddpg": sbx.DDPG, "sac": sbx.SAC, "tqc": sbx.TQC}[algo]
    if algo == "tqc":
        from sb3_contrib import TQC

        return TQC
    from stable_baselines3 import DDPG, SAC

    return {"ddpg": DDPG, "sac": SAC}[algo]


def make_env(task: str, *, terminate_on_success: bool = True,
             control: str = DEFAULT_CONTROL, randomization: str | None = None,
             control_timestep: float | None = None, velocity_timestep: float | None = None,
             weld_time_constant: float | None = None, object_damping: float = 0.0,
             guard_ignores_carried: bool | None = None, environment: str | None = None,
             **render_options) -> gym.Env:
    """The sparse-reward Gymnasium env of `task` (`FrankaPushSparse-v0`, ...), or, with
    `environment`, that suite's (`ENVIRONMENTS`).

    `terminate_on_success=True` is the paper's ids; False gives Fetch semantics (episodes
    always last the task's time limit, 50 steps, stack's and flip's 100), for which HER's
    relabelled rewards and `done` flags are exact.
    `randomization`: a preset's name (`randomization.PRESETS`), or None.
    `control_timestep`: seconds per step, or None for the task's; `velocity_timestep`: the
    seconds velocities are multiplied by, or None for the control period;
    `weld_time_constant`: the mocap weld's, or None for the task's; `object_damping`: the
    objects' free joints' (0: undamped, the task's); `guard_ignores_carried`: the surface
    guard's, or None for the task's (the builders of other envs take none: refused). `render_options`
    (`render_mode`, `width`, `height`) go to `gym.make` as they are.
    """
    if environment is not None:
        if guard_ignores_carried is not None:  # (Their builders take no guard setting.)
            raise ValueError(f"the run trained in {environment}'s {task} environment with "
                             f"guard_ignores_carried={guard_ignores_carried}, which that "
                             "environment's builder does not set")
        if environment not in ENVIRONMENTS:
            raise ValueError(f"the run trained in {environment}'s {task} environment, which "
                             "this process does not build: train, evaluate or play it through "
                             "the experiments/ script that trained it")
        return ENVIRONMENTS[environment](
            task, terminate_on_success=terminate_on_success, control=control,
            randomization=randomization, control_timestep=control_timestep,
            velocity_timestep=velocity_timestep, weld_time_constant=weld_time_constant,
            object_damping=object_damping, **render_options)
    options = _task_options(randomization=randomization, control_timestep=control_timestep,
                            velocity_timestep=velocity_timestep,
                            weld_time_constant=weld_time_constant,
                            object_damping=object_damping,
                            guard_ignores_carried=guard_ignores_carried)
    return gym.make(env_id(task, "sparse", control), terminate_on_success=terminate_on_success,
                    **options, **render_options)


def env_task_config(task: str, *, terminate_on_success: bool = True,
                    control: str = DEFAULT_CONTROL, **options):
    """The task configuration (`TaskConfig`) of the env `make_env` makes of this suite with
    these options (`make_env`'s, rendering and other suites' envs aside), without building
    it: what a policy is checked against first."""
    from franka_composer.tasks import task_config

    return task_config(task, terminate_on_success=terminate_on_success, control=control,
                       **_task_options(**options))


def _task_options(*, randomization: str | None = None, control_timestep: float | None = None,
                  velocity_timestep: float | None = None,
                  weld_time_constant: float | None = None,
                  object_damping: float = 0.0,
                  guard_ignores_carried: bool | None = None) -> dict:
    """`make_env`'s options as the task takes them: those left to the task omitted."""
    return {name: value for name, value in (("randomization", randomization),
                                            ("control_timestep", control_timestep),
                                            ("velocity_timestep", velocity_timestep),
                                            ("weld_time_constant", weld_time_constant),
                                            ("object_damping", object_damping or None),
                                            ("guard_ignores_carried", guard_ignores_carried))
            if value is not None}


def resolve_device(device: str) -> str:
    """`auto` -> cuda when torch sees a GPU, else cpu; `cuda` without one is a ValueError."""
    import torch

    check_choice("device", device, DEVICES)
    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda, but torch sees no CUDA GPU (torch.cuda.is_available() "
                         "is False); use --device cpu or auto")
    return device


def _schedule_kwargs(hp: Hyperparameters) -> dict:
    if hp.update_schedule == "episode":
        return dict(train_freq=(1, "episode"), gradient_steps=-1)
    return dict(train_freq=hp.train_every, gradient_steps=1)


def _sbx_kwargs(algo: str, hp: Hyperparameters) -> dict:
    """sbx settings whose defaults differ from SB3's, pinned to SB3's algorithm.

    sbx lets the critic have its own learning rate (DDPG's default is 1e-3 whatever the
    actor's) and delay the actor (`policy_delay`); SB3 uses one rate and updates the actor
    after every critic step (DDPG: forced by sbx). Dropout and layer norm in the critics
    (DroQ / CrossQ-style options) are off in SB3. The target entropy is -dim(action) in both.
    """
    if algo == "tqc" and hp.n_critics != 2:
        raise ValueError(f"sbx's TQC has exactly 2 critics, got n_critics={hp.n_critics}")
    kwargs: dict[str, Any] = dict(qf_learning_rate=hp.learning_rate)
    if algo in ("sac", "tqc"):
        kwargs.update(policy_delay=1, target_entropy="auto")
    return kwargs


def _policy(algo_class, backend: str):
    """SB3's "MultiInputPolicy" for the Dict observations; sbx flattens Dict observations in
    every policy, but its DDPG lists only "MlpPolicy" (which SB3's checks refuse for a Dict
    space), so the policy class itself is passed there."""
    if backend == "sb3" or "MultiInputPolicy" in algo_class.policy_aliases:
        return "MultiInputPolicy"
    return algo_class.policy_aliases["MlpPolicy"]


def policy_kwargs(algo: str, hp: Hyperparameters, backend: str = "sb3") -> dict:
    """The networks of `algo` with `hp`: what a model is built with, and what a saved actor
    (`policy_file`) is rebuilt with."""
    kwargs: dict[str, Any] = dict(net_arch=list(hp.net_arch))
    if algo == "tqc":
        kwargs.update(n_critics=hp.n_critics, n_quantiles=hp.n_quantiles)
    if backend == "sbx":
        kwargs.update(dropout_rate=0.0, layer_norm=False)
    return kwargs


def quiet_logger():
    """SB3's logger, writing nowhere. Without a logger of its own, each `learn()` makes an
    empty `SB3-<time>` folder in the system's temporary directory."""
    from stable_baselines3.common.logger import Logger

    return Logger(folder=None, output_formats=[])


def build_model(algo: str, hp: Hyperparameters, env: gym.Env, *, seed: int,
                device: str = "auto", tensorboard_log: str | None = None,
                backend: str = "sb3"):
    """A fresh HER model with `hp` (Table I unless overridden) on `env`."""
    algo_class = algorithm_class(algo, backend)
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.noise import NormalActionNoise

    n_actions = gym.spaces.flatdim(env.action_space)
    kwargs = dict(
        learning_rate=hp.learning_rate, buffer_size=hp.buffer_size,
        learning_starts=hp.learning_starts, batch_size=hp.batch_size, tau=hp.tau,
        gamma=hp.gamma, replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=hp.her_n_sampled_goal,
                                  goal_selection_strategy=hp.her_goal_selection_strategy),
        policy_kwargs=policy_kwargs(algo, hp, backend), seed=seed,
        device=resolve_device(device), tensorboard_log=tensorboard_log, verbose=0,
        **_schedule_kwargs(hp),
    )
    if hp.action_noise_std is not None:
        kwargs["action_noise"] = NormalActionNoise(np.zeros(n_actions),
                                                   hp.action_noise_std * np.ones(n_actions))
    if algo in ("sac", "tqc"):
        kwargs["ent_coef"] = hp.ent_coef
    if algo == "tqc":
        kwargs["top_quantiles_to_drop_per_net"] = hp.top_quantiles_to_drop_per_net
    if backend == "sbx":
        kwargs.update(_sbx_kwargs(algo, hp))
    least, memory = _least_weight_bytes(env, hp), _physical_memory_bytes()
    if least > memory:  # JAX would fail later, at sbx's first use of them, in a traceback.
        raise _too_large(hp, f"the weights of one actor and one critic alone take "
                             f"{least / 2**30:,.1f} GiB (float32), and the machine has "
                             f"{memory / 2**30:,.1f} GiB")
    try:
        return algo_class(_policy(algo_class, backend), env, **kwargs)
    except (MemoryError, RuntimeError, ValueError) as error:
        if not isinstance(error, MemoryError) and not any(
                sign in str(error).lower() for sign in _OUT_OF_MEMORY):
            raise
        raise _too_large(hp, str(error).strip().splitlines()[-1]) from None


def _too_large(hp: Hyperparameters, why: str) -> MemoryError:
    return MemoryError(f"the replay buffer (--buffer-size {hp.buffer_size:,}) and networks "
                       f"(--net-arch {','.join(map(str, hp.net_arch))}) do not fit in this "
                       f"machine's memory: {why}")


def _least_weight_bytes(env: gym.Env, hp: Hyperparameters) -> int:
    """Fewer bytes than any algorithm's networks on `env` take: the float32 weights of an
    actor and one critic on the vector observations (images add a CNN; critics add copies,
    targets and optimiser moments). More than the machine's memory, they cannot be built."""
    spaces = getattr(env.observation_space, "spaces", {"observation": env.observation_space})
    observed = sum(space.shape[0] for space in spaces.values() if len(space.shape) == 1)
    actions = gym.spaces.flatdim(env.action_space)

    def weights(sizes) -> int:
        return sum(a * b for a, b in zip(sizes, sizes[1:]))

    return 4 * (weights([observed, *hp.net_arch, actions])
                + weights([observed + actions, *hp.net_arch, 1]))


def _physical_memory_bytes() -> int:
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


#: How the libraries say that an allocation failed (lower case): numpy raises MemoryError,
#: or a ValueError for more elements than its index type counts (--buffer-size 1e19), torch
#: a RuntimeError from its CPU allocator (or CUDA's, a subclass). (JAX allocates as it
#: dispatches, after this: sbx's networks fail at their first use.)
_OUT_OF_MEMORY = ("can't allocate memory", "out of memory", "maximum allowed dimension exceeded",
                  "array is too big")


def check_saved_by(path, algo: str, backend: str) -> None:
    """A ValueError where the model at `path` was saved by another algorithm or library than
    `algo` in `backend` (its run's config.json edited by hand): SB3 would load it partway
    and fail inside with an AttributeError."""
    algo_class = algorithm_class(algo, backend)
    policy = _policy(algo_class, backend)
    expected = (algo_class.policy_aliases[policy] if isinstance(policy, str)
                else policy).__module__.rsplit(".", 1)[0]
    saved = saved_policy_module(path)
    if saved is not None and saved.rsplit(".", 1)[0] != expected:
        raise ValueError(f"{path} holds a model of {saved.rsplit('.', 1)[0]}, and its run's "
                         f"config.json says algo {algo}, backend {backend} (a model of "
                         f"{expected}): put them back as the run was trained")


def load_model(algo: str, path, *, env: gym.Env, device: str = "auto", backend: str = "sb3",
               force_reset: bool = True):
    """A saved model on `env` (HER models cannot be loaded without their env). Without
    `force_reset` it keeps its last observation: `env` must be brought to it."""
    check_saved_by(path, algo, backend)
    return algorithm_class(algo, backend).load(path, env=env, device=resolve_device(device),
                                               force_reset=force_reset)
