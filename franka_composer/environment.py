"""The environment `franka_composer.load` returns: Composer's, changed only through its public
surface. `fast_path.FastEnvironment` is the same environment, faster, where the installed
dm_control has what it needs; this one is the stock path it falls back to.

Three things differ from plain `composer.Environment`:
- A closed environment says so: `close()` twice is harmless, and `reset`, `step` or
  `physics` afterwards raise `EnvironmentClosedError` (Composer fails deep inside).
- A step whose physics diverged gets the task's reward for the state it reports (MuJoCo
  has reset it), not Composer's fixed 0.0, which for a sparse task is the reward for
  reaching the goal. Like dm_control, a step diverged when MuJoCo raised a new warning.
- Threads: a reset or step that renders camera observations from a thread other than the
  one that renders the environment raises `render_owner.RenderThreadError` before anything
  moves, and `close()` works from any thread.
"""

from __future__ import annotations

import dm_env
import numpy as np
from dm_control import composer

from franka_composer import render_owner


class EnvironmentClosedError(RuntimeError):
    """`reset`, `step` or `physics` used after `close()`."""


class GoalEnvironment(composer.Environment):
    """`composer.Environment` with clear errors once closed and the task's reward on a
    diverged step."""

    def __init__(self, task, **kwargs) -> None:
        super().__init__(task, **kwargs)
        self._closed = False
        # Its resets and steps render (camera observations), on one thread only.
        self._renders_observations = bool(getattr(task, "pixel_keys", ()))

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def physics(self):
        self._check_open()
        return super().physics

    def close(self) -> None:
        """Frees the physics, from any thread; closing again is harmless."""
        if not self._closed:
            render_owner.release(self, super().physics)
            super().close()
            self._closed = True

    def reset(self) -> dm_env.TimeStep:
        self._check_can_step()
        return super().reset()

    def step(self, action) -> dm_env.TimeStep:
        self._check_can_step()
        warnings = super().physics.data.warning.number.copy()
        timestep = super().step(action)
        if timestep.last() and diverged(super().physics, warnings):
            timestep = timestep._replace(reward=self.task.get_reward(super().physics))
        return timestep

    def _check_can_step(self) -> None:
        """Open, and on the thread that renders it if its observations are images."""
        self._check_open()
        if self._renders_observations:
            render_owner.claim(self)

    def _check_open(self) -> None:
        if self._closed:
            raise EnvironmentClosedError(
                "this environment is closed (close() freed its physics): make a new one")


def diverged(physics, warnings_before: np.ndarray) -> bool:
    """Whether MuJoCo raised a warning since `warnings_before` (its warning counters), which
    is when dm_control takes the physics to have diverged."""
    return bool((physics.data.warning.number > warnings_before).any())
