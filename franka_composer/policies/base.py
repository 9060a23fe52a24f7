"""What every scripted expert shares: reading the public observation, steering the hand.

Experts see only what a learner sees: the Gymnasium observation dict. Its `observation`
vector is, in order (see `task.observation_fields`): tool-centre-point (TCP) position (m,
world frame), TCP velocity (m per control step), the finger width (m) when the gripper is
actuated, then the object's position, orientation, linear and angular velocity.
"""

from __future__ import annotations

import abc
import dataclasses

import numpy as np

#: Metres the TCP target moves per control step for an action component of 1.
MAX_TCP_STEP = 0.05


@dataclasses.dataclass(frozen=True)
class Scene:
    """The quantities an expert plans with, read from one observation (m, world frame)."""

    tcp: np.ndarray
    object_position: np.ndarray
    object_velocity: np.ndarray  # m per control step
    goal: np.ndarray
    finger_width: float | None  # None when the fingers are locked closed

    @classmethod
    def read(cls, obs: dict, with_finger_width: bool) -> "Scene":
        vector = np.asarray(obs["observation"], dtype=np.float64)
        start = 7 if with_finger_width else 6
        return cls(
            tcp=vector[0:3],
            object_position=vector[start:start + 3],
            object_velocity=vector[start + 6:start + 9],
            goal=np.asarray(obs["desired_goal"], dtype=np.float64),
            finger_width=float(vector[6]) if with_finger_width else None,
        )


def move_towards(tcp: np.ndarray, target: np.ndarray, max_speed: float = 1.0) -> np.ndarray:
    """The TCP part of an action that reaches `target` in one step when it is close enough,
    else moves straight towards it at `max_speed` (a fraction of the full step)."""
    step = (np.asarray(target) - tcp) / MAX_TCP_STEP
    norm = np.linalg.norm(step)
    if norm > max_speed:
        step *= max_speed / norm
    return step


def unit(vector: np.ndarray) -> np.ndarray:
    """`vector` scaled to length 1 (a zero vector points along +x)."""
    norm = np.linalg.norm(vector)
    return vector / norm if norm > 1e-9 else np.eye(len(vector))[0]


class Expert(abc.ABC):
    """A scripted policy: `reset()` at each episode start, then `expert(obs) -> action`."""

    #: Length of the action vector: dx, dy, dz (and the gripper for pick and place).
    action_size = 3

    def reset(self) -> None:
        """Forgets the previous episode's plan."""

    def __call__(self, obs: dict) -> np.ndarray:
        action = np.zeros(self.action_size)
        action[:] = self.act(obs)
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    @abc.abstractmethod
    def act(self, obs: dict) -> np.ndarray:
        """The unclipped action for `obs`."""
