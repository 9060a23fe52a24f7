"""What every scripted expert shares: reading the public observation, steering the hand.

Experts see only what a learner sees, the Gymnasium observation dict, and read its
`observation` vector by field name through the env's `ObservationLayout` (a dm_env
observation is flattened to it, and in the pixel modes the state is read through the task:
`observations.ExpertInput`); they know the
task's configuration (object sizes, the action scale) as its author would, and turn
targets into actions with the controller's own inverse (`ControlSettings.tcp_action`).
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from franka_composer.policies.observations import ExpertInput
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.layout import ObservationLayout


@dataclasses.dataclass(frozen=True)
class Scene:
    """The quantities an expert plans with, read from one observation (m, world frame)."""

    tcp: np.ndarray
    object_position: np.ndarray
    object_velocity: np.ndarray  # m per control step
    goal: np.ndarray
    finger_width: float | None  # None when the fingers are locked closed

    @classmethod
    def read(cls, obs: Mapping[str, Any], layout: ObservationLayout) -> "Scene":
        vector = np.asarray(obs["observation"], dtype=np.float64)
        return cls(
            tcp=layout.read(vector, "tcp_position"),
            object_position=layout.read(vector, "object_position"),
            object_velocity=layout.read(vector, "object_linear_velocity"),
            goal=np.asarray(obs["desired_goal"], dtype=np.float64),
            finger_width=(float(layout.read(vector, "finger_width")[0])
                          if "finger_width" in layout else None),
        )


def unit(vector: np.ndarray) -> np.ndarray:
    """`vector` scaled to length 1 (a zero vector points along +x)."""
    norm = np.linalg.norm(vector)
    return vector / norm if norm > 1e-9 else np.eye(len(vector))[0]


class Expert(abc.ABC):
    """A scripted policy for one task's env: `reset()` at each episode start, then
    `expert(obs) -> action`, `obs` as the env returned it. Built by `make_expert(env)`;
    `expert_input` turns observations into the goal dict `act` reads (by default only
    Gymnasium goal dicts with the state; `make_expert` gives one that reads dm_env's and
    the pixel modes' too)."""

    def __init__(self, layout: ObservationLayout, config: TaskConfig,
                 expert_input: ExpertInput | None = None) -> None:
        self.layout, self.config = layout, config
        self._input = expert_input or ExpertInput(layout)
        #: Length of the action vector: dx, dy, dz (and the gripper where it is actuated).
        self.action_size = config.control.action_size
        self.reset()

    def reset(self) -> None:
        """Forgets the previous episode's plan."""

    def scene(self, obs: Mapping[str, Any]) -> Scene:
        return Scene.read(obs, self.layout)

    def move_towards(self, tcp: np.ndarray, target, max_speed: float = 1.0) -> np.ndarray:
        """The position part of an action towards `target` (`ControlSettings.tcp_action`)."""
        return self.config.control.tcp_action(tcp, target, max_speed)

    def __call__(self, obs: Mapping[str, Any]) -> np.ndarray:
        action = np.zeros(self.action_size)
        action[:] = self.act(self._input(obs))
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    @abc.abstractmethod
    def act(self, obs: Mapping[str, Any]) -> np.ndarray:
        """The unclipped action for the goal dict `obs` ("observation", "desired_goal")."""
