"""Stack expert: pick-and-place block 1 onto its goal, release it, then block 2 on top."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from franka_composer.policies.pick_and_place import PickAndPlaceExpert

#: How close (m) a block's centre must be to its goal to count as placed: then it is
#: released and the next block fetched.
PLACED = 0.012
#: Room (m) kept under a carried block's centre above its goal height on the way, so block
#: 2 passes over block 1 (4 cm tall) without touching it.
CLEARANCE = 0.03
#: How far (m) the hand rises, open, once both blocks are placed.
RETREAT = 0.05
#: How much wider (m) than a block the fingers open, in place, before the hand leaves a
#: placed block: rising or moving off as they open lifted or dragged it off its goal.
LET_GO = 0.01


class StackExpert(PickAndPlaceExpert):
    """Works on the first block that is not yet at its goal, with pick and place's state
    machine; moving on to the next block opens the hand, which releases the placed one."""

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        vector = np.asarray(obs["observation"], dtype=np.float64)
        tcp = self.layout.read(vector, "tcp_position")
        width = float(self.layout.read(vector, "finger_width")[0])
        goals = np.asarray(obs["desired_goal"], dtype=np.float64).reshape(-1, 3)
        for index, goal in enumerate(goals):
            block = self.layout.read(vector, f"object{index + 1}_position")
            if np.linalg.norm(block - goal) > PLACED:
                return self.fetch(tcp, width, block, goal, carry_height=goal[2] + CLEARANCE)
            if width < self.block_width + LET_GO and self.in_hand(tcp, block):
                return np.array([0.0, 0.0, 0.0, 1.0])  # Placed: let go before leaving it.
        return np.array([*self.move_towards(tcp, tcp + [0.0, 0.0, RETREAT]), 1.0])
