"""The goal-conditioned task all three tasks share: placing, goals, reward, success.

A `GoalTask` is wired from ready-made entities (arena, Panda, prop, goal marker) and data
(workspace, control, physics and reward settings); the task modules only choose them.
"""

from __future__ import annotations

import numpy as np
from dm_control import composer
from dm_control.composer import initializers
from dm_control.composer.observation import observable
from dm_control.composer.variation import distributions

from franka_composer.arenas import FloorArena
from franka_composer.controllers import MocapController
from franka_composer.entities import GoalMarker, Panda, Prop
from franka_composer.entities.panda import MAX_FINGER_WIDTH
from franka_composer.tasks import rewards
from franka_composer.tasks.config import PhysicsSettings, TaskConfig, Workspace
from franka_composer.tasks.layout import ObservationLayout, layout_for


class GoalTask(composer.Task):
    """Move a prop to a goal position with the Panda's tool centre point under mocap control.

    Wired from ready-made entities and the task's `TaskConfig` (`builder.build_task`).
    Reward and success are functions of (achieved goal = prop position, desired goal) only,
    through `rewards.compute_reward`, so HER relabelling is exact.
    """

    def __init__(self, arena: FloorArena, panda: Panda, prop: Prop, goal_marker: GoalMarker,
                 config: TaskConfig) -> None:
        self._arena, self._panda, self._prop, self._goal_marker = arena, panda, prop, goal_marker
        self._config = config
        self._neutral_arm_qpos = np.asarray(config.neutral_arm_qpos, dtype=np.float64)
        # The hand starts open when it can grasp, closed when it is locked.
        self._initial_finger_width = (MAX_FINGER_WIDTH if config.control.actuated_gripper
                                      else 0.0)
        self._goal = np.zeros(3)
        # Goal distance (m) at the end of the last step or reset: computed once per step
        # (`after_step`) for the reward, the discount, termination and the adapter's success.
        self._distance = np.float64(np.inf)
        self._success = False
        self._achieved_view = None  # The prop position's slice of MjData, per episode.

        arena.attach(panda)
        arena.add_free_entity(prop)
        arena.attach(goal_marker)
        self._controller = MocapController(arena, panda, config.control)
        self._apply_physics_settings(config.physics)
        self.set_timesteps(control_timestep=config.control_timestep,
                           physics_timestep=config.physics.timestep)

        workspace = config.workspace
        low, high = workspace.object_box.low, workspace.object_box.high
        self._prop_placer = initializers.PropPlacer(
            props=[prop],
            position=distributions.Uniform(
                low=(low[0], low[1], prop.resting_height + arena.surface_height),
                high=(high[0], high[1], prop.resting_height + arena.surface_height)),
            ignore_collisions=True,  # One prop, and the arm starts high above it.
            settle_physics=False,  # It is placed resting on the surface: nothing to settle.
        )
        goal_low, goal_high = workspace.goal_box.low, workspace.goal_box.high
        self._goal_xy = distributions.Uniform(low=goal_low, high=goal_high)
        self._goal_in_air = distributions.Bernoulli(prob=workspace.goal_in_air_probability)
        self._goal_lift = distributions.Uniform(low=0.0, high=workspace.goal_max_height)

        self._observation_layout = layout_for(config)
        self._enable_observables()
        goal = observable.Generic(lambda physics: self._goal.copy())
        goal.enabled = True
        self._task_observables = {"goal": goal}

    def _apply_physics_settings(self, settings: PhysicsSettings) -> None:
        option = self._arena.mjcf_model.option
        for name in ("timestep", "integrator", "cone", "impratio", "noslip_iterations",
                     "iterations", "ls_iterations"):
            setattr(option, name, getattr(settings, name))

    def _enable_observables(self) -> None:
        """Enables exactly the observables the observation vector is built from (others stay
        available to enable)."""
        entities = {self._panda.mjcf_model.model: self._panda,
                    self._prop.mjcf_model.model: self._prop}
        for field in self._observation_layout.fields:
            entity_name, observable_name = field.key.split("/")
            entities[entity_name].observables.get_observable(observable_name).enabled = True

    # ----- What the adapter and users read -------------------------------------------------

    @property
    def root_entity(self) -> FloorArena:
        return self._arena

    @property
    def task_observables(self) -> dict:
        return self._task_observables

    @property
    def panda(self) -> Panda:
        return self._panda

    @property
    def prop(self) -> Prop:
        return self._prop

    @property
    def controller(self) -> MocapController:
        return self._controller

    @property
    def config(self) -> TaskConfig:
        """Everything the task was built from."""
        return self._config

    @property
    def workspace(self) -> Workspace:
        return self._config.workspace

    @property
    def reward_type(self) -> str:
        return self._config.reward_type

    @property
    def distance_threshold(self) -> float:
        return self._config.distance_threshold

    @property
    def terminate_on_success(self) -> bool:
        return self._config.terminate_on_success

    @property
    def observation_layout(self) -> ObservationLayout:
        """The flat observation vector's fields (the adapter and the experts read it)."""
        return self._observation_layout

    @property
    def achieved_goal_key(self) -> str:
        return f"{self._prop.mjcf_model.model}/position"

    @property
    def desired_goal_key(self) -> str:
        return "goal"

    def compute_reward(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.compute_reward(achieved_goal, desired_goal, self.reward_type,
                                      self.distance_threshold)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.is_success(achieved_goal, desired_goal, self.distance_threshold)

    @property
    def success(self) -> bool:
        """Whether the object ended the last control step (or reset) within
        `distance_threshold` of the goal."""
        return self._success

    @property
    def goal(self) -> np.ndarray:
        """Desired goal position (m, world frame) of this episode."""
        return self._goal.copy()

    # ----- Composer hooks -------------------------------------------------------------------

    def initialize_episode(self, physics, random_state: np.random.RandomState) -> None:
        self._panda.configure_joints(physics, self._neutral_arm_qpos, self._initial_finger_width)
        self._prop_placer(physics, random_state)
        self._goal = self._sample_goal(random_state)
        self._goal_marker.set_position(physics, self._goal)
        physics.forward()
        self._controller.initialize_episode(physics)
        # A view, not a binding: this is read every step (valid while this physics lives;
        # Composer makes a new one only when recompiling, and initialises again then).
        self._achieved_view = physics.bind(self._prop.position).sensordata.view(np.ndarray)
        self._update_distance()

    def _update_distance(self) -> None:
        self._distance = rewards.goal_distance(self._achieved_view, self._goal)
        self._success = bool(rewards.success_from_distance(self._distance,
                                                           self._config.distance_threshold))

    def _sample_goal(self, random_state: np.random.RandomState) -> np.ndarray:
        height = self._prop.resting_height + self._arena.surface_height
        xy = self._goal_xy(random_state=random_state)
        workspace = self._config.workspace
        if workspace.goal_max_height > 0 and self._goal_in_air(random_state=random_state):
            height += self._goal_lift(random_state=random_state)
        return np.array([xy[0], xy[1], height])

    def action_spec(self, physics):
        return self._controller.action_spec()

    def before_step(self, physics, action, random_state) -> None:
        self._controller.apply(physics, action)

    def after_step(self, physics, random_state) -> None:
        self._update_distance()

    # Reward, discount and termination describe the state at the end of the last control
    # step (Composer calls them right after `after_step`), from the distance computed there.

    def get_reward(self, physics) -> float:
        return float(rewards.reward_from_distance(self._distance, self._config.reward_type,
                                                  self._config.distance_threshold))

    def get_discount(self, physics) -> float:
        # Reaching the goal with terminate_on_success is a true terminal state.
        return 0.0 if self.should_terminate_episode(physics) else 1.0

    def should_terminate_episode(self, physics) -> bool:
        return self._config.terminate_on_success and self._success
