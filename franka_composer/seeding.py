"""Seeds: any non-negative int, and one episode stream per seed in both interfaces.

Composer draws every episode from one `np.random.RandomState`, whose own `seed()` takes
only ints below 2**32, while Gymnasium accepts any non-negative int (and vector envs add the
worker index to it). So a seed becomes Composer's random state through
`np.random.SeedSequence`, which takes any non-negative int and spreads it over MT19937's
whole state: `load(name, seed=s)` and `gym.make(id).reset(seed=s)` start the same episode,
for every s.

Shimmy's `DmControlCompatibilityV0(env).reset(seed=s)` replaces Composer's random state with
`np.random.RandomState(s)` (numpy's legacy seeding; Shimmy's own code), so it starts the
episode of `load(name, seed=np.random.RandomState(s))`, not Gymnasium's. Gymnasium's
episodes for seed s come through Shimmy by seeding at `load(name, seed=s)` and resetting
without a seed (`tests/test_seeding.py`).
"""

from __future__ import annotations

import numbers

import numpy as np


def check_seed(seed) -> int:
    """`seed` as an int if it is a non-negative integer (bools are not), else a ValueError
    that says what a seed may be."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    return int(seed)


def random_state(seed) -> np.random.RandomState:
    """The RandomState an episode stream seeded with `seed` draws from."""
    return np.random.RandomState(np.random.MT19937(np.random.SeedSequence(check_seed(seed))))


def reseed(state: np.random.RandomState, seed) -> None:
    """Puts `state` (Composer's, shared with every hook) where `random_state(seed)` starts."""
    state.set_state(random_state(seed).get_state())
