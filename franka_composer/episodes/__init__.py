"""Episodes: what one holds and the check every reader makes (`record`), the `.npz` file
they are kept in (`npz_file`), and `Trajectories`, the episodes of one policy in one env.
Below both the policies that record them and the dataset formats that convert them."""

from __future__ import annotations

from franka_composer.episodes.record import (GOAL_KEYS, OBSERVATION_KEYS, STEP_KEYS,
                                             check_episodes, check_not_diverged)
from franka_composer.episodes.trajectories import Trajectories

__all__ = ["GOAL_KEYS", "OBSERVATION_KEYS", "STEP_KEYS", "Trajectories", "check_episodes",
           "check_not_diverged"]
