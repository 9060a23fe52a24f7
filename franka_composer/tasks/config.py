"""Every number a task is made of, as data: `TaskConfig`, a frozen record composed of the
records the builder hands to the entities and the task as they are (`records.py`: the
objects, the `Workspace`, what is observed, MuJoCo's `PhysicsSettings`) and the
controller's `ControlSettings`. The task modules state only what differs from the defaults.

Users change a task through flat option names (`options.py`): `config.replace(**options)`
checks and sets them, and refuses what the result cannot run, before anything is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from franka_composer.controllers import ControlSettings
from franka_composer.entities.panda import MAX_FINGER_WIDTH, NEUTRAL_ARM_QPOS
from franka_composer.randomization import RandomizationSettings
from franka_composer.tasks.clearance import check_clearance, clearance_inputs
from franka_composer.tasks.options import (LIFTED_GOALS, OPTION_NAMES, OPTIONS, expand_timing,
                                           refuse_unread, timing_name, unread_option)
from franka_composer.tasks.placement import (CHECKED_PLACEMENTS, MAX_ATTEMPTS,
                                             PLACEMENT_MARGIN, room_to_place_apart)
from franka_composer.tasks.records import (MAX_SUBSTEPS, BlockSpec, ObjectSpec,
                                           ObservationSettings, OrientationGoalSettings,
                                           PhysicsSettings, Workspace)
from franka_composer.validation import check_names, spelling


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """A task's parameters (SI units, world frame, robot base at the origin).

    Attributes:
      name: the task's name (`franka_composer.load(name)`), by which its expert is found.
      description: what the task asks, for its documentation page.
      objects: the objects the robot moves (each a `BlockSpec` or `PuckSpec`; none for reach).
      goal: what the task asks for, a kind of `goals.GOALS`.
      object_orientation: how the observation gives each object's orientation: "euler"
        (roll, pitch, yaw; the paper's) or "quaternion" (w, x, y, z).
      floor_friction: sliding friction of the floor; an object's contact with it takes the
        smaller of the two (`contacts.surface_friction`), the hand's the larger (MuJoCo's
        rule: the finger pads' 2 rules the grip).
      workspace: where the object starts and goals lie.
      control: which controller moves the arm, how far an action moves it, and whether
        the gripper is actuated.
      physics: MuJoCo's solver options.
      reward_type: "sparse" (0 / -1) or "dense" (-distance).
      distance_threshold: success radius (m).
      terminate_on_success: end the episode when the goal is reached (the paper); False
        gives Fetch semantics, for which HER relabelling is exact.
      control_timestep: seconds per control step (a whole multiple of the physics step, at
        most `records.MAX_SUBSTEPS` of them: 100 s).
      velocity_timestep: seconds the observation's velocities are multiplied by (None: the
        control period, as Fetch's velp * dt). The reference code steps
        0.5 s but multiplies by its stated 0.05 s (`TIMINGS["reference"]`).
      neutral_arm_qpos: arm joint angles (rad) at reset.
      max_episode_steps: control steps in an episode, unless it ends on success: the dm_env
        environment's time limit (`time_limit`) and the Gymnasium ids' max_episode_steps.
      observations: the state vector, camera images or both (`ObservationSettings`).
      randomization: what is randomised each episode (`randomization` package); off by
        default.
      orientation_goal: how orientation goals are drawn (`OrientationGoalSettings`); None
        for tasks whose goal is not an orientation.
      version: the suffix of the task's Gymnasium ids, bumped when its goals, dynamics or
        initial state change.
      version_history: what each version after v0 changed, and why (its page shows them).
    """

    name: str = "push"
    description: str = ""
    objects: tuple[ObjectSpec, ...] = (BlockSpec(),)
    goal: str = "object_position"
    object_orientation: str = "euler"
    floor_friction: float = 1.0
    workspace: Workspace = Workspace()
    control: ControlSettings = ControlSettings()
    physics: PhysicsSettings = PhysicsSettings()
    reward_type: str = "sparse"
    distance_threshold: float = 0.05
    terminate_on_success: bool = True
    control_timestep: float = 0.05
    velocity_timestep: float | None = None
    neutral_arm_qpos: tuple[float, ...] = NEUTRAL_ARM_QPOS
    max_episode_steps: int = 50
    observations: ObservationSettings = ObservationSettings()
    randomization: RandomizationSettings = RandomizationSettings()
    orientation_goal: OrientationGoalSettings | None = None
    version: int = 0
    version_history: tuple[str, ...] = ()

    def replace(self, **options) -> "TaskConfig":
        """A copy with `options` (names of `OPTIONS`) set; an unknown name is a ValueError
        listing the valid ones, a bad value one naming the option and what it accepts."""
        options = expand_timing(options)
        check_names("task option", options, OPTION_NAMES)
        config = self
        for name, value in options.items():
            option = OPTIONS[name]
            config = option.set(config, option.check(name, value, config))
        refuse_unread(config, options)
        config.check(since=self)
        return config

    def check(self, since: "TaskConfig | None" = None) -> None:
        """Checks what no single option can: the timestep ratio, a whole number of physics
        steps (to within Composer's own 1e-6 of a step, which it checks again), at most
        `MAX_SUBSTEPS` of them; room to place the objects apart; a neutral pose within
        the joints' ranges with the hand above the floor, objects that start clear of the
        hand, and that can be grasped where goals need them lifted (`clearance`), unless
        what that reads is as in `since`, a config already checked or a task's own."""
        substeps = self.control_timestep / self.physics.timestep
        if round(substeps) < 1 or abs(substeps - round(substeps)) > 1e-6:
            raise ValueError(f"{spelling('control_timestep')} must be a whole multiple of the "
                             f"physics timestep ({self.physics.timestep:g} s), got "
                             f"{self.control_timestep!r}")
        if round(substeps) > MAX_SUBSTEPS:
            raise ValueError(f"{spelling('control_timestep')} must be at most {MAX_SUBSTEPS:,} "
                             f"physics steps of {self.physics.timestep:g} s "
                             f"({MAX_SUBSTEPS * self.physics.timestep:g} s), got "
                             f"{self.control_timestep!r}")
        box = self.workspace.object_box
        if not room_to_place_apart(box.low, box.high,
                                   [spec.footprint_radius for spec in self.objects]):
            sizes = ", ".join(f"{spec.entity_name} {2 * spec.footprint_radius:.3g} m"
                              for spec in self.objects)
            raise ValueError(f"object_range {tuple(box.size)} is too small to place "
                             f"{self.name}'s objects apart at every episode's start "
                             f"(footprints across: {sizes}; {PLACEMENT_MARGIN} m between "
                             f"them; of {CHECKED_PLACEMENTS} simulated starts, one found no "
                             f"room in {MAX_ATTEMPTS} draws): give a wider object_range or "
                             "smaller objects")
        if since is None or clearance_inputs(self) != clearance_inputs(since):
            check_clearance(self)

    @property
    def initial_finger_width(self) -> float:
        """The fingers' opening (m) at reset: open where the gripper is actuated, closed
        where it is locked."""
        return MAX_FINGER_WIDTH if self.control.actuated_gripper else 0.0

    @property
    def lifts_objects(self) -> bool:
        """Whether goals need an object lifted: stacked, or lifted into the air."""
        return bool(self.objects) and (self.goal == "stacked" or (
            self.goal in LIFTED_GOALS and self.workspace.goal_max_height > 0
            and self.workspace.goal_in_air_probability > 0))

    @property
    def lifting_goals(self) -> str:
        """What in the goals needs an object lifted (where `lifts_objects`), for errors."""
        if self.goal == "stacked":
            return "one block stacked on the other"
        workspace = self.workspace
        return (f"goals up to {workspace.goal_max_height:g} m in the air "
                f"{workspace.goal_in_air_probability:.0%} of the time")

    @property
    def time_limit(self) -> float:
        """Seconds an episode lasts unless it ends on success: `max_episode_steps` control
        periods (a 50-step task's: 2.5 s at the default timing, 25 s at the reference one;
        stack's and flip's 100 steps twice that)."""
        return self.max_episode_steps * self.control_timestep

    @property
    def timing_name(self) -> str | None:
        """The name in `TIMINGS` of this configuration's timing, or None for another."""
        return timing_name(self.control.kind, {
            "control_timestep": self.control_timestep,
            "velocity_timestep": self.velocity_timestep,
            "weld_time_constant": self.control.weld_time_constant})

    @property
    def velocity_period(self) -> float:
        """Seconds the observation's velocities are multiplied by."""
        return (self.control_timestep if self.velocity_timestep is None
                else self.velocity_timestep)

    @property
    def options(self) -> dict[str, Any]:
        """Every option this configuration reads, with its value, by name: those that do
        not apply to its task, or that it would refuse as doing nothing here
        (`unread_option`), left out, so that `replace(**config.options)` holds."""
        return {name: option.get(self) for name, option in OPTIONS.items()
                if option.applies_to(self) and unread_option(self, name) is None}
