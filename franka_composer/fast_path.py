"""The fast path: the one module that uses dm_control's private names, behind a probe.

Composer's `step` loops over a control step's substeps in Python, calling substep hooks and
the observation updater each time. When no hook needs to run between substeps and every
observable is due only at the end of a control step, that loop only costs time:
`FastEnvironment` then calls `physics.step(n_sub_steps)` once (which MuJoCo runs in C, and
which honours `suppress_physics_errors()`); it reads the observables directly where none has
a delay, buffer or aggregator (the default), else updates Composer's buffers once, at the
last substep (an observation delayed by whole control steps, `randomization`); and falls
back to Composer's loop otherwise. A task's torque law (its
`substep_control`, all its `before_substep` does) is called before each physics step in a
plain loop instead. It also:
- keeps the observation updater across resets while its make-up is unchanged (rebuilding it
  is a quarter of a reset);
- compiles the MJCF once, through `model_cache`: Composer compiles it again on the first
  reset (for `initialize_episode_mjcf` hooks; none of ours has one), and there the fast path
  keeps the model compiled at construction and does the rest of that reset as Composer does
  (its `after_compile` hooks, and a new observation updater reset once before the episode
  is initialised: a corruptor draws from the random state there);
- clears dm_control's "dirty" flag after a step a binding write preceded: the legacy step's
  closing `mj_step1` has brought positions and velocities up to date, so the first binding
  read need not run a whole `mj_forward` again.
Trajectories, observations, rewards and terminations are those of the stock path
(`environment.GoalEnvironment`), bit for bit (`tests/test_fast_path.py`).

Private names change between dm_control releases, so `probe()` checks each one the fast path
touches; `load()` builds the stock environment, with one warning, if any is missing, or if
`FRANKA_COMPOSER_FAST_PATH=0`.
"""

from __future__ import annotations

import os

import dm_env
import numpy as np
from absl import logging
from dm_control import composer
from dm_control.composer import environment as composer_environment
from dm_control.composer.observation import updater as composer_updater
from dm_control.rl import control

from franka_composer.environment import GoalEnvironment
from franka_composer.model_cache import compile_physics

#: Set to "0" to use the stock path (plain Composer stepping) whatever the probe finds.
ENV_VARIABLE = "FRANKA_COMPOSER_FAST_PATH"

#: Private functions of `dm_control.composer.environment` it calls.
_MODULE_FUNCTIONS = ("_callable_is_trivial",)
#: Private names of `composer.Environment` instances the fast path reads or writes.
_ENVIRONMENT_ATTRIBUTES = (
    "_hooks", "_observation_updater", "_mjcf_never_compiled", "_recompile_mjcf_every_episode",
    "_task", "_physics", "_physics_proxy", "_random_state", "_fixed_initial_state",
    "_reset_next_step", "_n_sub_steps", "_time_limit", "_raise_exception_on_physics_error",
    "_legacy_step")
#: Private methods of `composer.Environment` it overrides or calls.
_ENVIRONMENT_METHODS = ("_reset_attempt", "_recompile_physics")
#: Private names of the hook scheduler and the observation updater.
_HOOK_NAMES = ("_initialize_episode_mjcf", "_before_substep", "_after_substep")
_UPDATER_ATTRIBUTES = ("_enabled_list", "_enabled_structure", "_observables", "_step_counter")

_warned = False


class FastPathUnavailable(RuntimeError):
    """The installed dm_control lacks a private name the fast path needs."""


def probe() -> list[str]:
    """The private dm_control names the fast path needs that the installed one lacks
    (without building anything)."""
    missing = [f"dm_control.composer.environment.{name}" for name in _MODULE_FUNCTIONS
               if not hasattr(composer_environment, name)]
    missing += [f"composer.Environment.{name}" for name in _ENVIRONMENT_METHODS
                if not hasattr(composer.Environment, name)]
    for name in ("prepare_for_next_control_step", "update", "get_observation"):
        if not hasattr(composer_updater.Updater, name):
            missing.append(f"composer Updater.{name}")
    return missing


def _probe_instance(env: composer.Environment) -> list[str]:
    """The private names a built environment lacks."""
    missing = [f"composer.Environment.{name}" for name in _ENVIRONMENT_ATTRIBUTES
               if not hasattr(env, name)]
    if hasattr(env, "_hooks"):
        for name in _HOOK_NAMES:
            hook = getattr(env._hooks, name, None)  # pylint: disable=protected-access
            if hook is None or not all(hasattr(hook, a) for a in ("entity_hooks",
                                                                   "extra_hooks")):
                missing.append(f"composer hooks.{name}")
    if hasattr(env, "_observation_updater"):
        missing += [f"composer Updater.{name}" for name in _UPDATER_ATTRIBUTES
                    if not hasattr(env._observation_updater, name)]  # pylint: disable=protected-access
    physics = getattr(env, "_physics", None)
    if physics is not None and not hasattr(physics, "_dirty"):
        missing.append("mjcf.Physics._dirty")
    return missing


def wanted() -> bool:
    """Whether the fast path is to be tried (`FRANKA_COMPOSER_FAST_PATH` is not "0")."""
    return os.environ.get(ENV_VARIABLE, "1").strip() != "0"


def make_environment(task, **kwargs) -> GoalEnvironment:
    """A `FastEnvironment` where wanted and possible, else the stock `GoalEnvironment`
    (one warning per process when the probe found something missing)."""
    if wanted():
        missing = probe()
        if not missing:
            try:
                return FastEnvironment(task, **kwargs)
            except FastPathUnavailable as error:
                missing = [str(error)]
        _warn_once(missing)
    return GoalEnvironment(task, **kwargs)


def _warn_once(missing: list[str]) -> None:
    global _warned
    if not _warned:
        _warned = True
        logging.warning("franka_composer: the installed dm_control lacks %s; using Composer's "
                        "stock stepping (same results, slower). Set %s=0 to silence this.",
                        ", ".join(missing), ENV_VARIABLE)


class FastEnvironment(GoalEnvironment):
    """`GoalEnvironment` with the substep loop batched where nothing observes it."""

    # Set at each reset that rebuilds Composer's observation updater.
    _direct: list | None
    _signature: tuple

    def __init__(self, task, **kwargs) -> None:
        super().__init__(task, **kwargs)
        missing = _probe_instance(self)
        if missing:
            self.close()
            raise FastPathUnavailable(", ".join(missing))

    # pylint: disable=protected-access

    def _recompile_physics(self) -> None:
        # Composer's first reset would compile again the model compiled at construction (the
        # flag is not yet set then): kept, unless an `initialize_episode_mjcf` hook changed it.
        if getattr(self, "_mjcf_never_compiled", False) and not self._has_mjcf_hooks():
            return
        physics = getattr(self, "_physics", None)
        if physics:
            physics.free()
        self._physics = compile_physics(self._task.root_entity.mjcf_model)
        self._physics.legacy_step = self._legacy_step

    def _has_mjcf_hooks(self) -> bool:
        if self._recompile_mjcf_every_episode:
            return True
        if not composer_environment._callable_is_trivial(self._task.initialize_episode_mjcf):
            return True
        hook = self._hooks._initialize_episode_mjcf
        return bool(hook.entity_hooks or hook.extra_hooks)

    def _can_batch_substeps(self) -> bool:
        hooks = self._hooks
        for name in ("before_substep", "after_substep"):
            # A GoalTask's before_substep only runs its `substep_control`, which `step` calls.
            task_runs_control_only = (name == "before_substep"
                                      and hasattr(self._task, "substep_control"))
            if not (task_runs_control_only or
                    composer_environment._callable_is_trivial(getattr(self._task, name))):
                return False
            hook = getattr(hooks, "_" + name)
            if hook.entity_hooks or hook.extra_hooks:
                return False
        return all(_due_at_control_steps(enabled, self._n_sub_steps)
                   for enabled in self._observation_updater._enabled_list)

    def _direct_observables(self) -> list | None:
        """(name, callable) per observable when each is simply read at the end of the step
        (Composer's buffer would hold exactly that one value); None otherwise."""
        structure = self._observation_updater._enabled_structure
        if not isinstance(structure, dict):
            return None
        direct = []
        for name, enabled in structure.items():
            if (enabled.buffer_size != 1 or enabled.observable.aggregator is not None
                    or enabled.delay != 0 or enabled.update_interval != 1):
                return None
            direct.append((name, enabled.observation_callable))
        return direct

    def _observables_signature(self) -> tuple:
        """Everything Composer's updater is built from at a reset: which observables are
        enabled and how each is scheduled. Users may change these between episodes."""
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
        if self._observables_signature() != self._signature:
            # The episode's initialisation changed how observables are read (a randomised
            # observation delay): Composer's updater takes it from here, as on its own path.
            self._updater_rebuilt = True
            self._observation_updater.reset(self._physics_proxy, self._random_state)
            return dm_env.TimeStep(dm_env.StepType.FIRST, None, None,
                                   self._observation_updater.get_observation())
        return dm_env.TimeStep(dm_env.StepType.FIRST, None, None, self._read_observation())

    def _read_observation(self) -> dict:
        # What Composer's one-entry buffer would hand back: a copy of the latest reading.
        assert self._direct is not None  # Read so only while observables are read directly.
        return {name: np.array(read()) for name, read in self._direct}

    def reset(self) -> dm_env.TimeStep:
        self._updater_rebuilt = False
        timestep = super().reset()
        if self._updater_rebuilt:
            self._batch_substeps = self._can_batch_substeps()
            self._direct = self._direct_observables() if self._batch_substeps else None
            self._signature = self._observables_signature()
        return timestep

    def step(self, action) -> dm_env.TimeStep:
        if self._reset_next_step or not getattr(self, "_batch_substeps", False):
            return super().step(action)
        self._check_can_step()
        physics = self._physics
        self._hooks.before_step(self._physics_proxy, action, self._random_state)
        direct = self._direct
        updater = self._observation_updater
        if direct is None:
            updater.prepare_for_next_control_step()
        try:
            # Composer's loop does physics.step() n times; one call does the same MuJoCo
            # steps, raising (or, inside suppress_physics_errors(), logging) the same way.
            # A torque law runs before each of them, as the task's before_substep would.
            substep_control = getattr(self._task, "substep_control", None)
            if substep_control is None:
                physics.step(self._n_sub_steps)
            else:
                for _ in range(self._n_sub_steps):
                    substep_control()
                    physics.step()
            if physics.legacy_step:
                # A binding write before the step marked the physics dirty, and the first
                # binding read after it would run a whole mj_forward (~6 % of a step) to
                # refresh what the legacy step's closing mj_step1 has just computed.
                physics._dirty = False
            physics_is_divergent = False
        except control.PhysicsError as error:
            if self._raise_exception_on_physics_error:
                raise
            logging.warning(error)
            physics_is_divergent = True
        self._hooks.after_step(self._physics_proxy, self._random_state)
        if direct is None:
            # Observables are due only on the last substep: skip the counter to it.
            updater._step_counter += self._n_sub_steps - 1
            updater.update()
            observation = updater.get_observation()
        else:
            observation = self._read_observation()
        return self._make_timestep(physics_is_divergent, observation)

    def _make_timestep(self, physics_is_divergent: bool, obs: dict) -> dm_env.TimeStep:
        # A diverged step gets the task's reward for the state it reports, as on the stock
        # path (`GoalEnvironment.step`).
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


def _due_at_control_steps(enabled, substeps: int) -> bool:
    """Whether an enabled observable is only ever due at the end of a control step: read
    every substep with no delay into a one-entry buffer (Composer then schedules only the
    last substep; a buffer of b entries takes the last b substeps' readings), or read once
    per control step with a delay of whole control steps into a one-entry buffer."""
    interval, delay = enabled.update_interval, enabled.delay
    if not (isinstance(interval, int) and isinstance(delay, int)):
        return False  # Drawn anew at each update (a Variation).
    if interval == 1 and delay == 0:
        return enabled.buffer_size == 1
    return interval == substeps and delay % substeps == 0 and enabled.buffer_size == 1
