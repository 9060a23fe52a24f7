"""Each speed lever's effect, measured against the lever undone, in the same process.

    python benchmarks/levers.py

Step levers are timed as interleaved blocks of env steps (lever on, lever undone,
alternately; medians), so a shared machine's load falls on both sides alike. The compile
levers (one compile, compiled-model cache) show in `franka-composer bench`'s cold start:
`cold_start.uncached_s` against `cold_start.median_s`.
"""

from __future__ import annotations

import functools
import statistics
import sys
import time
import timeit

import gymnasium as gym
import numpy as np
from dm_control.composer.observation import observable

from franka_composer.adapters.goal_env import OBS_DTYPE
from franka_composer.adapters.registration import env_id
from franka_composer.entities.features import ArrayFeature
from franka_composer.entities.panda import MAX_FINGER_WIDTH

BLOCK, BLOCKS = 100, 20


def _undo_direct_observables(env) -> None:
    """Composer's buffered observation updater, as before the lever."""
    env.unwrapped.composer_env._direct_observables = lambda: None


def _undo_fast_reset(env) -> None:
    """Composer's reset, which rebuilds the observation updater every episode."""
    env.unwrapped.composer_env._observables_signature = object


def _undo_fused_step(env) -> None:
    """dm_control's `physics.step(n)` (the same MuJoCo calls, more Python around them)."""
    composer_env = env.unwrapped.composer_env
    composer_env._step_physics = lambda: composer_env.physics.step(composer_env._n_sub_steps)


def _undo_one_distance(env) -> None:
    """The goal distance recomputed through a binding by the reward, the discount and the
    termination, and the adapter computing success and reward again from the observation.
    (The task's `after_step` still computes its distance once: ~3 us more on this side.)"""
    adapter = env.unwrapped
    task = adapter.task

    def distance_success(physics):
        return bool(task.is_success(task.achieved_goal(physics), task.goal))

    task.get_reward = lambda physics: float(task.compute_reward(task.achieved_goal(physics),
                                                                task.goal))
    task.should_terminate_episode = (
        lambda physics: task.terminate_on_success and distance_success(physics))
    step = adapter.step

    def step_and_recompute(action):
        obs, reward, terminated, truncated, info = step(action)
        info = {"is_success": bool(task.is_success(obs["achieved_goal"], obs["desired_goal"]))}
        reward = adapter.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)[()]
        return obs, reward, terminated, truncated, info

    adapter.step = step_and_recompute


def _undo_controller_views(env) -> None:
    """The controller reading and writing through `physics.bind` every step."""
    task = env.unwrapped.task
    controller, panda = task.controller, task.panda

    def apply(physics, action):
        action = np.clip(controller.validate(action), -1.0, 1.0)
        settings = controller.settings
        target = (np.array(physics.bind(panda.tcp_site).xpos)
                  + settings.max_tcp_step * action[:3])
        target[2] = max(target[2], settings.min_tcp_height)
        physics.bind(controller.target).mocap_pos = target
        if settings.actuated_gripper:
            width = panda.finger_width(physics) + settings.max_finger_step * action[3]
            physics.bind(panda.gripper_actuator).ctrl = np.clip(width, 0.0, MAX_FINGER_WIDTH)

    controller.apply = apply


def _binding_callable(feature: ArrayFeature, physics):
    binding = physics.bind(feature._mjcf_element)
    kind, transform = feature._kind, feature._transform or np.array
    return lambda: transform(getattr(binding, kind))


def _undo_observable_views(env) -> None:
    """Every observable read through a dm_control binding (`MJCFFeature`'s way)."""
    task = env.unwrapped.task
    for entity in (task.panda, task.prop):
        for feature in entity.observables.as_dict().values():
            if isinstance(feature, ArrayFeature):
                feature._callable = functools.partial(_binding_callable, feature)


def _step_blocks(env, actions) -> float:
    seconds = 0.0
    for action in actions:
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        seconds += time.perf_counter() - start
        if terminated or truncated:
            env.reset()
    return seconds / len(actions)


def _reset_blocks(env, actions) -> float:
    times = []
    for _ in range(len(actions) // 10):
        start = time.perf_counter()
        env.reset()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def interleaved(task: str, undo, measure) -> tuple[float, float]:
    """Median microseconds of `measure` with the lever and with it undone."""
    with_lever, without = gym.make(env_id(task, "sparse")), gym.make(env_id(task, "sparse"))
    undo(without)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (BLOCK,) + with_lever.action_space.shape).astype(np.float32)
    for env in (with_lever, without):
        env.reset(seed=0)
        _step_blocks(env, actions)  # Warm-up.
    on, off = [], []
    for _ in range(BLOCKS):
        on.append(measure(with_lever, actions))
        off.append(measure(without, actions))
    return statistics.median(on) * 1e6, statistics.median(off) * 1e6


def _old_quat_to_euler(quat):
    w, x, y, z = quat
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.array([roll, pitch, yaw])


def observable_levers() -> list[tuple[str, float, float]]:
    """The two derived observables and the adapter's assembly, old code against new."""
    env = gym.make(env_id("pick_and_place", "sparse"))
    env.reset(seed=0)
    adapter = env.unwrapped
    physics, task = adapter.composer_env.physics, adapter.task
    prop, panda = task.prop, task.panda
    rows = []
    sensor = prop.orientation
    old = observable.Generic(lambda p: _old_quat_to_euler(p.bind(sensor).sensordata))
    new = prop.observables.orientation_euler
    rows.append(("orientation_euler observable", old.observation_callable(physics),
                 new.observation_callable(physics)))
    old = observable.Generic(lambda p: np.array([panda.finger_width(p)]))
    rows.append(("finger_width observable", old.observation_callable(physics),
                 panda.observables.finger_width.observation_callable(physics)))
    observation = adapter.composer_env._read_observation()
    scales = [adapter.dt if f.per_control_step else 1.0 for f in task.observation_fields]

    def old_vector():
        return np.concatenate([
            np.asarray(observation[f.key], dtype=OBS_DTYPE).ravel() * s
            for f, s in zip(task.observation_fields, scales)])

    rows.append(("adapter observation vector", old_vector,
                 lambda: adapter._observation(observation)))
    result = []
    for name, before, after in rows:
        times = [min(timeit.repeat(f, number=2000, repeat=5)) / 2000 * 1e6
                 for f in (after, before)]
        result.append((name, *times))
    return result


def main() -> int:
    print("| lever | task | with (us) | undone (us) | saving |")
    print("|---|---|---|---|---|")
    cases = [("direct observables (step)", task, _undo_direct_observables, _step_blocks)
             for task in ("push", "pick_and_place")]
    for name, undo in (("fused physics step (step)", _undo_fused_step),
                       ("one goal distance per step (step)", _undo_one_distance),
                       ("controller views (step)", _undo_controller_views),
                       ("observables read through views (step)", _undo_observable_views)):
        cases += [(name, task, undo, _step_blocks) for task in ("slide", "pick_and_place")]
    cases += [("reset keeps the observation updater (reset)", task, _undo_fast_reset,
               _reset_blocks) for task in ("push", "pick_and_place")]
    for name, task, undo, measure in cases:
        on, off = interleaved(task, undo, measure)
        print(f"| {name} | {task} | {on:.0f} | {off:.0f} | {off - on:.0f} us "
              f"({(1 - on / off) * 100:.0f} %) |")
    for name, on, off in observable_levers():
        print(f"| {name} (one call) | pick_and_place | {on:.1f} | {off:.1f} | "
              f"{off - on:.1f} us ({(1 - on / off) * 100:.0f} %) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
