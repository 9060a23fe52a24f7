"""Slide expert: strike the puck once towards the goal, hard enough to pass through it, wait.

The goal is often out of the arm's reach, so the puck must glide there. Two facts about the
hand drive the strike (both measured through the public interface, see the constants):

- The hand moves in jerks: each control step the TCP races to its new target within a few
  milliseconds, so a puck touched by a moving finger leaves at the jerk's peak speed, not
  the average. A single step from rest against the puck is therefore a repeatable kick
  whose length sets the puck's speed.
- A puck leaves along the contact normal. Striking with a corner of the closed fingers
  (a box of half-size `FINGER_HALF_SIZE` around the TCP) lets the normal point anywhere.

On the slippery floor (friction 0.04) the puck then glides v^2 / (2 * 0.04 * 9.81) metres.
Success counts as soon as the puck passes within the success radius, so the expert aims past
the goal by `OVERSHOOT` rather than risk stopping short.
"""

from __future__ import annotations

import numpy as np

from franka_composer.policies.base import Expert

#: Half-size (m) of the closed fingers seen from above (x, y), from where they first touch
#: the puck approached from each direction.
FINGER_HALF_SIZE = np.array([0.0094, 0.0256])
#: TCP height (m) while striking: the fingertips hit the puck's lower half and the hand
#: (0.039 m above the TCP, wide in y) passes over the puck's top at 0.06 m.
STRIKE_HEIGHT = 0.025
#: Height (m) at which the hand travels over the puck.
TRAVEL_HEIGHT = 0.1
#: Gap (m) left between finger and puck before the kick.
GAP = 0.002
#: How close (m) the TCP must be to the strike point before kicking.
POSITION_TOLERANCE = 0.002
#: Metres past the goal the strike aims for: passing through the goal succeeds.
OVERSHOOT = 0.1
#: Kick size to glide distance: distance = GLIDE_GAIN^2 * f(angle) * (kick - DEAD_KICK)^2,
#: with the kick a fraction of a full step, fitted to strikes straight along +x.
GLIDE_GAIN = 1.69
DEAD_KICK = 0.061
#: Strike angle (deg, world x axis = 0) -> how far the puck glides relative to a strike
#: along +x.
GLIDE_ANGLES = (-70.0, -45.0, -28.0, -26.0, -10.0, 0.0, 20.0, 40.0, 50.0, 70.0)
GLIDE_FACTORS = (0.72, 0.75, 0.75, 0.9, 0.97, 1.0, 0.92, 0.84, 0.77, 0.72)
#: Strike angle (deg) -> degrees the puck's path turns from the strike direction, in pieces
#: (strike angles, turns) measured with 3 to 4 seeds each. The finger corner that meets the puck
#: changes between pieces, and the turn with it: no strike sends the puck along paths between
#: -32 and -23 degrees, or -3.6 and -0.6 (the nearest reachable path is used), and strikes at the
#: changes themselves go either way, so the pieces stop short of them. A strike at exactly 0
#: meets the flat front of the fingers.
PATH_TURN_PIECES = (
    ((-75.0, -55.0, -40.0, -28.5), (-3.5, -2.5, -3.2, -3.4)),
    ((-26.5, -22.5, -20.0, -15.0, -10.0, -7.5, -5.0, -0.5),
     (3.5, 3.0, 2.0, 0.9, 0.4, -0.6, -3.0, -3.1)),
    ((0.0,), (-0.6,)),
    ((0.5, 5.0, 20.0, 40.0, 55.0, 75.0), (0.8, 0.9, 0.7, 0.6, 0.9, 1.6)),
)


class SlideExpert(Expert):
    """Lines a finger corner up behind the puck, kicks once, steps back and waits; strikes
    again if the puck comes to rest short of the goal."""

    def reset(self) -> None:
        self._waiting = False

    def act(self, obs: dict) -> np.ndarray:
        scene = self.scene(obs)
        puck, tcp = scene.object_position, scene.tcp
        if self._waiting:
            self._waiting = np.linalg.norm(scene.object_velocity[:2]) > 1e-4
            return self.move_towards(tcp, [*tcp[:2], TRAVEL_HEIGHT])
        to_goal = scene.goal[:2] - puck[:2]
        strike_angle = _strike_angle(np.degrees(np.arctan2(to_goal[1], to_goal[0])))
        direction = np.array([np.cos(np.radians(strike_angle)), np.sin(np.radians(strike_angle))])
        corner = FINGER_HALF_SIZE * np.sign(direction)
        radius = self.config.objects[0].radius
        start = np.array([*(puck[:2] - direction * (radius + GAP) - corner), STRIKE_HEIGHT])
        if np.linalg.norm(tcp - start) < POSITION_TOLERANCE:
            self._waiting = True
            distance = np.linalg.norm(to_goal) + OVERSHOOT
            glide = GLIDE_GAIN * np.sqrt(np.interp(strike_angle, GLIDE_ANGLES, GLIDE_FACTORS))
            return np.array([*direction * (DEAD_KICK + np.sqrt(distance) / glide), 0.0])
        if np.linalg.norm(tcp[:2] - start[:2]) < POSITION_TOLERANCE:
            return self.move_towards(tcp, start)
        if tcp[2] < TRAVEL_HEIGHT - 0.02 and np.linalg.norm(tcp[:2] - puck[:2]) < 0.1:
            return self.move_towards(tcp, [*tcp[:2], TRAVEL_HEIGHT])  # Lift clear of the puck.
        return self.move_towards(tcp, [*start[:2], TRAVEL_HEIGHT])


def _reachable_strikes() -> tuple[np.ndarray, np.ndarray]:
    """Strike angles sampled every 0.1 degree within each piece, and the paths they give."""
    strikes, paths = [], []
    for angles, turns in PATH_TURN_PIECES:
        sampled = np.arange(angles[0], angles[-1] + 0.05, 0.1)
        strikes.append(sampled)
        paths.append(sampled + np.interp(sampled, angles, turns))
    return np.concatenate(strikes), np.concatenate(paths)


_STRIKES, _PATHS = _reachable_strikes()


def _strike_angle(path_angle: float) -> float:
    """The strike direction (deg) whose puck path comes closest to `path_angle` (deg)."""
    return float(_STRIKES[np.argmin(np.abs(_PATHS - path_angle))])
