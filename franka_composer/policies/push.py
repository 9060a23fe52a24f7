"""Push expert: get behind the block, low, on the far side from the goal, and push it there."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from franka_composer.policies.base import Expert, unit

#: Height (m) of the TCP while pushing: the closed fingertips (6 mm below the TCP) skim the
#: floor and meet the block's lower half, which keeps it from tipping over.
PUSH_HEIGHT = 0.012
#: Height (m) at which the hand travels over the block without touching it (top at 0.04 m).
TRAVEL_HEIGHT = 0.08
#: Distance (m) from the block centre to where the TCP descends, behind the block: clear of
#: it whichever side of the closed fingers (up to 0.026 m from the TCP) faces it.
APPROACH_OFFSET = 0.065
#: Pushing speed (fraction of a full step): faster pushes make the 1 kg block hop and tumble.
PUSH_SPEED = 0.35
#: Slowest push (fraction of a full step), used when the block is almost at the goal.
MIN_PUSH_SPEED = 0.15
#: How far (m) the hand may stray sideways from the block-goal line before re-approaching.
MAX_SIDEWAYS = 0.02


class PushExpert(Expert):
    """Approaches over the top, descends behind the block, then pushes it along the line to
    the goal, steering sideways to stay behind its centre; re-approaches when it gets away."""

    def reset(self) -> None:
        self._pushing = False

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        scene = self.scene(obs)
        block, tcp = scene.object_position, scene.tcp
        to_goal = scene.goal[:2] - block[:2]
        direction = unit(to_goal)
        sideways_axis = np.array([-direction[1], direction[0]])
        offset = tcp[:2] - block[:2]
        along, sideways = offset @ direction, offset @ sideways_axis
        self._pushing = (self._pushing and along < -0.015 and abs(sideways) < MAX_SIDEWAYS
                         and tcp[2] < PUSH_HEIGHT + 0.02)
        if self._pushing:
            # Move along the line to the goal while steering back onto the line through the
            # block's centre: the line is recomputed each step, so a drifting block is followed.
            speed = np.clip(np.linalg.norm(to_goal) / 0.1 * PUSH_SPEED, MIN_PUSH_SPEED, PUSH_SPEED)
            # The action law inverted (`ControlSettings.tcp_action`) for the corrections.
            step = self.config.control.max_tcp_step
            xy = direction * speed - sideways_axis * sideways / step
            return np.array([*xy, (PUSH_HEIGHT - tcp[2]) / step])
        start = np.array([*(block[:2] - direction * APPROACH_OFFSET), PUSH_HEIGHT])
        if np.linalg.norm(tcp[:2] - start[:2]) < 0.01:
            self._pushing = tcp[2] < PUSH_HEIGHT + 0.005
            return self.move_towards(tcp, start)
        if tcp[2] < TRAVEL_HEIGHT - 0.02 and np.linalg.norm(offset) < APPROACH_OFFSET + 0.03:
            return self.move_towards(tcp, [*tcp[:2], TRAVEL_HEIGHT])  # Lift clear of the block.
        return self.move_towards(tcp, [*start[:2], TRAVEL_HEIGHT])
