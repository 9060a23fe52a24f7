"""Where an env step's time goes beyond MuJoCo: each layer timed on its own, in one process.

    python benchmarks/overhead.py [--tasks TASK[,TASK]]

Every part is timed with `timeit` (best of 5) at a fixed state with zero actions, so the
parts are comparable with each other and with `mj_step` in the same run; they do not add
up to a step exactly (cache effects between layers are not in any part).
"""

from __future__ import annotations

import argparse
import timeit

import gymnasium as gym
import mujoco
import numpy as np

import franka_composer
from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import add_tasks_argument


def best_us(function, number: int) -> float:
    return min(timeit.repeat(function, number=number, repeat=5)) / number * 1e6


def breakdown(task: str) -> dict[str, float]:
    env = gym.make(env_id(task, "sparse"))
    env.reset(seed=0)
    adapter = env.unwrapped
    composer_env, task_object = adapter.composer_env, adapter.task
    physics = composer_env.physics
    action = np.zeros(adapter.action_space.shape, np.float32)

    def gym_step():
        if any(env.step(action)[2:4]):  # Terminated or truncated.
            env.reset()

    def apply_action():
        task_object.controller.apply(physics, action)  # Writes through views: no mj_forward.

    def adapter_step():
        if any(adapter.step(action)[2:4]):
            adapter.reset()

    observation = composer_env._read_observation()
    goals = adapter.goal_observation(observation)
    parts = {
        "gym.make step (wrappers included)": best_us(gym_step, 1000),
        "adapter step": best_us(adapter_step, 1000),
        # Every 50th step is a reset, as after each of the env's episodes.
        "Composer step": best_us(lambda: composer_env.step(action), 1000),
        "physics.step(25) (the fast path's one call)": best_us(lambda: physics.step(25), 1000),
        "mj_step(model, data, 25)": best_us(
            lambda: mujoco.mj_step(physics.model.ptr, physics.data.ptr, 25), 1000),
        "controller.apply (before_step)": best_us(apply_action, 5000),
    }
    parts.update({
        f"observables ({len(observation)} reads)": best_us(composer_env._read_observation,
                                                           5000),
        "distance + reward + discount + termination": best_us(
            lambda: (task_object.after_step(physics, None),
                     composer_env._make_timestep(False, observation)), 5000),
        "reward + discount + termination (no distance)": best_us(
            lambda: composer_env._make_timestep(False, observation), 5000),
        "adapter observation dict": best_us(lambda: adapter.goal_observation(observation), 5000),
        "compute_reward, one pair (HER's call)": best_us(
            lambda: adapter.compute_reward(goals["achieved_goal"], goals["desired_goal"]),
            5000),
    })
    return parts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, franka_composer.ALL_TASKS, "tasks to time (default: all)")
    for task in parser.parse_args(argv).tasks:
        parts = breakdown(task)
        floor = parts["mj_step(model, data, 25)"]
        print(f"\n{task}")
        for name, micros in parts.items():
            print(f"  {name:46s} {micros:7.1f} us  ({micros / floor:5.2f} x mj_step)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
