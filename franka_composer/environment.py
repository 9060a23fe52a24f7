"""A `composer.Environment` that runs a control step's physics substeps in one MuJoCo call.

Composer's `step` loops over substeps in Python, calling substep hooks and the observation
updater each time. When no hook needs to run between substeps and every observable is
sampled once per control step (the default schedule), that loop only costs time: this
environment then calls `physics.step(n_sub_steps)` once, which MuJoCo runs in C, and falls
back to Composer's loop otherwise. Both paths produce the same states, bit for bit
(`tests/test_environment.py`).
"""

from __future__ import annotations

import dm_env
from absl import logging
from dm_control import composer
from dm_control.composer.environment import _callable_is_trivial
from dm_control.rl import control


class Environment(composer.Environment):
    """Composer's environment with the substep loop batched where nothing observes it."""

    def _can_batch_substeps(self) -> bool:
        hooks = self._hooks
        for name in ("before_substep", "after_substep"):
            if not _callable_is_trivial(getattr(self._task, name)):
                return False
            hook = getattr(hooks, "_" + name)
            if hook.entity_hooks or hook.extra_hooks:
                return False
        updater = self._observation_updater
        return all(
            enabled.update_interval == 1 and enabled.delay == 0
            and enabled.buffer_size < self._n_sub_steps
            for enabled in updater._enabled_list  # pylint: disable=protected-access
        )

    def reset(self) -> dm_env.TimeStep:
        timestep = super().reset()
        self._batch_substeps = self._can_batch_substeps()
        return timestep

    def step(self, action) -> dm_env.TimeStep:
        if self._reset_next_step or not getattr(self, "_batch_substeps", False):
            return super().step(action)
        self._hooks.before_step(self._physics_proxy, action, self._random_state)
        updater = self._observation_updater
        updater.prepare_for_next_control_step()
        try:
            self._physics.step(self._n_sub_steps)
            physics_is_divergent = False
        except control.PhysicsError as error:
            if self._raise_exception_on_physics_error:
                raise
            logging.warning(error)
            physics_is_divergent = True
        # Observables are due only on the last substep: skip the counter to it.
        updater._step_counter += self._n_sub_steps - 1  # pylint: disable=protected-access
        self._hooks.after_step(self._physics_proxy, self._random_state)
        updater.update()
        return self._make_timestep(physics_is_divergent)

    def _make_timestep(self, physics_is_divergent: bool) -> dm_env.TimeStep:
        if physics_is_divergent:
            reward, discount, terminating = 0.0, 0.0, True
        else:
            reward = self._task.get_reward(self._physics_proxy)
            discount = self._task.get_discount(self._physics_proxy)
            terminating = (self._task.should_terminate_episode(self._physics_proxy)
                           or self._physics.time() >= self._time_limit)
        obs = self._observation_updater.get_observation()
        if not terminating:
            return dm_env.TimeStep(dm_env.StepType.MID, reward, discount, obs)
        self._reset_next_step = True
        return dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, obs)
