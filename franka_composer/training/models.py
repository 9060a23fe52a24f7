"""Environments and Stable-Baselines3 models built from a run's settings.

One function turns (task, algorithm, `Hyperparameters`) into a model, so a fresh run, a
resumed run and an evaluation all see the same construction.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from franka_composer.adapters.registration import env_id
from franka_composer.training.hyperparams import ALGOS, Hyperparameters, check_choice

DEVICES = ("auto", "cpu", "cuda")


def algorithm_class(algo: str):
    """The SB3 / sb3-contrib class for `algo` (imported lazily: training is an extra)."""
    check_choice("algorithm", algo, ALGOS)
    if algo == "tqc":
        from sb3_contrib import TQC

        return TQC
    from stable_baselines3 import DDPG, SAC

    return {"ddpg": DDPG, "sac": SAC}[algo]


def make_env(task: str, *, terminate_on_success: bool = True) -> gym.Env:
    """The sparse-reward Gymnasium env of `task` (`FrankaPushSparse-v0`, ...).

    `terminate_on_success=True` is the paper's ids; False gives Fetch semantics (episodes
    always last 50 steps), for which HER's relabelled rewards and `done` flags are exact.
    """
    return gym.make(env_id(task, "sparse"), terminate_on_success=terminate_on_success)


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


def build_model(task: str, algo: str, hp: Hyperparameters, env: gym.Env, *, seed: int,
                device: str = "auto", tensorboard_log: str | None = None):
    """A fresh HER model with `hp` (Table I unless overridden) on `env`."""
    from stable_baselines3 import HerReplayBuffer
    from stable_baselines3.common.noise import NormalActionNoise

    n_actions = env.action_space.shape[0]
    kwargs = dict(
        learning_rate=hp.learning_rate, buffer_size=hp.buffer_size,
        learning_starts=hp.learning_starts, batch_size=hp.batch_size, tau=hp.tau,
        gamma=hp.gamma, replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=hp.her_n_sampled_goal,
                                  goal_selection_strategy=hp.her_goal_selection_strategy),
        policy_kwargs=dict(net_arch=list(hp.net_arch)), seed=seed,
        device=resolve_device(device), tensorboard_log=tensorboard_log, verbose=0,
        **_schedule_kwargs(hp),
    )
    if hp.action_noise_std is not None:
        kwargs["action_noise"] = NormalActionNoise(np.zeros(n_actions),
                                                   hp.action_noise_std * np.ones(n_actions))
    if algo in ("sac", "tqc"):
        kwargs["ent_coef"] = hp.ent_coef
    if algo == "tqc":
        kwargs["policy_kwargs"].update(n_critics=hp.n_critics, n_quantiles=hp.n_quantiles)
        kwargs["top_quantiles_to_drop_per_net"] = hp.top_quantiles_to_drop_per_net
    return algorithm_class(algo)("MultiInputPolicy", env, **kwargs)


def load_model(algo: str, path, *, env: gym.Env, device: str = "auto"):
    """A saved model on `env` (HER models cannot be loaded without their env)."""
    return algorithm_class(algo).load(path, env=env, device=resolve_device(device))
