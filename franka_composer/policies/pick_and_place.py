"""Pick-and-place expert: open above the block, descend, close, lift, carry to the goal, hold."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from franka_composer.entities.panda import MAX_FINGER_WIDTH
from franka_composer.policies.base import Expert
from franka_composer.tasks.records import BlockSpec

#: Height (m) above the block's centre at which the open hand lines up before descending.
HOVER_HEIGHT = 0.08
#: TCP height (m) relative to the block's centre when grasping: the fingertips reach below
#: the centre so the pads hold the block squarely.
GRASP_DEPTH = -0.005
#: Finger width (m, as observed) the hand opens to before it descends.
OPEN_WIDTH = 0.075
#: The finger widths (m) that mean "holding the block", about its width: a held 4 cm block
#: reads about 0.04 once the squeeze settles, 0.03 just after closing.
HOLDING_BELOW, HOLDING_ABOVE = 0.02, 0.005
#: Control steps the gripper keeps closing at the block before lifting.
CLOSING_STEPS = 3
#: Lowest height (m) of the block's centre while it is carried towards the goal.
CARRY_HEIGHT = 0.05
#: Carrying speed (fraction of a full step): quicker swings make the 1 kg block slip.
CARRY_SPEED = 0.7
#: How far (m) the block may sit from where the hand holds it and still count as held.
HOLD_TOLERANCE = 0.025
#: How much (m) the fingers must have closed in a step to count as still closing.
STILL_CLOSING = 0.002


class PickAndPlaceExpert(Expert):
    """A small state machine driven by what it observes each step, so a dropped block is
    simply picked up again."""

    def reset(self) -> None:
        self._closing_steps = 0
        #: The finger width when the fingers were last told to close on the block; None
        #: when they are not closing on it.
        self._closing_from: float | None = None

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        scene = self.scene(obs)
        assert scene.finger_width is not None
        return self.fetch(scene.tcp, scene.finger_width, scene.object_position, scene.goal)

    def fetch(self, tcp: np.ndarray, width: float, block: np.ndarray, goal: np.ndarray,
              carry_height: float = CARRY_HEIGHT) -> np.ndarray:
        """The action that grasps `block` (or carries it, once held) to `goal`, its centre
        no lower than `carry_height` on the way (m, world frame)."""
        across = self.block_width
        if self.in_hand(tcp, block) and across - HOLDING_BELOW < width < across + HOLDING_ABOVE:
            if self._closing_steps >= CLOSING_STEPS:
                return np.array([*self._carry(tcp, block, goal, carry_height), -1.0])
            self._closing_steps += 1
            return np.array([0.0, 0.0, 0.0, -1.0])
        self._closing_steps = 0
        grasp = block + [0, 0, GRASP_DEPTH]
        hover = block + [0, 0, HOVER_HEIGHT]
        closing, self._closing_from = self._closing_from, None
        if (closing is not None and across + HOLDING_ABOVE <= width < closing - STILL_CLOSING
                and np.linalg.norm(tcp[:2] - block[:2]) <= 0.01):
            # Fingers whose target closes by less than the open hand's width a step (a
            # max_finger_step below 0.08 m) may still be on their way to the block: not a
            # miss to open again for.
            self._closing_from = width
            return np.array([*self.move_towards(tcp, grasp), -1.0])
        if np.linalg.norm(tcp[:2] - block[:2]) > 0.01:
            # Rise before moving sideways if the hand is low, so it does not hit the block.
            target = hover if tcp[2] > block[2] + 0.03 else [*tcp[:2], hover[2]]
            return np.array([*self.move_towards(tcp, target), 1.0])
        if width < OPEN_WIDTH:
            return np.array([*self.move_towards(tcp, [*block[:2], max(tcp[2], hover[2])]), 1.0])
        if tcp[2] - grasp[2] > 0.005:
            return np.array([*self.move_towards(tcp, grasp), 1.0])
        if self.config.control.max_finger_step < MAX_FINGER_WIDTH:  # It may take some.
            self._closing_from = width
        return np.array([*self.move_towards(tcp, grasp), -1.0])

    @property
    def block_width(self) -> float:
        """Every block's width (m): one option sets them all."""
        block = self.config.objects[0]
        assert isinstance(block, BlockSpec)
        return 2 * block.half_size

    @staticmethod
    def in_hand(tcp: np.ndarray, block: np.ndarray) -> bool:
        """Whether `block` sits where the hand holds the block it grasps."""
        return bool(np.linalg.norm(block - tcp + [0, 0, GRASP_DEPTH]) < HOLD_TOLERANCE)

    def _carry(self, tcp: np.ndarray, block: np.ndarray, goal: np.ndarray,
               carry_height: float) -> np.ndarray:
        """Moves the block (not the TCP: the block may sit off-centre in the hand) up off the
        floor, then over to the goal at a pace the grip holds, then down onto it."""
        target = goal.copy()
        if np.linalg.norm(goal[:2] - block[:2]) > 0.02:
            target[2] = max(goal[2], carry_height)
            if block[2] < target[2] - 0.01:
                target[:2] = block[:2]  # Lift straight up first: dragging tilts the block.
        return self.move_towards(tcp, tcp + target - block, max_speed=CARRY_SPEED)
