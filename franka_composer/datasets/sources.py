"""Who acts in a recorded episode: a task's scripted expert or a trained policy (a run
directory of `franka-composer train`), optionally with Gaussian action noise for more
diverse data."""

from __future__ import annotations

import pathlib

import gymnasium as gym
import numpy as np

from franka_composer.adapters.goal_env import state_box
from franka_composer.policies import make_expert
from franka_composer.tasks.layout import OBSERVATION_DTYPE
from franka_composer.validation import check_number


class NoisyPolicy:
    """`policy`'s action plus N(0, `scale`) noise per component, clipped to [-1, 1]; the
    noise stream restarts from (`seed`, the episode's index) at each `reset`, so a recorded
    episode is a function of its seed."""

    def __init__(self, policy, scale: float, seed: int) -> None:
        self._policy, self._scale, self._seed = policy, scale, seed
        self._episode = -1
        self._rng = np.random.default_rng(seed)

    def reset(self) -> None:
        self._episode += 1
        self._rng = np.random.default_rng([self._seed, self._episode])
        if hasattr(self._policy, "reset"):
            self._policy.reset()

    def __call__(self, obs) -> np.ndarray:
        action = np.asarray(self._policy(obs), dtype=np.float32)
        noise = self._rng.normal(0.0, self._scale, size=action.shape)
        return np.clip(action + noise, -1.0, 1.0).astype(np.float32)


class TrainedPolicy:
    """The best model of a training run, acting deterministically on goal observations. It
    learned from state observations: in the pixel modes it acts on the state the task reads
    (`StateView`), never on the images, as the scripted experts do: a privileged teacher
    for datasets of pixels."""

    def __init__(self, run_dir: pathlib.Path, env) -> None:
        from franka_composer.training.policy_file import load_trained
        from franka_composer.training.runs import RunDir

        run = RunDir(pathlib.Path(run_dir))
        config = run.read_config()
        check_acts_in(run_dir, config, env.unwrapped.task.config)
        self._view = StateView(env) if env.unwrapped.task.pixel_keys else None
        self._model = load_trained(run, self._view or env, device="cpu")

    def __call__(self, obs) -> np.ndarray:
        if self._view is not None:
            obs = self._view.observation(obs)
        action, _ = self._model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float32)


class StateView(gym.ObservationWrapper):
    """A pixel-mode env as a policy trained on state observations sees it: the state mode's
    goal dict without the images, its state vector as observed (state+pixels) or, where the
    mode observes none (pixels), read through the task (without the randomised observation
    noise and delay, which act on observables)."""

    def __init__(self, env) -> None:
        super().__init__(env)
        unwrapped = env.unwrapped
        self._task, self._composer_env = unwrapped.task, unwrapped.composer_env
        goal = env.observation_space["desired_goal"]
        self.observation_space = gym.spaces.Dict({
            "observation": state_box(self._task.observation_layout),
            "achieved_goal": goal, "desired_goal": goal})

    def observation(self, observation):
        state = observation.get("observation")
        if state is None:
            state = self._task.state_vector(self._composer_env.physics)
        return {"observation": np.asarray(state, dtype=OBSERVATION_DTYPE),
                "achieved_goal": observation["achieved_goal"],
                "desired_goal": observation["desired_goal"]}


def check_acts_in(run_dir, config, env_config) -> None:
    """A ValueError naming `run_dir` unless its run (`config`) acts in an env of
    `env_config` (a `TaskConfig`) as it learned: the same task, this suite's env, the same
    controller, timing, velocity scale, weld and surface guard. Asked before the env is
    made where it can be (`demo --policy`), and by `TrainedPolicy`."""
    task = env_config.name
    if config.task != task:
        raise ValueError(f"{run_dir} trained {config.task}, not {task}")
    if config.environment is not None:  # Another suite's env (RunConfig.environment).
        raise ValueError(f"{run_dir} trained in {config.environment}'s {task} "
                         "environment, not this suite's")
    control = env_config.control.kind
    if config.control != control:  # Its actions mean what they did in training.
        raise ValueError(f"{run_dir} acts through {config.control} control, not "
                         f"{control}")
    if config.control_timestep != env_config.control_timestep:  # And last as long.
        raise ValueError(f"{run_dir} acts every {config.control_timestep} s, not every "
                         f"{env_config.control_timestep} s")
    if config.velocity_timestep != env_config.velocity_timestep:  # Sees as it learned.
        raise ValueError(f"{run_dir} observes velocities per "
                         f"{config.velocity_timestep or config.control_timestep} s, not "
                         f"per {env_config.velocity_period} s")
    if (env_config.control.has_weld  # The same hand (the other controllers have none).
            and config.weld_time_constant != env_config.control.weld_time_constant):
        raise ValueError(f"{run_dir} moved a hand welded with a time constant of "
                         f"{config.weld_time_constant} s, not "
                         f"{env_config.control.weld_time_constant} s")
    if config.guard_ignores_carried != env_config.control.guard_ignores_carried:
        raise ValueError(f"{run_dir} trained with guard_ignores_carried="
                         f"{config.guard_ignores_carried}, not "
                         f"{env_config.control.guard_ignores_carried}: the surface guard "
                         "held the hand differently wherever it carried a block")


def make_policy(env, *, policy_dir=None, action_noise: float = 0.0, seed: int = 0):
    """The expert of `env`'s task (or the policy trained in `policy_dir`), with action
    noise of standard deviation `action_noise` (0: none)."""
    action_noise = check_number("action_noise", action_noise, minimum=0.0)
    policy = make_expert(env) if policy_dir is None else TrainedPolicy(policy_dir, env)
    return NoisyPolicy(policy, action_noise, seed) if action_noise > 0 else policy


def source_name(policy_dir, action_noise: float) -> str:
    """How a dataset names who acted: "expert", "policy", with "-noisy" for action noise."""
    name = "expert" if policy_dir is None else "policy"
    return f"{name}-noisy" if action_noise > 0 else name
