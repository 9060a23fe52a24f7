"""What every dataset reader checks of the episodes it gives back, whatever the format: a
damaged or foreign file is refused by name, saying what is wrong, before anything trains.

An episode of T steps holds the goal observation's keys with T + 1 rows (the reset's
first) and one row per step of `action`, `reward`, `is_success`, `terminated`,
`truncated`; it ends on its last step (terminated or truncated there, at no step before).
"""

from __future__ import annotations

import numpy as np

from franka_composer.policies.rollout import OBSERVATION_KEYS, STEP_KEYS


def check_episodes(path, episodes: list[dict]) -> None:
    """A ValueError naming `path` unless `episodes` is at least one episode, each whole."""
    if not episodes:
        raise ValueError(f"{path} holds no episodes (an empty or damaged dataset?)")
    for index, episode in enumerate(episodes):
        missing = [key for key in OBSERVATION_KEYS + STEP_KEYS if key not in episode]
        if missing:
            raise ValueError(f"{path}: episode {index} has no {', '.join(missing)}")
        steps = len(episode["action"])
        if steps == 0:
            raise ValueError(f"{path}: episode {index} has no steps")
        for key in OBSERVATION_KEYS:
            if len(episode[key]) != steps + 1:
                raise ValueError(f"{path}: episode {index} has {len(episode[key])} rows of "
                                 f"{key} for {steps} actions, not {steps + 1} (the reset's "
                                 "first)")
        for key in STEP_KEYS[1:]:
            if len(episode[key]) != steps:
                raise ValueError(f"{path}: episode {index} has {len(episode[key])} rows of "
                                 f"{key} for {steps} actions")
        ends = np.flatnonzero(np.asarray(episode["terminated"], dtype=bool)
                              | np.asarray(episode["truncated"], dtype=bool))
        if ends.tolist() != [steps - 1]:
            raise ValueError(f"{path}: episode {index} ({steps} steps) ends at step(s) "
                             f"{ends.tolist()} by its terminated and truncated flags, not at "
                             f"its last, {steps - 1}: its episode boundaries do not match "
                             "its arrays")
