"""Reach expert: straight to the goal at full speed, then hold there."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from franka_composer.policies.base import Expert


class ReachExpert(Expert):
    """Moves the tool centre point straight at the goal (a full step while it is farther
    than one), which the controller's action law makes exact once it is in range."""

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        tcp = self.layout.read(obs["observation"], "tcp_position")
        return self.move_towards(tcp, np.asarray(obs["desired_goal"], dtype=np.float64))
