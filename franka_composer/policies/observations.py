"""What an expert plans with, from whichever observation its environment gives.

The experts read the Gymnasium goal dict's state vector (`observation`) and goal
(`desired_goal`). `ExpertInput` makes that dict from
- a Gymnasium goal observation with the state vector: as it is;
- a dm_env (Composer) observation with the state observables: flattened by the task's
  layout, as the Gymnasium adapter does;
- an observation without the state (the pixel modes, either interface): the state read
  through the task from the physics (`GoalTask.state_vector`), never from the images: the
  true state, which sensing noise and delay (randomisation) do not reach.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Callable

import numpy as np

from franka_composer.tasks.layout import ObservationLayout

#: The Gymnasium goal dict's keys the experts read.
STATE_KEY, GOAL_KEY = "observation", "desired_goal"


class ExpertInput:
    """Turns an env's observation into {"observation": state vector, "desired_goal": goal}.

    Args:
      layout: the task's observation layout.
      composer_goal_key: the Composer observable holding the desired goal, for dm_env
        observations ("goal", as `make_expert` gives it; None: Gymnasium goal dicts only).
      read_state: () -> the state vector now, for observations without it (None: such an
        observation is a ValueError saying how to get an expert that reads it).
    """

    def __init__(self, layout: ObservationLayout, composer_goal_key: str | None = None,
                 read_state: Callable[[], np.ndarray] | None = None) -> None:
        self._layout, self._composer_goal_key = layout, composer_goal_key
        self._read_state = read_state

    def __call__(self, obs: Mapping) -> Mapping:
        if not isinstance(obs, Mapping):
            raise ValueError(f"an expert takes the observation dict its env returns, got "
                             f"{type(obs).__name__}"
                             + (f" of shape {obs.shape}" if hasattr(obs, "shape") else ""))
        if STATE_KEY in obs:
            return obs
        goal = self._goal(obs)
        if all(key in obs for key in self._layout.keys):
            return {STATE_KEY: self._layout.flatten(obs), GOAL_KEY: goal}
        if self._read_state is None:
            raise ValueError(
                "this observation holds no state vector (a pixel mode?): build the expert "
                "with make_expert(env), which reads the state through env's task")
        return {STATE_KEY: self._read_state(), GOAL_KEY: goal}

    def _goal(self, obs: Mapping) -> np.ndarray:
        for key in (GOAL_KEY, self._composer_goal_key):
            if key is not None and key in obs:
                return np.asarray(obs[key], dtype=np.float64)
        raise ValueError(f"an expert needs the desired goal, and this observation has none "
                         f"(its keys: {', '.join(map(str, obs))}); pass the observation the "
                         f"env returned, a Gymnasium goal dict or a dm_env observation")
