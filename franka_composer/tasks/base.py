"""The goal-conditioned task all three tasks share: placing, goals, reward, success.

A `GoalTask` is wired from ready-made entities (arena, Panda, prop, goal marker) and data
(workspace, control, physics and reward settings); the task modules only choose them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from dm_control import composer
from dm_control.composer import initializers
from dm_control.composer.observation import observable
from dm_control.composer.variation import distributions

from franka_composer.arenas import FloorArena
from franka_composer.controllers import ControlSettings, MocapController
from franka_composer.entities import GoalMarker, Panda, Prop
from franka_composer.entities.panda import NEUTRAL_ARM_QPOS
from franka_composer.tasks import rewards
from franka_composer.tasks.config import PhysicsSettings
from franka_composer.tasks.workspaces import Workspace


class ObservationField(NamedTuple):
    """One slice of the flat `observation` vector: a Composer observable and its meaning."""

    key: str
    size: int
    meaning: str
    unit: str
    per_control_step: bool  # multiplied by the control period (a displacement per step)


class GoalTask(composer.Task):
    """Move a prop to a goal position with the Panda's tool centre point under mocap control.

    Reward and success are functions of (achieved goal = prop position, desired goal) only,
    through `rewards.compute_reward`, so HER relabelling is exact.
    """

    def __init__(
        self,
        arena: FloorArena,
        panda: Panda,
        prop: Prop,
        goal_marker: GoalMarker,
        *,
        workspace: Workspace,
        control: ControlSettings,
        physics: PhysicsSettings,
        reward_type: str = "sparse",
        distance_threshold: float = 0.05,
        terminate_on_success: bool = True,
        control_timestep: float = 0.05,
        neutral_arm_qpos=NEUTRAL_ARM_QPOS,
        initial_finger_width: float = 0.0,
    ) -> None:
        self._arena, self._panda, self._prop, self._goal_marker = arena, panda, prop, goal_marker
        self._workspace = workspace
        self._reward_type = reward_type
        self._distance_threshold = float(distance_threshold)
        self._terminate_on_success = bool(terminate_on_success)
        self._neutral_arm_qpos = np.asarray(neutral_arm_qpos, dtype=np.float64)
        self._initial_finger_width = float(initial_finger_width)
        self._goal = np.zeros(3)
        # Goal distance (m) at the end of the last step or reset: computed once per step
        # (`after_step`) for the reward, the discount, termination and the adapter's success.
        self._distance = np.float64(np.inf)
        self._success = False
        self._achieved_view = None  # The prop position's slice of MjData, per episode.

        arena.attach(panda)
        arena.add_free_entity(prop)
        arena.attach(goal_marker)
        self._controller = MocapController(arena, panda, control)
        self._apply_physics_settings(physics)
        self.set_timesteps(control_timestep=control_timestep, physics_timestep=physics.timestep)

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

        self._observation_fields = self._enable_observables(control.actuated_gripper)
        goal = observable.Generic(lambda physics: self._goal.copy())
        goal.enabled = True
        self._task_observables = {"goal": goal}

    def _apply_physics_settings(self, settings: PhysicsSettings) -> None:
        option = self._arena.mjcf_model.option
        option.timestep = settings.timestep
        option.integrator = settings.integrator
        option.cone = settings.cone
        option.impratio = settings.impratio
        option.noslip_iterations = settings.noslip_iterations
        option.iterations = settings.iterations
        option.ls_iterations = settings.ls_iterations

    def _enable_observables(self, with_finger_width: bool) -> tuple[ObservationField, ...]:
        """Enables exactly the observables the observation vector is built from (others stay
        available to enable) and returns the vector's layout, in the paper's order."""
        panda, prop = self._panda, self._prop
        fields = [
            (panda, "tcp_pos", 3, "end-effector (tool centre point) position", "m", False),
            (panda, "tcp_velp", 3, "end-effector linear velocity", "m/step", True),
        ]
        if with_finger_width:
            fields.append((panda, "finger_width", 1, "finger width", "m", False))
        fields += [
            (prop, "position", 3, "object position", "m", False),
            (prop, "orientation_euler", 3,
             "object orientation (roll, pitch, yaw; x-y-z extrinsic)", "rad", False),
            (prop, "linear_velocity", 3, "object linear velocity", "m/step", True),
            (prop, "angular_velocity", 3, "object angular velocity", "rad/step", True),
        ]
        layout = []
        for entity, name, size, meaning, unit, per_step in fields:
            entity.observables.get_observable(name).enabled = True
            layout.append(ObservationField(f"{entity.mjcf_model.model}/{name}", size, meaning,
                                           unit, per_step))
        return tuple(layout)

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
    def workspace(self) -> Workspace:
        return self._workspace

    @property
    def reward_type(self) -> str:
        return self._reward_type

    @property
    def distance_threshold(self) -> float:
        return self._distance_threshold

    @property
    def terminate_on_success(self) -> bool:
        return self._terminate_on_success

    @property
    def observation_fields(self) -> tuple[ObservationField, ...]:
        """Layout of the flat observation vector (the adapter concatenates these keys)."""
        return self._observation_fields

    @property
    def achieved_goal_key(self) -> str:
        return f"{self._prop.mjcf_model.model}/position"

    @property
    def desired_goal_key(self) -> str:
        return "goal"

    def compute_reward(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.compute_reward(achieved_goal, desired_goal, self._reward_type,
                                      self._distance_threshold)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.is_success(achieved_goal, desired_goal, self._distance_threshold)

    def achieved_goal(self, physics) -> np.ndarray:
        return np.array(physics.bind(self._prop.position).sensordata)

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
                                                           self._distance_threshold))

    def _sample_goal(self, random_state: np.random.RandomState) -> np.ndarray:
        height = self._prop.resting_height + self._arena.surface_height
        xy = self._goal_xy(random_state=random_state)
        if self._workspace.goal_max_height > 0 and self._goal_in_air(random_state=random_state):
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
        return float(rewards.reward_from_distance(self._distance, self._reward_type,
                                                  self._distance_threshold))

    def get_discount(self, physics) -> float:
        # Reaching the goal with terminate_on_success is a true terminal state.
        return 0.0 if self.should_terminate_episode(physics) else 1.0

    def should_terminate_episode(self, physics) -> bool:
        return self._terminate_on_success and self.success
