"""Env steps per second under seeded random actions: the one timing loop behind
`franka-composer bench` and `benchmarks/peers.py`, so this suite and its peers are timed alike.

It imports nothing of franka_composer: the peers' processes load this file by its path
(`benchmarks/peer_worker.py`) without importing the package, whose Gymnasium ids the paper's
reference code also registers.
"""

from __future__ import annotations

import time

#: Env steps taken before the clock starts (caches, first contacts).
WARMUP_STEPS = 100


def random_steps_per_second(env, steps: int) -> float:
    """Env steps/s of `env` (a Gymnasium env, its wrappers included) under random actions
    seeded with 0, resets included, after `WARMUP_STEPS`; drawing the actions is not timed."""
    env.action_space.seed(0)
    env.reset(seed=0)
    actions = [env.action_space.sample() for _ in range(steps + WARMUP_STEPS)]
    elapsed = 0.0
    for index, action in enumerate(actions):
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
        if index >= WARMUP_STEPS:
            elapsed += time.perf_counter() - start
    return steps / elapsed
