"""The goal-conditioned task every task shares: placing, goals, reward, success.

A `GoalTask` is wired from ready-made entities (arena, Panda, the objects) and the task's
`TaskConfig`; what it asks for is a `goals.Goal` chosen by the config's `goal`.
"""

from __future__ import annotations

import itertools

import numpy as np
from dm_control import composer
from dm_control.composer import initializers
from dm_control.composer.observation import observable
from dm_control.composer.variation import distributions
from dm_control.mujoco import wrapper

from franka_composer.arenas import FloorArena
from franka_composer.contacts import add_surface_pair
from franka_composer.controllers import Controller, make_controller
from franka_composer.entities import Panda, Prop
from franka_composer.entities.panda import COLLISION_GROUP, VISUAL_GROUP
from franka_composer.randomization import Randomizer
from franka_composer.randomization.parameters import noise_parameter
from franka_composer.tasks import rewards
from franka_composer.tasks.cameras import EpisodeCamera
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.goals import GOALS, Goal
from franka_composer.tasks.layout import ObservationLayout, layout_for
from franka_composer.tasks.placement import MAX_ATTEMPTS, PLACEMENT_RESTARTS, place_apart
from franka_composer.tasks.records import ObservationSettings, PhysicsSettings, Workspace


class GoalTask(composer.Task):
    """Bring the objects (or the hand) to a goal with the Panda, moved by the controller the
    config's `control` names.

    Wired from ready-made entities and the task's `TaskConfig` (`builder.build_task`).
    Reward and success are functions of (achieved goal, desired goal) only, through
    `rewards.compute_reward`, so HER relabelling is exact. The goals are observed exactly
    ("achieved_goal", "goal"): observation noise and delay (`randomization`) act on what the
    policy senses of the robot and the objects, never on the goals the reward is made of.
    """

    def __init__(self, arena: FloorArena, panda: Panda, props: list[Prop],
                 config: TaskConfig) -> None:
        self._arena, self._panda, self._props = arena, panda, list(props)
        self._config = config
        self._neutral_arm_qpos = np.asarray(config.neutral_arm_qpos, dtype=np.float64)
        self._initial_finger_width = config.initial_finger_width
        # Goal distance at the end of the last step or reset: computed once per step
        # (`after_step`) for the reward, the discount, termination and the adapter's success.
        self._distance: np.ndarray | np.float64 = np.float64(np.inf)
        self._success = False
        self._episode_started = False  # Cameras render from the first episode on.

        arena.attach(panda)
        for prop, spec in zip(self._props, config.objects):
            if spec.joint_damping:  # A free joint that can be damped (a freejoint cannot).
                arena.attach(prop).add("joint", type="free", damping=spec.joint_damping)
            else:
                arena.add_free_entity(prop)
        self._surface_pairs = self._add_surface_pairs()
        self._goal_spec: Goal = GOALS[config.goal](config, arena, panda, self._props)
        self._goal = np.zeros(self._goal_spec.size)
        if not config.observations.goal_marker_visible:
            self._goal_spec.marker.hide()
        arena.attach(self._goal_spec.marker)
        self._controller = make_controller(arena, panda, config.control)
        self._apply_physics_settings(config.physics)
        self.set_timesteps(control_timestep=config.control_timestep,
                           physics_timestep=config.physics.timestep)
        self._placers = self._make_placers(config.workspace)

        self._observation_layout = layout_for(config)
        self._enable_observables(config.observations)
        goal = observable.Generic(lambda physics: self._goal.copy())
        achieved = observable.Generic(lambda physics: self._goal_spec.achieved())
        goal.enabled = achieved.enabled = True
        self._cameras = self._observed_cameras(config.observations)
        self._task_observables = {"goal": goal, "achieved_goal": achieved,
                                  **self._camera_observables(config.observations)}
        self._randomizer = (self._make_randomizer(config) if config.randomization.enabled
                            else None)

    def _add_surface_pairs(self) -> list:
        """The contact pairs of the surfaces the objects rest on (`contacts.py`): each object
        with the floor, and each two objects with each other."""
        root, floor = self._arena.mjcf_model, self._arena.floor
        pairs = [add_surface_pair(root, floor, prop.geom, f"{prop.mjcf_model.model}_floor")
                 for prop in self._props]
        pairs += [add_surface_pair(root, first.geom, second.geom,
                                   f"{first.mjcf_model.model}_{second.mjcf_model.model}")
                  for first, second in itertools.combinations(self._props, 2)]
        return pairs

    def _make_placers(self, workspace: Workspace) -> list:
        """How the objects are placed each episode: resting, upright, in the object box."""
        if not self._props:
            return []
        low, high = workspace.object_box.low, workspace.object_box.high
        if len(self._props) == 1:
            prop, surface = self._props[0], self._arena.surface_height
            return [initializers.PropPlacer(
                props=[prop],
                position=distributions.Uniform(
                    low=(low[0], low[1], prop.resting_height + surface),
                    high=(high[0], high[1], prop.resting_height + surface)),
                ignore_collisions=True,  # One prop, and the arm starts high above it.
                settle_physics=False,  # It rests on the surface: nothing to settle.
            )]
        radii = [spec.footprint_radius for spec in self._config.objects]
        return [ApartPlacer(self._props, radii, low, high, self._arena.surface_height)]

    def _apply_physics_settings(self, settings: PhysicsSettings) -> None:
        option = self._arena.mjcf_model.option
        for name in ("timestep", "integrator", "cone", "impratio", "noslip_iterations",
                     "iterations", "ls_iterations"):
            setattr(option, name, getattr(settings, name))

    def _enable_observables(self, settings: ObservationSettings) -> None:
        """Enables exactly the entity observables the state vector is built from, in state
        modes (others stay available to enable)."""
        if settings.state:
            for key in self._observation_layout.keys:
                self._entity_observable(key).enabled = True

    def _entity_observable(self, key: str):
        """The entity observable "<entity>/<name>"."""
        every: list[composer.Entity] = [self._panda, *self._props]
        entities = {entity.mjcf_model.model: entity for entity in every}
        entity_name, observable_name = key.split("/")
        return entities[entity_name].observables.get_observable(observable_name)

    def _observed_cameras(self, settings: ObservationSettings) -> dict:
        """The camera elements the pixel observations render, by camera name."""
        if not settings.pixels:
            return {}
        cameras = {"workspace": self._arena.workspace_camera,
                   "wrist": self._panda.wrist_camera}
        return {name: cameras[name] for name in settings.cameras}

    def _make_randomizer(self, config: TaskConfig) -> Randomizer:
        """The randomizer, with what the policy senses: the state vector's observables
        (each with its noise) and the cameras' images (delayed, not noised)."""
        sensed: list[tuple[observable.Observable, str | None, bool]] = []
        if config.observations.state:
            sensed += [(self._entity_observable(field.key), noise_parameter(field),
                        field.quaternion) for field in self._observation_layout.fields]
        sensed += [(self._task_observables[f"{name}_pixels"], None, False)
                   for name in self._cameras]
        return Randomizer(config.randomization, arena=self._arena, panda=self._panda,
                          props=self._props, surface_pairs=self._surface_pairs,
                          controller=self._controller, sensed=sensed,
                          cameras=list(self._cameras.values()),
                          marker_sites=self._goal_spec.marker_sites_by_prop(),
                          substeps=self.physics_steps_per_control_step)

    def _camera_observables(self, settings: ObservationSettings) -> dict:
        """Composer camera observables "<camera>_pixels", (height, width, 3) uint8, for the
        pixel modes."""
        scene = wrapper.MjvOption()  # The Panda's collision hulls (group 3) or visual meshes.
        scene.geomgroup[VISUAL_GROUP] = settings.camera_meshes == "visual"
        scene.geomgroup[COLLISION_GROUP] = settings.camera_meshes == "hulls"
        observables = {}
        for name, element in self._cameras.items():
            camera = EpisodeCamera(element, height=settings.height, width=settings.width,
                                   scene_option=scene,
                                   episode_started=lambda: self._episode_started)
            camera.enabled = True
            observables[f"{name}_pixels"] = camera
        return observables

    @property
    def pixel_keys(self) -> tuple[str, ...]:
        """The camera observables' names ("workspace_pixels", ...), in the cameras' order."""
        return tuple(key for key in self._task_observables if key.endswith("_pixels"))

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
        """The (first) object."""
        return self._props[0]

    @property
    def props(self) -> list[Prop]:
        """The objects, in the config's order (none for reach)."""
        return list(self._props)

    @property
    def goal_marker(self):
        return self._goal_spec.marker

    @property
    def goal_size(self) -> int:
        """How many numbers a goal holds: 3 (a position), 6 (two), 4 (a quaternion)."""
        return self._goal_spec.size

    @property
    def goal_metric(self) -> str:
        return self._goal_spec.metric

    @property
    def controller(self) -> Controller:
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

    def state_vector(self, physics) -> np.ndarray:
        """The flat state vector (`observation_layout`) of `physics` now, read through the
        entity observables whether or not they are observed (the pixel modes observe none):
        what a state mode's `observation` would hold, for the scripted experts."""
        return self._observation_layout.flatten({
            key: np.asarray(self._entity_observable(key)(physics))
            for key in self._observation_layout.keys})

    @property
    def achieved_goal_key(self) -> str:
        """The task observable holding the achieved goal (read exactly, never corrupted)."""
        return "achieved_goal"

    @property
    def desired_goal_key(self) -> str:
        return "goal"

    @property
    def randomization(self) -> dict:
        """This episode's randomised parameters, by name (`randomization.PARAMETERS`:
        factors of the nominal values, colours, offsets, angles, delay steps); empty when
        the task is not randomised. For system identification and analysis."""
        return dict(self._randomizer.values) if self._randomizer is not None else {}

    def compute_reward(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.compute_reward(achieved_goal, desired_goal, self.reward_type,
                                      self.distance_threshold, self.goal_metric,
                                      self.goal_size)

    def is_success(self, achieved_goal, desired_goal) -> np.ndarray:
        return rewards.is_success(achieved_goal, desired_goal, self.distance_threshold,
                                  self.goal_metric, self.goal_size)

    @property
    def success(self) -> bool:
        """Whether the last control step (or reset) ended within `distance_threshold` of
        the goal."""
        return self._success

    @property
    def goal(self) -> np.ndarray:
        """This episode's desired goal (positions m, world frame; or a quaternion)."""
        return self._goal.copy()

    # ----- Composer hooks -------------------------------------------------------------------

    def after_compile(self, physics, random_state) -> None:
        # Views, not bindings: the achieved goal is read every step (valid while this
        # physics lives; Composer calls this again whenever it compiles a new one).
        self._goal_spec.bind(physics)
        if self._randomizer is not None:
            self._randomizer.bind(physics)

    def initialize_episode(self, physics, random_state: np.random.RandomState) -> None:
        self._episode_started = True
        if self._randomizer is not None:  # First: masses and gains before anything moves.
            self._randomizer.start_episode(physics, random_state)
        self._panda.configure_joints(physics, self._neutral_arm_qpos, self._initial_finger_width)
        for placer in self._placers:
            placer(physics, random_state)
        self._goal = self._goal_spec.sample(random_state)
        self._goal_spec.show(physics, self._goal)
        physics.forward()
        self._controller.initialize_episode(physics)
        self._update_distance()

    def _update_distance(self) -> None:
        spec = self._goal_spec
        self._distance = rewards.distance(spec.achieved(), self._goal, spec.metric, spec.size)
        self._success = bool(rewards.success_from_distance(self._distance,
                                                           self._config.distance_threshold))

    def action_spec(self, physics):
        return self._controller.action_spec()

    def before_step(self, physics, action, random_state) -> None:
        self._controller.apply(physics, action, perturb=(
            None if self._randomizer is None else self._randomizer.step_action))

    @property
    def substep_control(self):
        """What must run before every physics step (a torque law), or None; it is all that
        `before_substep` does, so the fast path may call it directly."""
        return self._controller.substep_law

    def before_substep(self, physics, action, random_state) -> None:
        control = self._controller.substep_law
        if control is not None:
            control()

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


class ApartPlacer(composer.Initializer):
    """Places several objects resting, upright, at uniform points of a box, their footprints
    (circles of `radii`) apart (`placement.place_apart`, begun again up to
    `PLACEMENT_RESTARTS` times where it finds no room, and only then Composer's retry of
    the episode, which logs an ERROR line for a reset that goes on to succeed).
    `PropPlacer` would count the floor the objects rest on as a collision."""

    def __init__(self, props: list[Prop], radii, low, high, surface_height: float) -> None:
        self._props, self._radii, self._surface = props, tuple(radii), surface_height
        self._xy = distributions.Uniform(low=low, high=high)

    def __call__(self, physics, random_state: np.random.RandomState) -> None:
        for _ in range(PLACEMENT_RESTARTS):
            placed = place_apart(lambda: self._xy(random_state=random_state), self._radii)
            if not isinstance(placed, int):
                break
        else:
            assert isinstance(placed, int)  # The prop the last attempt found no room for.
            raise composer.EpisodeInitializationError(
                f"no room for {self._props[placed].mjcf_model.model} after {MAX_ATTEMPTS} "
                f"draws, {PLACEMENT_RESTARTS} times")
        for prop, xy in zip(self._props, placed):
            prop.set_pose(physics, position=[xy[0], xy[1], prop.resting_height + self._surface],
                          quaternion=[1.0, 0.0, 0.0, 0.0])
            prop.set_velocity(physics, velocity=np.zeros(3), angular_velocity=np.zeros(3))
