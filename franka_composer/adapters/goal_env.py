"""A thin Gymnasium `GoalEnv`-style adapter over the Composer suite, for HER learners.

It only reshapes what the task exposes: the flat `observation` is built by the task's
`observation_layout` (velocities times `TaskConfig.velocity_period`: the control period
unless `velocity_timestep` sets another), the goals are the task's
achieved/desired goal observables, the reward is the timestep's (the task's
reward function on those goals: the same function `compute_reward`, which HER calls to
relabel, runs) and `is_success` is the task's.
"""

from __future__ import annotations

import pickle
import sys
from collections.abc import Mapping
from typing import Any

import dm_env
import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle

from franka_composer import render_owner, seeding, suite
from franka_composer.environment import ended_by_divergence
from franka_composer.headless_gl import (HeadlessGLError, display_not_opened,
                                         glfw_opens_the_display, has_display)
from franka_composer.randomization import (PARAMETERS, RandomizationSettings,
                                          randomization_settings)
from franka_composer.randomization.settings import from_a_preset
from franka_composer.arenas.floor import CAMERAS, MAX_RENDER_SIZE, RENDER_SIZE
from franka_composer.tasks.layout import OBSERVATION_DTYPE
from franka_composer.tasks.records import ObservationSettings
from franka_composer.tasks.options import OPTION_NAMES
from franka_composer.validation import (check_bool, check_choice, check_names, check_number,
                                        named_parameters)

#: `suite.load`'s parameters that the adapter sets itself, and how a Gymnasium user sets
#: what they stand for.
_SET_BY_THE_ADAPTER = {
    "seed": "seed the episodes with env.reset(seed=...)",
    "renderable": "render_mode sets it (an env without one leaves the visual meshes out)",
    "name": "the id (or task=) names the task",
}

#: dtype of rewards (observations: `layout.OBSERVATION_DTYPE`, the same).
REWARD_DTYPE = np.float64


class FrankaGoalEnv(gym.Env, EzPickle):
    """A franka_composer task as a Gymnasium environment with dict goal observations.

    Args:
      task: a name from `franka_composer.ALL_TASKS`.
      reward_type: "sparse" or "dense".
      render_mode: None, "rgb_array" (headless frames) or "human" (a viewer window).
      width, height: size (pixels) of `rgb_array` frames and of the `human` viewer's
        window, at most 1024 (480 if not given).
      camera: the arena camera to render from ("workspace", the default, or "top").
      An env without a render mode renders nothing: width, height or camera given to one is
      refused, not ignored (and goal_marker_visible, unless camera observations show it).
      **task_kwargs: overrides of the task's configuration (e.g. terminate_on_success=False).

    Episodes end with `terminated=True` on success when the task's `terminate_on_success`
    is set (the paper's default), and with `truncated=True` at the dm_env environment's
    time limit or if the physics diverges (`info["diverged"]`: no end of the task, so a
    learner bootstraps there rather than learn that breaking the simulation ends its
    costs): the time limit is the task's `max_episode_steps` unless `time_limit`
    (seconds; None: none) says otherwise. Through `gym.make` the length is Gymnasium's
    `TimeLimit`'s alone, `max_episode_steps` (the task's by default), as in
    Gymnasium-Robotics (`registration.make_registered`).
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __getstate__(self):
        # EzPickle rebuilds from the constructor's arguments; `gym.make`'s spec goes along
        # where it pickles (an id registered with a lambda as its entry point does not).
        state = EzPickle.__getstate__(self)
        try:
            pickle.dumps(self.spec)
        except (pickle.PicklingError, AttributeError, TypeError):
            return state
        return {**state, "spec": self.spec}

    def __setstate__(self, state):
        state = dict(state)
        spec = state.pop("spec", None)
        EzPickle.__setstate__(self, state)
        self.spec = spec

    def __init__(self, task: str = "push", reward_type: str = "sparse",
                 render_mode: str | None = None, width: int | None = None,
                 height: int | None = None, camera: str | None = None,
                 **task_kwargs: Any) -> None:
        EzPickle.__init__(self, task, reward_type, render_mode, width, height, camera,
                          **task_kwargs)
        check_not_loads_own(task_kwargs)
        check_names("task option", set(task_kwargs) - {"time_limit"}, OPTION_NAMES,
                    own=("the env", ENV_ARGUMENTS))
        # Every rendering argument is checked before anything is built or reaches MuJoCo.
        if render_mode is not None:
            check_choice("render_mode", render_mode, tuple(self.metadata["render_modes"]),
                         also="None")
        if render_mode == "human":
            _check_display()
        _check_rendering_asked(render_mode, width=width, height=height, camera=camera)
        _check_goal_marker_seen(render_mode, task_kwargs)
        _check_visuals_seen(render_mode, task_kwargs)
        width = RENDER_SIZE if width is None else width
        height = RENDER_SIZE if height is None else height
        camera = CAMERAS[0] if camera is None else camera
        # Checked as the pixel observations' sizes are (`pixel_width`, `pixel_height`).
        width, height = (int(check_number(name, value, minimum=1, maximum=MAX_RENDER_SIZE,
                                          integer=True))
                         for name, value in (("width", width), ("height", height)))
        check_choice("camera", camera, CAMERAS)
        # An env that never renders leaves the Panda's visual meshes out (~50 MB per env),
        # unless its images draw them (camera_meshes="visual").
        self._env = suite.load(task, reward_type=reward_type,
                               renderable=True if render_mode is not None else None,
                               **task_kwargs)
        self._task = self._env.task
        self.task_name = task
        self.render_mode = render_mode
        self._width, self._height, self._camera = width, height, camera
        self._renderer = None
        self._timestep: dm_env.TimeStep | None = None
        self._an_episode_ended = False  # Then a step before reset() says why it needs one;
        self._reset_failed = False  # and so after a reset that raised.
        self._stream_started = False  # Whether a reset has seeded the episode stream.
        self._randomization = None  # This episode's randomised parameters, if randomised.
        self._closed = False

        self._layout = self._task.observation_layout
        settings = self._task.config.observations
        self._state, self._pixel_keys = settings.state, self._task.pixel_keys
        goal_box = spaces.Box(-np.inf, np.inf, shape=(self._task.goal_size,),
                              dtype=OBSERVATION_DTYPE)
        # The goals are state vectors in every observation mode: HER relabels them exactly.
        space: dict[str, spaces.Space] = (
            {"observation": state_box(self._layout)} if self._state else {})
        space.update(achieved_goal=goal_box, desired_goal=goal_box)
        for key in self._pixel_keys:
            space[key] = spaces.Box(0, 255, shape=(settings.height, settings.width, 3),
                                    dtype=np.uint8)
        self.observation_space = spaces.Dict(space)
        action_spec = self._env.action_spec()
        self.action_space = spaces.Box(-1.0, 1.0, shape=action_spec.shape, dtype=np.float32)
        self.metadata = {**self.metadata, "render_fps": _frames_per_second(self.dt)}

    # ----- Gymnasium API --------------------------------------------------------------------

    @property
    def dt(self) -> float:
        """Seconds per step (the control period)."""
        return self._env.control_timestep()

    @property
    def task(self):
        """The Composer task (goals, reward settings, observation layout)."""
        return self._task

    @property
    def observation_layout(self):
        """What each element of `obs["observation"]` is (`ObservationLayout`)."""
        return self._layout

    @property
    def composer_env(self):
        """The underlying dm_env `composer.Environment`."""
        return self._env

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Starts an episode; `seed` (any non-negative int) makes it a function of the seed.
        `options` is accepted only empty: this env has no reset options."""
        self._check_open()
        if seed is not None:
            seed = seeding.check_seed(seed)  # Before anything is reseeded; numpy ints as int.
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(f"reset options must be a dict or None (Gymnasium's reset), got "
                             f"{type(options).__name__} {options!r}")
        if options:
            raise ValueError(f"unknown reset option(s) {', '.join(map(repr, sorted(options)))}; "
                             "this environment takes none (task options go to gym.make)")
        super().reset(seed=seed)
        if seed is not None or not self._stream_started:
            # The episode stream is a function of the seed; an unseeded first reset draws it
            # from Gymnasium's np_random so `reset()` alone is still reproducible per env.
            # Later unseeded resets continue it, however the episodes before them ended.
            seeding.reseed(self._env.random_state,
                           seed if seed is not None else int(self.np_random.integers(2**63 - 1)))
            self._stream_started = True
        try:
            self._timestep = self._env.reset()
        except BaseException:
            if self._env.reset_due:  # Begun and failed: it left no episode to step. (One
                self._timestep, self._reset_failed = None, True  # refused changed nothing.)
            raise
        self._reset_failed = False
        self._randomization = (self._task.randomization
                               if self._task.config.randomization.enabled else None)
        obs = self.goal_observation(self._timestep.observation)
        if self.render_mode == "human":
            self.render()
        return obs, self._info()

    def step(self, action):
        self._check_open()
        if self._timestep is None:
            raise gym.error.ResetNeeded(
                "Cannot call env.step() before calling env.reset()" + (
                    ": the last reset() raised, and left no episode to step"
                    if self._reset_failed else
                    ": the episode ended at its last step (terminated or truncated), and "
                    "reset() begins the next" if self._an_episode_ended else ""))
        self._timestep = self._env.step(action)
        obs = self.goal_observation(self._timestep.observation)
        info = self._info()
        reward = REWARD_DTYPE(self._timestep.reward)
        # dm_env's LAST step: discount 1 is the time-out, Gymnasium's truncation; discount
        # 0 the goal reached, or the physics diverged (Composer's discount there), which is
        # no end of the task: a truncation too.
        ended = self._timestep.last()
        diverged = ended_by_divergence(self._timestep, self._task)
        truncated = bool(ended and (self._timestep.discount > 0 or diverged))
        terminated = bool(ended and not truncated)
        if diverged:
            info["diverged"] = True
        if ended:
            self._timestep = None  # Composer would reset on the next step: make it explicit.
            self._an_episode_ended = True
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Reward for goal pairs with any leading batch shape; `info` is ignored (may be a
        dict, a list or array of dicts, or None). Returns float64 of the batch shape."""
        return self._task.compute_reward(achieved_goal, desired_goal)

    def compute_terminated(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Whether each goal pair ends the episode (success with terminate_on_success)."""
        success = self._task.is_success(achieved_goal, desired_goal)
        return success & self._task.terminate_on_success

    def compute_truncated(self, achieved_goal, desired_goal, info=None) -> np.ndarray:
        """Never: goals do not truncate an episode, its time limit does."""
        return np.zeros(np.shape(self._task.is_success(achieved_goal, desired_goal)),
                        dtype=bool)

    def render(self):
        self._check_open()
        if self.render_mode is None:
            return None
        # A GL context belongs to the thread that made it (dm_control's and the viewer's).
        render_owner.claim(self._env)
        if self.render_mode == "rgb_array":
            return self._env.physics.render(self._height, self._width, camera_id=self._camera)
        if self.render_mode == "human":
            if self._renderer is None:
                from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

                physics = self._env.physics
                self._renderer = MujocoRenderer(physics.model.ptr, physics.data.ptr,
                                                width=self._width, height=self._height,
                                                camera_name=self._camera)
            return self._renderer.render("human")
        return None

    def close(self) -> None:
        """Frees the viewer and the physics, from any thread; closing again is harmless, and
        `reset`, `step` and `render` afterwards raise Gymnasium's ClosedEnvironmentError."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if getattr(self, "_env", None) is not None:
            self._env.close()
        self._closed = True

    def _check_open(self) -> None:
        if self._closed:
            raise gym.error.ClosedEnvironmentError(
                f"this {self.spec.id if self.spec else type(self).__name__} environment is "
                "closed: make a new one")

    # ----- Reshaping ------------------------------------------------------------------------

    def _info(self) -> dict:
        """`is_success`, and under randomisation the episode's parameters (a new dict each
        time, of immutable values)."""
        if self._randomization is None:
            return {"is_success": self._task.success}
        return {"is_success": self._task.success, "randomization": dict(self._randomization)}

    def goal_observation(self, composer_obs: dict) -> dict[str, np.ndarray]:
        """The goal dict this env returns for a Composer observation (e.g. one read from
        an RLDS dataset, or from the dm_env under this env)."""
        obs = {"observation": self._layout.flatten(composer_obs)} if self._state else {}
        obs["achieved_goal"] = np.array(composer_obs[self._task.achieved_goal_key],
                                        dtype=OBSERVATION_DTYPE)
        obs["desired_goal"] = np.array(composer_obs[self._task.desired_goal_key],
                                       dtype=OBSERVATION_DTYPE)
        for key in self._pixel_keys:
            obs[key] = composer_obs[key]
        return obs


def _frames_per_second(dt: float) -> int | float:
    """One frame per step, as Gymnasium's `render_fps` (what video writers are given): a
    whole number where it is one (20 at 0.05 s), else the exact rate (0.5 at 2 s a step;
    rounded, it read 0)."""
    rate = 1.0 / dt
    return int(round(rate)) if abs(rate - round(rate)) <= 1e-9 * rate else rate


def state_box(layout) -> spaces.Box:
    """The space of the state vector of `layout` (an `ObservationLayout`), the goal dict's
    "observation" in the state modes."""
    return spaces.Box(-np.inf, np.inf, shape=(layout.size,), dtype=OBSERVATION_DTYPE)


def _check_rendering_asked(render_mode: str | None, **given) -> None:
    """A ValueError for rendering arguments given to an env that renders nothing: they
    would do nothing, silently (the pixel options are refused in state mode alike)."""
    named = [name for name, value in given.items() if value is not None]
    if render_mode is None and named:
        raise ValueError(f"{', '.join(named)} set{'s' * (len(named) == 1)} the rendered "
                         "frames, and render_mode=None renders none: give render_mode="
                         f"'rgb_array' or 'human', or leave {'it' if len(named) == 1 else 'them'}"
                         " out")


def _check_goal_marker_seen(render_mode: str | None, task_kwargs: dict) -> None:
    """A ValueError for `goal_marker_visible` given to an env with neither frames nor camera
    observations, where nothing would show the goal or hide it."""
    if "goal_marker_visible" not in task_kwargs or render_mode is not None:
        return
    check_bool("goal_marker_visible", task_kwargs["goal_marker_visible"])
    if task_kwargs.get("observation_mode", ObservationSettings.mode) == "state":
        raise ValueError("goal_marker_visible shows or hides the goal in rendered frames and "
                         "camera observations, and render_mode=None with observation_mode="
                         "'state' has neither: give render_mode='rgb_array' or 'human', or "
                         "observation_mode='pixels' or 'state+pixels', or leave it out")


def _check_visuals_seen(render_mode: str | None, task_kwargs: dict) -> None:
    """A ValueError for a custom randomisation's visual parameters (colours, lights) given
    to an env with neither frames nor camera observations, where no image shows them: the
    task takes them, for a dm_env user may render its physics. A preset's own entries apply
    where they can, as the preset does (`from_a_preset`)."""
    given = task_kwargs.get("randomization")
    if render_mode is not None or not isinstance(given, (Mapping, RandomizationSettings)) or (
            task_kwargs.get("observation_mode", ObservationSettings.mode) != "state"):
        return  # (A preset's name is not probed here: ~55 ms, which the task does again.)
    settings = randomization_settings("randomization", given)
    visual = [parameter for parameter, distribution in settings.ranges
              if PARAMETERS[parameter].group == "visual"
              and not PARAMETERS[parameter].observed_cameras  # (The task refuses those.)
              and not from_a_preset(parameter, distribution)]
    if settings.name == "custom" and visual:
        raise ValueError(f"randomization {visual[0]!r} does nothing here: it changes what "
                         "images show, and render_mode=None with observation_mode='state' "
                         "has none: give render_mode='rgb_array' or 'human', or "
                         "observation_mode='pixels' or 'state+pixels', or leave it out")


def _check_display() -> None:
    """`human` rendering opens a GLFW window; without a display, or with one set that GLFW
    cannot open (a DISPLAY left over from ssh or a container), GLFW aborts the whole process
    (an assertion in C, no Python exception), so refuse before it is touched."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd")):
        return
    if not has_display():
        raise RuntimeError("render_mode='human' needs a display, and none was found (neither "
                           "DISPLAY nor WAYLAND_DISPLAY is set): use render_mode='rgb_array' "
                           "for headless frames, or set DISPLAY")
    if not glfw_opens_the_display():
        raise HeadlessGLError(f"render_mode='human' opens a window, and GLFW "
                              f"{display_not_opened()}: use render_mode='rgb_array' for "
                              "headless frames, or set DISPLAY to a display you can open")


#: What the env takes beside the task options: its own parameters and `load`'s time limit.
ENV_ARGUMENTS = (*named_parameters(FrankaGoalEnv.__init__), "time_limit")


def check_not_loads_own(options: dict) -> None:
    """A ValueError for a `suite.load` parameter the adapter sets itself, before Python
    says `load()` got it twice, or it is taken and has no effect (a seed)."""
    for name, instead in _SET_BY_THE_ADAPTER.items():
        if name in options:
            raise ValueError(f"{name} is not an option of the Gymnasium env: {instead}")
