"""What an episode is wherever episodes are kept (a rollout's `Trajectories`, the npz, Minari
and RLDS datasets, demonstrations): its keys, and the check every reader makes of the
episodes it gives back, so that a damaged or foreign file is refused by name, saying what is
wrong, before anything trains.

An episode of T steps holds the observation's keys (at least the two goals; the state
vector and camera images as its observation mode has them) with T + 1 rows (the reset's
first) and one row per step of `action`, `reward`, `is_success`, `terminated`,
`truncated`; it ends on its last step (terminated or truncated there, at no step before).
"""

from __future__ import annotations

import numpy as np

#: Keys of the Gymnasium goal observation dict in the state modes (the pixel modes add
#: "<camera>_pixels" images, and "pixels" alone has no "observation").
OBSERVATION_KEYS = ("observation", "achieved_goal", "desired_goal")
#: What every observation mode observes.
GOAL_KEYS = ("achieved_goal", "desired_goal")
#: Per-step arrays (one entry per action taken).
STEP_KEYS = ("action", "reward", "is_success", "terminated", "truncated")


def check_episodes(path, episodes: list[dict]) -> None:
    """A ValueError naming `path` unless `episodes` is at least one episode, each whole."""
    if not episodes:
        raise ValueError(f"{path} holds no episodes (an empty or damaged dataset?)")
    for index, episode in enumerate(episodes):
        missing = [key for key in GOAL_KEYS + STEP_KEYS if key not in episode]
        if missing:
            raise ValueError(f"{path}: episode {index} has no {', '.join(missing)}")
        steps = len(episode["action"])
        if steps == 0:
            raise ValueError(f"{path}: episode {index} has no steps")
        for key in (key for key in episode if key not in STEP_KEYS):
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
