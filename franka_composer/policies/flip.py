"""Flip expert: tip the right face up, then turn the cube about z to the goal's yaw.

The hand is held top-down with a fixed yaw, so it cannot hold the cube in a general
orientation: the cube can only be brought to rest flat on a face, at any yaw. The task's
goals are such orientations (`OrientationGoal`); given panda-gym's uniform goals
(orientation_goal="uniform") the expert aims at the nearest resting orientation, which is
within the success angle of the goal in only ~6 % of episodes:

1. The face to end up on top is the one whose normal the goal points most nearly up.
2. Tipping: a push near the top edge of the face opposite the push (slowly: faster or
   deeper pushes tip it twice) turns that face to the top. A face sideways is tipped up in
   one push, a face down first to the side.
3. Turning: pushing a side face off its centre, low (so the cube slides and turns rather
   than tips), from the side that drives the cube back towards the middle of the object
   square, until the yaw matches.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np

from franka_composer.policies.base import Expert
from franka_composer.tasks.records import BlockSpec

#: Fingertips this far (m) below the cube's top edge when tipping it, and the tipping push's
#: speed (fraction of a full step): measured to tip the 4 cm cube once (deeper or faster
#: pushes tip it twice).
TIP_DEPTH = 0.004
TIP_SPEED = 0.2
#: Distance (m) from the cube's centre to the TCP, horizontally, where a push starts: half
#: the cube, the closed fingers' half-thickness, and a gap.
PUSH_OFFSET = 0.042
#: Height (m) of the fingertips above the floor while turning the cube: low, so it turns.
TURN_HEIGHT = 0.006
#: Sideways offset (m) of the turning push from the face's centre, near its corner (nearer
#: the centre the cube slides more than it turns), and the push's speed.
TURN_OFFSET = 0.018
TURN_SPEED = 0.25
#: Yaw error (rad) at which the expert stops turning: well inside the 0.2 rad of success.
YAW_TOLERANCE = 0.06
#: How far (m) the hand backs away from the cube as it rises after a push, so that it does
#: not drag the cube up with it.
RETREAT = 0.03
#: The longest push (m) before the hand goes round again.
MAX_PUSH = 0.08
#: Height (m) of the TCP while it travels around the cube.
TRAVEL_HEIGHT = 0.1
#: How close (m) the TCP must be to a push's start before pushing.
POSITION_TOLERANCE = 0.004
#: How far (m) off the start, horizontally, a lowered TCP may be and still close in on it
#: rather than rise and come down again.
APPROACH_TOLERANCE = 0.012


def _axes(quaternion) -> np.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z): body axes as columns."""
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quaternion, dtype=np.float64))
    return matrix.reshape(3, 3)


def _levelled_yaw(matrix: np.ndarray, index: int, sign: float) -> float:
    """The heading (rad) of an orientation once body axis `index` (times `sign`) is turned
    straight up by the smallest rotation: the angle of the next body axis in the floor."""
    levelled = _flat_frame(matrix, index, sign) @ matrix
    other = levelled[:, (index + 1) % 3]
    return float(np.arctan2(other[1], other[0]))


class FlipExpert(Expert):
    """Tips, then turns; each step decided afresh from the observation."""

    def reset(self) -> None:
        # The push under way: (its start, its direction xy).
        self._pushing: tuple[np.ndarray, np.ndarray] | None = None

    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        vector = np.asarray(obs["observation"], dtype=np.float64)
        tcp = self.layout.read(vector, "tcp_position")
        cube = self.layout.read(vector, "object_position")
        current = _axes(self.layout.read(vector, "object_orientation"))
        goal = _axes(obs["desired_goal"])
        spec = self.config.objects[0]
        assert isinstance(spec, BlockSpec)
        half = spec.half_size
        below_tcp = 0.0073  # The closed fingertips below the TCP (m).
        # The body axis (a column index and sign) the goal points most nearly up.
        index = int(np.argmax(np.abs(goal[2])))
        sign = np.sign(goal[2, index])
        up = sign * current[:, index]  # Where that face's normal points now.
        if up[2] > 0.9:
            # The right face is up: turn about z until the yaw matches the goal's.
            error = _wrap(_levelled_yaw(goal, index, sign)
                          - _levelled_yaw(current, index, sign))
            if abs(error) < YAW_TOLERANCE:
                self._pushing = None
                return np.array([*self.move_towards(tcp, [*tcp[:2], TRAVEL_HEIGHT]), -1.0])
            return self._turn(tcp, cube, current, error, below_tcp)
        if up[2] > -0.5:  # Sideways, or on its way up: keep pushing the same way.
            horizontal = up[:2] / np.linalg.norm(up[:2])
        else:  # Face down: tip it to a side first (any side: towards +x here).
            horizontal = np.array([-1.0, 0.0])
        # Push from the side the face looks to, towards the other side, near the top edge.
        start = np.array([*(cube[:2] + horizontal * PUSH_OFFSET),
                          cube[2] + half - TIP_DEPTH + below_tcp])
        return self._push(tcp, cube, start, -horizontal, TIP_SPEED)

    def _turn(self, tcp, cube, current, error, below_tcp) -> np.ndarray:
        # Push, off its centre, the side face that looks most away from the middle of the
        # object square: the cube slides back towards it rather than out of reach.
        faces = [current[:2, i] * s for i in range(3) for s in (1, -1)
                 if abs(current[2, i]) < 0.5]
        away = cube[:2] - np.asarray(self.config.workspace.object_box.centre)
        normal = max(faces, key=lambda n: n @ away)
        normal = normal / np.linalg.norm(normal)
        tangent = np.array([-normal[1], normal[0]])  # z x normal.
        # Pushing into the face at +tangent turns the cube positively about z.
        offset = TURN_OFFSET * np.sign(error)
        start = np.array([*(cube[:2] + normal * PUSH_OFFSET + tangent * offset),
                          TURN_HEIGHT + below_tcp])
        return self._push(tcp, cube, start, -normal, TURN_SPEED)

    def _push(self, tcp, cube, start, direction, speed) -> np.ndarray:
        """Goes to `start` (around the cube, from above) and pushes along `direction` while
        the push still points the same way (the cube moves, and the start with it), for at
        most `MAX_PUSH`."""
        if self._pushing is not None:
            origin, pushing_direction = self._pushing
            moved = (tcp[:2] - origin[:2]) @ pushing_direction
            if pushing_direction @ direction > 0.9 and moved < MAX_PUSH:
                xy = pushing_direction * speed
                return np.array([*xy, (start[2] - tcp[2]) / self.config.control.max_tcp_step,
                                 -1.0])
            self._pushing = None
        if np.linalg.norm(tcp - start) < POSITION_TOLERANCE:
            self._pushing = (start, direction)
            return np.array([*self.move_towards(tcp, start), -1.0])
        off = np.linalg.norm(tcp[:2] - start[:2])
        if off < POSITION_TOLERANCE or (off < APPROACH_TOLERANCE
                                        and tcp[2] < TRAVEL_HEIGHT - 0.02):
            # Down onto the start, correcting on the way: a hand that lags its target
            # (osc) lands a few millimetres off and would otherwise go round again.
            return np.array([*self.move_towards(tcp, start), -1.0])
        if tcp[2] < TRAVEL_HEIGHT - 0.02:
            back = tcp[:2] - cube[:2]
            back = tcp[:2] + RETREAT * back / max(np.linalg.norm(back), 1e-9)
            return np.array([*self.move_towards(tcp, [*back, TRAVEL_HEIGHT]), -1.0])
        return np.array([*self.move_towards(tcp, [*start[:2], TRAVEL_HEIGHT]), -1.0])


def _flat_frame(matrix: np.ndarray, index: int, sign: float) -> np.ndarray:
    """The smallest rotation that turns body axis `index` (times `sign`) of `matrix`
    straight up (Rodrigues' formula)."""
    axis = sign * matrix[:, index]
    cross = np.cross(axis, [0.0, 0.0, 1.0])
    sine, cosine = np.linalg.norm(cross), axis[2]
    if sine < 1e-9:
        return np.eye(3)
    k = cross / sine
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sine * skew + (1 - cosine) * skew @ skew


def _wrap(angle: float) -> float:
    return float((angle + np.pi) % (2 * np.pi) - np.pi)
