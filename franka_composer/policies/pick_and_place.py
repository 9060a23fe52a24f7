"""Pick-and-place expert: open above the block, descend, close, lift, carry to the goal, hold."""

from __future__ import annotations

import numpy as np

from franka_composer.policies.base import Expert

#: Height (m) above the block's centre at which the open hand lines up before descending.
HOVER_HEIGHT = 0.08
#: TCP height (m) relative to the block's centre when grasping: the fingertips reach below
#: the centre so the pads hold the block squarely.
GRASP_DEPTH = -0.005
#: Finger widths (m, as observed): fully open, and the range that means "holding the 4 cm
#: block" (a held block reads about 0.04 once the squeeze settles, 0.03 just after closing).
OPEN_WIDTH = 0.075
HOLDING_WIDTHS = (0.02, 0.045)
#: Control steps the gripper keeps closing at the block before lifting.
CLOSING_STEPS = 3
#: Lowest height (m) of the block's centre while it is carried towards the goal.
CARRY_HEIGHT = 0.05
#: Carrying speed (fraction of a full step): quicker swings make the 1 kg block slip.
CARRY_SPEED = 0.7
#: How far (m) the block may sit from where the hand holds it and still count as held.
HOLD_TOLERANCE = 0.025


class PickAndPlaceExpert(Expert):
    """A small state machine driven by what it observes each step, so a dropped block is
    simply picked up again."""

    def reset(self) -> None:
        self._closing_steps = 0

    def act(self, obs: dict) -> np.ndarray:
        scene = self.scene(obs)
        return self.fetch(scene.tcp, scene.finger_width, scene.object_position, scene.goal)

    def fetch(self, tcp: np.ndarray, width: float, block: np.ndarray, goal: np.ndarray,
              carry_height: float = CARRY_HEIGHT) -> np.ndarray:
        """The action that grasps `block` (or carries it, once held) to `goal`, its centre
        no lower than `carry_height` on the way (m, world frame)."""
        block_in_hand = np.linalg.norm(block - tcp + [0, 0, GRASP_DEPTH]) < HOLD_TOLERANCE
        if block_in_hand and HOLDING_WIDTHS[0] < width < HOLDING_WIDTHS[1]:
            if self._closing_steps >= CLOSING_STEPS:
                return np.array([*self._carry(tcp, block, goal, carry_height), -1.0])
            self._closing_steps += 1
            return np.array([0.0, 0.0, 0.0, -1.0])
        self._closing_steps = 0
        grasp = block + [0, 0, GRASP_DEPTH]
        hover = block + [0, 0, HOVER_HEIGHT]
        if np.linalg.norm(tcp[:2] - block[:2]) > 0.01:
            # Rise before moving sideways if the hand is low, so it does not hit the block.
            target = hover if tcp[2] > block[2] + 0.03 else [*tcp[:2], hover[2]]
            return np.array([*self.move_towards(tcp, target), 1.0])
        if width < OPEN_WIDTH:
            return np.array([*self.move_towards(tcp, [*block[:2], max(tcp[2], hover[2])]), 1.0])
        if tcp[2] - grasp[2] > 0.005:
            return np.array([*self.move_towards(tcp, grasp), 1.0])
        return np.array([*self.move_towards(tcp, grasp), -1.0])

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
