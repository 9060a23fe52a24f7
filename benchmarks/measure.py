"""Measures one task's speed through `gym.make`, beside the bare-MuJoCo baseline of its model.

Users compare suites by env steps per second (docs/guide/benchmarks.md), so everything here
goes through `gym.make(id)` with its default wrappers. The floor is the same compiled model,
started from the same states and driven by the same actions through the same control law in
a plain `mujoco.mj_step(model, data, nstep)` loop: the ratio of the two is what Composer and
the adapter cost on top of the physics. `benchmarks/bench.py` runs `measure_task` once per
task in a fresh process (`python benchmarks/measure.py`), so peak RSS is per task.
"""

from __future__ import annotations

import argparse
import copy
import json
import resource
import statistics
import sys
import time
import timeit
from dataclasses import dataclass, field

import gymnasium as gym
import mujoco
import numpy as np

import franka_composer
from franka_composer.adapters.registration import env_id

#: Pairs in the batch `compute_reward` is timed on (HER relabels batches of this order).
REWARD_BATCH = 1024
#: State saved at each reset so the floor replays every episode from the env's own start.
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass
class Episode:
    """An episode's start state and the actions the env received (to replay on the floor)."""

    state: np.ndarray
    actions: list = field(default_factory=list)


class BareMujocoBaseline:
    """The env's compiled model (a copy) in a bare MuJoCo loop, driven by the env
    controller's own action law (`ActionLaw.on` this copy). Each control step makes the
    env's own MuJoCo calls (`mj_step2`, `mj_step(n - 1)`, `mj_step1`: the work of
    `mj_step(n)`, ending with positions and velocities current for the next action), so it
    simulates exactly what the env simulates."""

    def __init__(self, env: gym.Env) -> None:
        unwrapped = env.unwrapped
        physics = unwrapped.composer_env.physics
        self.model = copy.copy(physics.model.ptr)
        self.data = mujoco.MjData(self.model)
        self._law = unwrapped.task.controller.law.on(self.model, self.data)
        self._n_sub_steps = int(round(unwrapped.dt / self.model.opt.timestep))

    def replay(self, episode: Episode) -> tuple[float, int]:
        """Seconds and total contacts for the episode's actions from its start state."""
        model, data, law, n_sub_steps = self.model, self.data, self._law, self._n_sub_steps
        mujoco.mj_setState(model, data, episode.state, _STATE)
        mujoco.mj_forward(model, data)
        law.reset()  # As the env's controller does at the episode's start.
        contacts = 0
        start = time.perf_counter()
        for action in episode.actions:
            law(action)
            if law.has_substep:  # A torque law runs before every physics step.
                for _ in range(n_sub_steps):
                    law.substep()
                    mujoco.mj_step2(model, data)
                    mujoco.mj_step1(model, data)
            else:
                mujoco.mj_step2(model, data)
                mujoco.mj_step(model, data, nstep=n_sub_steps - 1)
                mujoco.mj_step1(model, data)
            contacts += data.ncon
        return time.perf_counter() - start, contacts


@dataclass
class Run:
    """Timings of a run of env steps and of the same episodes on the floor."""

    steps: int = 0
    episodes: int = 0
    step_seconds: float = 0.0
    reset_seconds: float = 0.0
    contacts: int = 0
    floor_seconds: float = 0.0
    floor_contacts: int = 0
    successes: int = 0
    finished: int = 0

    def add_floor(self, floor: BareMujocoBaseline, episode: Episode) -> None:
        seconds, contacts = floor.replay(episode)
        self.floor_seconds += seconds
        self.floor_contacts += contacts

    def summary(self) -> dict:
        steps = self.steps
        return {
            "steps": steps,
            "episodes": self.episodes,
            "steps_per_s_resets_included": steps / (self.step_seconds + self.reset_seconds),
            "steps_per_s_resets_excluded": steps / self.step_seconds,
            "floor_steps_per_s": steps / self.floor_seconds,
            "overhead_ratio": self.step_seconds / self.floor_seconds,
            "mean_contacts": self.contacts / steps,
            "floor_mean_contacts": self.floor_contacts / steps,
            "success_rate": self.successes / self.finished if self.finished else None,
        }


def _snapshot(model, data) -> np.ndarray:
    state = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, state, _STATE)
    return state


def run_env(env: gym.Env, floor: BareMujocoBaseline, steps: int, choose_action,
            on_reset=None) -> Run:
    """Steps `env` `steps` times, resetting when an episode ends, and replays each episode
    on `floor` as soon as it ends: interleaving keeps the ratio fair on a shared machine.
    Only `env.step` and `env.reset` are inside the env's timed regions."""
    physics = env.unwrapped.composer_env.physics
    model, data = physics.model.ptr, physics.data.ptr
    run = Run()
    clock = time.perf_counter
    obs, _ = env.reset(seed=0)
    if on_reset:
        on_reset()
    episode = Episode(_snapshot(model, data))
    while run.steps < steps:
        action = choose_action(obs)
        start = clock()
        obs, _, terminated, truncated, info = env.step(action)
        run.step_seconds += clock() - start
        run.steps += 1
        run.contacts += data.ncon
        episode.actions.append(np.asarray(action, dtype=np.float64))
        if terminated or truncated or run.steps == steps:
            run.episodes += 1
            run.add_floor(floor, episode)
        if terminated or truncated:
            run.finished += 1
            run.successes += bool(info["is_success"])
            start = clock()
            obs, _ = env.reset()
            run.reset_seconds += clock() - start
            if on_reset:
                on_reset()
            episode = Episode(_snapshot(model, data))
    return run


def _measure_run(env: gym.Env, steps: int, choose_action, on_reset=None) -> dict:
    env.reset(seed=0)  # The controller's law is bound at the first reset.
    floor = BareMujocoBaseline(env)
    run_env(env, floor, min(steps, 200), choose_action, on_reset)  # Warm-up.
    return run_env(env, floor, steps, choose_action, on_reset).summary()


def measure_random(env: gym.Env, steps: int) -> dict:
    env.action_space.seed(0)
    return _measure_run(env, steps, lambda obs: env.action_space.sample())


def load_expert_factory():
    """`franka_composer.policies.make_expert`, or None with the reason it is unavailable."""
    try:
        from franka_composer.policies import make_expert
    except ImportError as error:
        return None, f"no scripted expert ({error})"
    return make_expert, None


def measure_expert(env: gym.Env, task: str, steps: int) -> dict:
    make_expert, reason = load_expert_factory()
    if make_expert is None:
        return {"skipped": reason}
    expert = make_expert(env)
    policy = {"seconds": 0.0, "calls": 0}

    def choose_action(obs):
        start = time.perf_counter()
        action = expert(obs)
        policy["seconds"] += time.perf_counter() - start
        policy["calls"] += 1
        return action

    result = _measure_run(env, steps, choose_action, on_reset=expert.reset)
    result["expert_us_per_step"] = policy["seconds"] / policy["calls"] * 1e6
    return result


def median_reset_ms(env: gym.Env, samples: int) -> float:
    times = []
    for _ in range(samples):
        start = time.perf_counter()
        env.reset()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def compute_reward_us(env: gym.Env, batch: int = REWARD_BATCH) -> float:
    """Median microseconds of `compute_reward` on `batch` (achieved, desired) pairs: random
    positions, or random unit quaternions where the goal is an orientation (flip's
    `compute_reward` refuses others)."""
    rng = np.random.default_rng(0)
    size = env.observation_space["achieved_goal"].shape[0]  # 3, 6 (stack) or 4 (flip).
    achieved = rng.uniform(0.3, 0.9, size=(batch, size))
    desired = rng.uniform(0.3, 0.9, size=(batch, size))
    if env.unwrapped.task.goal_metric == "rotation_angle":
        achieved, desired = (goals / np.linalg.norm(goals, axis=-1, keepdims=True)
                             for goals in (achieved, desired))
    info = [{}] * batch
    reward = env.unwrapped.compute_reward(achieved, desired, info)
    if np.shape(reward) != (batch,):
        raise RuntimeError(f"compute_reward returned shape {np.shape(reward)} for {batch} pairs")
    number = 200
    runs = timeit.repeat(lambda: env.unwrapped.compute_reward(achieved, desired, info),
                         number=number, repeat=7)
    return statistics.median(runs) / number * 1e6


def render_ms(env_name: str, frames: int) -> dict:
    """Milliseconds for the first 480x480 `rgb_array` frame (GL context included) and the
    median of `frames` more, each after an env step."""
    env = gym.make(env_name, render_mode="rgb_array", width=480, height=480)
    env.reset(seed=0)
    start = time.perf_counter()
    frame = env.render()
    first = time.perf_counter() - start
    if frame.shape != (480, 480, 3):
        raise RuntimeError(f"rgb_array frame has shape {frame.shape}, expected (480, 480, 3)")
    times = []
    for _ in range(frames):
        if any(env.step(env.action_space.sample())[2:4]):  # Terminated or truncated.
            env.reset()
        start = time.perf_counter()
        env.render()
        times.append(time.perf_counter() - start)
    env.close()
    return {"first_frame_ms": first * 1e3, "ms_per_frame": statistics.median(times) * 1e3}


def vector_steps_per_s(task: str, workers: int, steps: int) -> float:
    """Env steps per second of all envs together in a `gymnasium.vector.AsyncVectorEnv` of
    `workers` processes, random actions, resets (autoreset) included."""
    name = env_id(task, "sparse")
    envs = gym.vector.AsyncVectorEnv([lambda: gym.make(name) for _ in range(workers)])
    try:
        envs.action_space.seed(0)
        envs.reset(seed=0)
        actions = [envs.action_space.sample() for _ in range(max(1, steps // workers))]
        for action in actions[:20]:  # Warm-up: worker start-up is not throughput.
            envs.step(action)
        start = time.perf_counter()
        for action in actions:
            envs.step(action)
        return len(actions) * workers / (time.perf_counter() - start)
    finally:
        envs.close()


def resident_mb() -> float:
    """This process's resident set size now (MB), from /proc/self/statm (Linux)."""
    with open("/proc/self/statm") as file:
        pages = int(file.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def memory_per_env_mb(task: str, render_mode: str | None, count: int) -> dict:
    """Resident memory of one env (`gym.make` + reset) and of each of `count` more, in this
    process: what a vector-env worker or a process holding many envs pays per env."""
    import gc

    name = env_id(task, "sparse")
    before = resident_mb()
    envs = [gym.make(name, render_mode=render_mode)]
    envs[0].reset(seed=0)
    gc.collect()
    first = resident_mb()
    for index in range(count):
        envs.append(gym.make(name, render_mode=render_mode))
        envs[-1].reset(seed=index + 1)
    gc.collect()
    return {"first_env_mb": first - before, "per_additional_env_mb": (resident_mb() - first) / count,
            "envs": count + 1}


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure_task(task: str, steps: int, reset_samples: int, render_frames: int) -> dict:
    """Every in-process figure for one task; peak RSS is read before rendering (a GL
    context is not part of a training run's footprint) and once more after it."""
    if task not in franka_composer.ALL_TASKS:
        raise ValueError(f"unknown task {task!r}; valid: {', '.join(franka_composer.ALL_TASKS)}")
    name = env_id(task, "sparse")
    env = gym.make(name)
    result = {"env_id": name, "random": measure_random(env, steps),
              "expert": measure_expert(env, task, steps),
              "reset_ms_median": median_reset_ms(env, reset_samples),
              "compute_reward_1024_us": compute_reward_us(env),
              "peak_rss_mb": peak_rss_mb()}
    env.close()
    if render_frames > 0:
        result["render"] = render_ms(name, render_frames)
        result["peak_rss_mb_with_render"] = peak_rss_mb()
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Measure one task in this process; prints one JSON line.")
    parser.add_argument("--task", required=True, choices=franka_composer.ALL_TASKS)
    parser.add_argument("--steps", type=int, required=True)
    parser.add_argument("--reset-samples", type=int, default=50)
    parser.add_argument("--render-frames", type=int, default=0)
    parser.add_argument("--memory-envs", type=int, default=0,
                        help="measure only the memory of this many more envs")
    parser.add_argument("--render-mode", default=None,
                        help="with --memory-envs: the envs' render_mode (default None)")
    parser.add_argument("--vector-workers", type=int, default=0,
                        help="measure only AsyncVectorEnv throughput with this many workers")
    args = parser.parse_args(argv)
    if args.memory_envs > 0:
        result = memory_per_env_mb(args.task, args.render_mode, args.memory_envs)
    elif args.vector_workers > 0:
        result = {"steps_per_s": vector_steps_per_s(args.task, args.vector_workers, args.steps)}
    else:
        result = measure_task(args.task, args.steps, args.reset_samples, args.render_frames)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
