"""A `composer.Environment` that runs a control step's physics substeps in one MuJoCo call.

Composer's `step` loops over substeps in Python, calling substep hooks and the observation
updater each time. When no hook needs to run between substeps and every observable is
sampled once per control step (the default schedule), that loop only costs time: this
environment then calls `physics.step(n_sub_steps)` once, which MuJoCo runs in C, and falls
back to Composer's loop otherwise. Both paths produce the same states, bit for bit
(`tests/test_environment.py`).

More costs go the same way (measured in BENCHMARKS.md):
- When every observable is read once per control step with no delay, buffer or aggregator
  (the default), the step calls the observables directly instead of scheduling them through
  Composer's observation buffers: same values, a fraction of the Python time.
- A state or control written through a binding before the step (by a user's hook, say)
  leaves dm_control's physics "dirty", so the first binding read after the step would run
  an extra `mj_forward`; the step's own closing `mj_step1` has already brought positions
  and velocities up to date, so the flag is cleared instead (same trajectories and
  observations, bit for bit). (Our controller writes through MjData views and marks
  nothing dirty.)
- Composer compiles the MJCF a second time on the first reset, for `initialize_episode_mjcf`
  hooks; none of ours has one, so the model compiled in `__init__` is kept.
- The model is compiled through `model_cache.compile_physics`, which reads a compiled
  model saved by an earlier process when there is one.
- The substeps run in one fused call (`_step_physics`): dm_control's own `Physics.step`
  does the same MuJoCo calls with ~15 us more Python around them.
"""

from __future__ import annotations

import dm_env
import mujoco
import numpy as np
from absl import logging
from dm_control import composer
from dm_control.composer.environment import _callable_is_trivial
from dm_control.rl import control

from franka_composer.model_cache import compile_physics

_RK4 = mujoco.mjtIntegrator.mjINT_RK4.value


class EnvironmentClosedError(RuntimeError):
    """`reset`, `step` or `physics` used after `close()`."""


class Environment(composer.Environment):
    """Composer's environment with the substep loop batched where nothing observes it."""

    def close(self) -> None:
        """Frees the physics; closing again is harmless, anything else after it raises
        `EnvironmentClosedError`."""
        if self._physics is not None:
            super().close()

    @property
    def closed(self) -> bool:
        return self._physics is None

    @property
    def physics(self):
        self._check_open()
        return super().physics

    def _check_open(self) -> None:
        if self._physics is None:
            raise EnvironmentClosedError(
                "this environment is closed (close() freed its physics): make a new one")

    def __init__(self, task, **kwargs) -> None:
        super().__init__(task, **kwargs)
        if not self._has_mjcf_hooks():
            # The model compiled above is the one the first reset would compile again.
            self._mjcf_never_compiled = False

    def _recompile_physics(self) -> None:
        physics = getattr(self, "_physics", None)
        if physics:
            physics.free()
        self._physics = compile_physics(self._task.root_entity.mjcf_model)
        self._physics.legacy_step = self._legacy_step

    def _has_mjcf_hooks(self) -> bool:
        if self._recompile_mjcf_every_episode:
            return True
        if not _callable_is_trivial(self._task.initialize_episode_mjcf):
            return True
        hook = self._hooks._initialize_episode_mjcf  # pylint: disable=protected-access
        return bool(hook.entity_hooks or hook.extra_hooks)

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

    def _direct_observables(self) -> list | None:
        """(name, callable) per observable when each is simply read at the end of the step
        (Composer's buffer would hold exactly that one value); None otherwise."""
        updater = self._observation_updater
        structure = updater._enabled_structure  # pylint: disable=protected-access
        if not isinstance(structure, dict):
            return None
        direct = []
        for name, enabled in structure.items():
            if enabled.buffer_size != 1 or enabled.observable.aggregator is not None:
                return None
            direct.append((name, enabled.observation_callable))
        return direct

    def _observables_signature(self) -> tuple:
        """Everything Composer's updater is built from at a reset: which observables are
        enabled and how each is scheduled. Users may change these between episodes."""
        # pylint: disable-next=protected-access
        return tuple(
            (name, o.enabled, o.update_interval, o.delay, o.buffer_size, o.aggregator,
             o.corruptor)
            for name, o in self._observation_updater._observables.items())

    def _reset_attempt(self) -> dm_env.TimeStep:
        if (getattr(self, "_direct", None) is None or self._mjcf_never_compiled
                or self._recompile_mjcf_every_episode or not self._can_batch_substeps()
                or self._observables_signature() != self._signature):
            self._updater_rebuilt = True
            return super()._reset_attempt()
        # Composer's reset without rebuilding the observation updater (a quarter of a
        # reset): while observables are read directly its buffers are never used.
        if self._fixed_initial_state:
            self._random_state.set_state(self._fixed_random_state)
        with self._physics.reset_context():
            self._hooks.initialize_episode(self._physics_proxy, self._random_state)
        self._reset_next_step = False
        return dm_env.TimeStep(dm_env.StepType.FIRST, None, None, self._read_observation())

    def _read_observation(self) -> dict:
        # What Composer's one-entry buffer would hand back: a copy of the latest reading.
        return {name: np.array(read()) for name, read in self._direct}

    def reset(self) -> dm_env.TimeStep:
        self._check_open()
        self._updater_rebuilt = False
        timestep = super().reset()
        if self._updater_rebuilt:
            self._batch_substeps = self._can_batch_substeps()
            self._direct = self._direct_observables() if self._batch_substeps else None
            self._signature = self._observables_signature()
        return timestep

    def step(self, action) -> dm_env.TimeStep:
        self._check_open()
        if self._reset_next_step or not getattr(self, "_batch_substeps", False):
            return super().step(action)
        self._hooks.before_step(self._physics_proxy, action, self._random_state)
        direct = self._direct
        updater = self._observation_updater
        if direct is None:
            updater.prepare_for_next_control_step()
        try:
            self._step_physics()
            if self._physics.legacy_step:
                # A binding write before the step marked the physics dirty, and the first
                # binding read after it would run a whole mj_forward (~6 % of a step) to
                # refresh what the legacy step's closing mj_step1 has just computed.
                self._physics._dirty = False  # pylint: disable=protected-access
            physics_is_divergent = False
        except control.PhysicsError as error:
            if self._raise_exception_on_physics_error:
                raise
            logging.warning(error)
            physics_is_divergent = True
        self._hooks.after_step(self._physics_proxy, self._random_state)
        if direct is None:
            # Observables are due only on the last substep: skip the counter to it.
            updater._step_counter += self._n_sub_steps - 1  # pylint: disable=protected-access
            updater.update()
            observation = updater.get_observation()
        else:
            observation = self._read_observation()
        return self._make_timestep(physics_is_divergent, observation)

    def _step_physics(self) -> None:
        """`physics.step(n_sub_steps)`: dm_control's legacy step (mj_step2, mj_step(n - 1),
        mj_step1, so positions and velocities describe the state after the step) and its
        PhysicsError when MuJoCo raised a new warning, in fewer Python calls. Other
        integrators and non-legacy stepping go through dm_control itself."""
        physics = self._physics
        if physics is not getattr(self, "_fused_physics", None):
            self._fused_physics = physics
            self._fused = None
            if physics.legacy_step and physics.model.opt.integrator != _RK4:
                self._fused = (physics.model.ptr, physics.data.ptr, physics.data.warning.number)
        if self._fused is None:
            physics.step(self._n_sub_steps)
            return
        model, data, warnings = self._fused
        before = warnings.copy()
        mujoco.mj_step2(model, data)
        if self._n_sub_steps > 1:
            mujoco.mj_step(model, data, self._n_sub_steps - 1)
        mujoco.mj_step1(model, data)
        if (warnings > before).any():
            names = [name for name, new in zip(mujoco.mjtWarning.__members__, warnings > before)
                     if new]
            raise control.PhysicsError(
                f"Physics state is invalid. Warning(s) raised: {', '.join(names)}")

    def _make_timestep(self, physics_is_divergent: bool, obs: dict) -> dm_env.TimeStep:
        # A diverged step still gets the task's reward for the state it reports (MuJoCo has
        # reset it): Composer's fixed 0.0 would be the sparse reward for reaching the goal.
        reward = self._task.get_reward(self._physics_proxy)
        if physics_is_divergent:
            discount, terminating = 0.0, True
        else:
            discount = self._task.get_discount(self._physics_proxy)
            terminating = (self._task.should_terminate_episode(self._physics_proxy)
                           or self._physics.time() >= self._time_limit)
        if not terminating:
            return dm_env.TimeStep(dm_env.StepType.MID, reward, discount, obs)
        self._reset_next_step = True
        return dm_env.TimeStep(dm_env.StepType.LAST, reward, discount, obs)
