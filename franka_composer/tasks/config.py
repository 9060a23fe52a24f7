"""Every number a task is made of, as data: frozen records, each default defined once.

A `TaskConfig` is composed of the records the builder hands to the entities and the task
as they are: the object (`BlockSpec` or `PuckSpec`, which builds its prop), the `Workspace`
(where objects start and goals lie), the controller's `ControlSettings` and MuJoCo's
`PhysicsSettings`. The task modules state only what differs from the defaults here.

Users change a task through flat option names, `load("push", distance_threshold=0.03)` or
`gym.make(id, goal_range=(0.2, 0.2))`: `OPTIONS` maps each name to the field it sets and
the check its value must pass, so a bad value is a ValueError naming the option and what it
accepts, raised before anything is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, NamedTuple, Union

import numpy as np
from dm_control.composer.variation import noises

from franka_composer.arenas.floor import MAX_RENDER_SIZE
from franka_composer.controllers import CONTROLS, ControlSettings
from franka_composer.controllers.settings import (REFERENCE_WELD_TIME_CONSTANT,
                                                  WELD_TIME_CONSTANT)
from franka_composer.entities import Block, Prop, Puck
from franka_composer.entities.props import MIN_MASS
from franka_composer.entities.panda import MAX_FINGER_WIDTH, NEUTRAL_ARM_QPOS
from franka_composer.randomization import RandomizationSettings, randomization_settings
from franka_composer.randomization.parameters import unread_parameter
from franka_composer.randomization.settings import from_a_preset
from franka_composer.tasks.clearance import check_clearance, clearance_inputs
from franka_composer.tasks.placement import (CHECKED_PLACEMENTS, MAX_ATTEMPTS,
                                             PLACEMENT_MARGIN, room_to_place_apart)
from franka_composer.tasks.rewards import REWARD_TYPES
from franka_composer.validation import (check_bool, check_choice, check_names, check_number,
                                        check_vector)

def _set(record, name: str, value) -> None:
    """Stores a checked, normalised value on a frozen record (from `__post_init__`)."""
    object.__setattr__(record, name, value)


#: MuJoCo's integrators and friction cones, by their MJCF names.
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
CONES = ("pyramidal", "elliptic")


@dataclasses.dataclass(frozen=True)
class Box2D:
    """An axis-aligned rectangle on the surface: `centre` (x, y) and full `size` (m)."""

    centre: tuple[float, float] = (0.6, 0.0)
    size: tuple[float, float] = (0.3, 0.3)

    @property
    def low(self) -> np.ndarray:
        return np.asarray(self.centre) - np.asarray(self.size) / 2

    @property
    def high(self) -> np.ndarray:
        return np.asarray(self.centre) + np.asarray(self.size) / 2

    def contains(self, xy, tolerance: float = 1e-9) -> bool:
        xy = np.asarray(xy)[:2]
        return bool(np.all(xy >= self.low - tolerance) and np.all(xy <= self.high + tolerance))


@dataclasses.dataclass(frozen=True)
class Workspace:
    """Where the object starts and where goals lie (world frame, m): the paper's 0.3 x 0.3 m
    square centred at (0.6, 0) in front of the robot, for both by default.

    Attributes:
      object_box: where the object's centre starts, on the surface.
      goal_box: where the goal's (x, y) is drawn.
      goal_max_height: the highest a goal is lifted above the object's resting height;
        0 keeps every goal on the surface.
      goal_in_air_probability: chance that a goal is lifted, uniformly in
        [0, goal_max_height], rather than left on the surface.
    """

    object_box: Box2D = Box2D()
    goal_box: Box2D = Box2D()
    goal_max_height: float = 0.0
    goal_in_air_probability: float = 0.0


#: The largest count MuJoCo takes, a C int's: the physics steps of a control step (stepped
#: in one call) and the solver's iteration counts (its MJCF parser refuses more: "number is
#: too large").
MUJOCO_MAX_COUNT = 2**31 - 1

#: The damping of the paper's reference code's block's free joint (its push and
#: pick-and-place XML: `<joint type="free" damping="0.01"/>`; its slide's puck has none):
#: on a 4 cm, 0.1 kg cube a turn dies out within 2.7 ms, so a push slides the block where
#: an undamped one tips over (docs/experiments/push-tip.md). Task option `object_damping`.
REFERENCE_OBJECT_DAMPING = 0.01
#: The tasks the reference code has, each with its object's free-joint damping there; this
#: suite's reach, stack and flip are panda-gym's, which the reference code lacks.
REFERENCE_CODE_OBJECT_DAMPING = {"push": REFERENCE_OBJECT_DAMPING, "slide": 0.0,
                                 "pick_and_place": REFERENCE_OBJECT_DAMPING}


@dataclasses.dataclass(frozen=True)
class BlockSpec:
    """A cube: `half_size` (m), `mass` (kg), sliding `friction`, colour; `coloured_faces`
    tells its faces apart in images; `entity_name` names its observables ("block/position");
    `joint_damping` damps its free joint's six degrees of freedom (N s/m, N m s/rad; none
    by default, as a real block)."""

    half_size: float = 0.02
    mass: float = 1.0
    friction: float = 1.0
    rgba: tuple[float, ...] = (0.1, 0.45, 0.9, 1.0)
    coloured_faces: bool = False
    entity_name: str = "block"
    joint_damping: float = 0.0

    @property
    def footprint_radius(self) -> float:
        """The radius (m) of the circle its upright footprint fits in."""
        return float(np.hypot(self.half_size, self.half_size))

    #: The options that set half its height and half its width across the grasp.
    height_option = grasp_option = "block_half_size"

    @property
    def height(self) -> float:
        return 2 * self.half_size

    @property
    def grasp_width(self) -> float:
        """How far (m) the fingers must open to close on it, as it starts (square to them)."""
        return 2 * self.half_size

    def make(self) -> Prop:
        return Block(half_size=self.half_size, mass=self.mass, friction=self.friction,
                     name=self.entity_name, rgba=self.rgba,
                     coloured_faces=self.coloured_faces)


@dataclasses.dataclass(frozen=True)
class PuckSpec:
    """A cylinder: `radius` and `half_height` (m), `mass` (kg), sliding `friction`;
    `joint_damping` as a block's."""

    radius: float = 0.03
    half_height: float = 0.03
    mass: float = 1.0
    friction: float = 0.04
    entity_name: str = "puck"
    joint_damping: float = 0.0

    @property
    def footprint_radius(self) -> float:
        """The radius (m) of the circle its upright footprint fits in."""
        return self.radius

    #: The options that set half its height and half its width across the grasp.
    height_option, grasp_option = "puck_half_height", "puck_radius"

    @property
    def height(self) -> float:
        return 2 * self.half_height

    @property
    def grasp_width(self) -> float:
        """How far (m) the fingers must open to close on it."""
        return 2 * self.radius

    def make(self) -> Prop:
        return Puck(radius=self.radius, half_height=self.half_height, mass=self.mass,
                    friction=self.friction, name=self.entity_name)


ObjectSpec = Union[BlockSpec, PuckSpec]

#: What an observation holds: the state vector (the paper's), camera images, or both. The
#: goals stay state vectors in every mode, so rewards and HER relabelling are unchanged.
OBSERVATION_MODES = ("state", "pixels", "state+pixels")
#: Cameras that can give pixel observations: the arena's fixed view of the workspace, and
#: one on the hand looking past the fingers (the usual view for grasping).
PIXEL_CAMERAS = ("workspace", "wrist")
#: How the Panda is drawn in camera observations: "hulls", its collision hulls (3k
#: triangles; with one 84 x 84 camera an env step is 6x faster on software GL,
#: `benchmarks/pixels.py`, and at that size it looks the same), or "visual", Menagerie's
#: visual meshes (135k triangles).
CAMERA_MESHES = ("hulls", "visual")


@dataclasses.dataclass(frozen=True)
class ObservationSettings:
    """What the agent observes.

    Attributes:
      mode: one of `OBSERVATION_MODES`.
      cameras: the cameras whose images are observed (in pixel modes), from
        `PIXEL_CAMERAS`, each under the key "<camera>_pixels".
      height, width: each image's size in pixels (84 x 84: the Atari/DrQ convention).
      goal_marker_visible: whether the goal is drawn (a pixel policy must see its goal).
      camera_meshes: how the Panda is drawn in the images, one of `CAMERA_MESHES`.
    """

    mode: str = "state"
    cameras: tuple[str, ...] = ("workspace",)
    height: int = 84
    width: int = 84
    goal_marker_visible: bool = True
    camera_meshes: str = "hulls"

    @property
    def needs_visual_meshes(self) -> bool:
        return self.pixels and self.camera_meshes == "visual"

    @property
    def state(self) -> bool:
        return "state" in self.mode

    @property
    def pixels(self) -> bool:
        return "pixels" in self.mode


@dataclasses.dataclass(frozen=True)
class PhysicsSettings:
    """MuJoCo options for a task (each task module says why its values were chosen).
    Every field is checked when the record is made."""

    timestep: float = 0.002
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    impratio: float = 1.0
    noslip_iterations: int = 0
    iterations: int = 50
    ls_iterations: int = 20

    def __post_init__(self) -> None:
        _set(self, "timestep", check_number("physics.timestep", self.timestep, above=0.0))
        check_choice("physics.integrator", self.integrator, INTEGRATORS)
        check_choice("physics.cone", self.cone, CONES)
        _set(self, "impratio", check_number("physics.impratio", self.impratio, above=0.0))
        for name, minimum in (("noslip_iterations", 0), ("iterations", 1),
                              ("ls_iterations", 1)):
            _set(self, name, check_number(f"physics.{name}", getattr(self, name),
                                          minimum=minimum, maximum=MUJOCO_MAX_COUNT,
                                          integer=True))


#: How an orientation goal (flip) is drawn: "face_up", a face of the cube up at a yaw near
#: the heading the fewest tips give it, which a top-down hand can reach; "uniform",
#: panda-gym's uniformly random orientation, which it mostly cannot (94 % of such goals are
#: more than 0.2 rad from every orientation of a cube resting on a face).
ORIENTATION_GOALS = ("face_up", "uniform")


@dataclasses.dataclass(frozen=True)
class OrientationGoalSettings:
    """How flip's goal orientations are drawn (`ORIENTATION_GOALS`): `kind`, and for
    "face_up" the half-width `yaw_range` (rad) of the uniform yaw offset about world z
    (flip's values, and why, are in `tasks/flip.py`)."""

    kind: str
    yaw_range: float

    def __post_init__(self) -> None:
        check_choice("orientation_goal", self.kind, ORIENTATION_GOALS)
        _set(self, "yaw_range", check_number("goal_yaw_range", self.yaw_range, minimum=0.0,
                                             maximum=float(np.pi)))


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
      floor_friction: sliding friction of the floor.
      workspace: where the object starts and goals lie.
      control: which controller moves the arm, how far an action moves it, and whether
        the gripper is actuated.
      physics: MuJoCo's solver options.
      reward_type: "sparse" (0 / -1) or "dense" (-distance).
      distance_threshold: success radius (m).
      terminate_on_success: end the episode when the goal is reached (the paper); False
        gives Fetch semantics, for which HER relabelling is exact.
      control_timestep: seconds per control step (a whole multiple of the physics step).
      velocity_timestep: seconds the observation's velocities are multiplied by (None: the
        control period, a displacement per step as in Fetch). The reference code steps
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
        check_names("task option", options, [*OPTIONS, "timing"])
        config = self
        for name, value in options.items():
            option = OPTIONS[name]
            config = option.set(config, option.check(name, value, config))
        for name in options:
            why = unread_option(config, name) if name in _READ_ONLY_WHERE else None
            if why is not None:  # (The image options are refused together, below.)
                raise ValueError(f"{name} does nothing here: {why}")
        randomized = config.randomization
        for parameter, distribution in randomized.ranges if randomized.name == "custom" else ():
            why = unread_parameter(parameter, config.name, bool(config.objects),
                                   config.observations.pixels, config.observations.state)
            if why is not None and not from_a_preset(parameter, distribution):
                raise ValueError(f"randomization {parameter!r} does nothing here: {why}: "
                                 "leave it out")
            if (parameter == "angle_noise" and isinstance(distribution, noises.Multiplicative)
                    and config.object_orientation == "quaternion"
                    and config.observations.state):
                raise ValueError(
                    "randomization 'angle_noise' as noises.Multiplicative scales each angle "
                    f"reading, and {config.name} observes its object's orientation as a unit "
                    "quaternion, which a scale cannot turn: give a distribution (three draws "
                    "a step turn it, in rad) or noises.Additive")
        images = [name for name in IMAGE_OPTIONS if name in options]
        if images and not config.observations.pixels:
            raise ValueError(f"{', '.join(images)} set the camera observations, and "
                             f"observation_mode={config.observations.mode!r} has none: give "
                             "observation_mode='pixels' or 'state+pixels', or leave "
                             f"{'it' if len(images) == 1 else 'them'} out")
        config.check(since=self)
        return config

    def check(self, since: "TaskConfig | None" = None) -> None:
        """Checks what no single option can: the timestep ratio, a whole number of physics
        steps (to within Composer's own 1e-6 of a step, which it checks again) that MuJoCo's
        step count (a C int) holds; room to place the objects apart; a neutral pose within
        the joints' ranges with the hand above the floor, objects that start clear of the
        hand, and that can be grasped where goals need them lifted (`clearance`), unless
        what that reads is as in `since`, a config already checked or a task's own."""
        substeps = self.control_timestep / self.physics.timestep
        if round(substeps) < 1 or abs(substeps - round(substeps)) > 1e-6:
            raise ValueError(f"control_timestep must be a whole multiple of the physics "
                             f"timestep ({self.physics.timestep:g} s), got "
                             f"{self.control_timestep!r}")
        if round(substeps) > MUJOCO_MAX_COUNT:
            raise ValueError(f"control_timestep must be at most {MUJOCO_MAX_COUNT:,} physics "
                             f"steps of {self.physics.timestep:g} s, got "
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


@dataclasses.dataclass(frozen=True)
class Option:
    """One user-facing option: the field it sets (a path through the records; a path that
    starts with "objects" sets that field of every object) and the check its value must
    pass (`check(name, value) -> normalised value`)."""

    path: tuple[str, ...]
    check_value: Callable[[str, Any], Any]

    def applies_to(self, config: TaskConfig) -> bool:
        if self.path[0] == "objects":
            return bool(config.objects) and all(hasattr(o, self.path[1])
                                                for o in config.objects)
        record = config
        for field in self.path[:-1]:
            record = getattr(record, field)
        return hasattr(record, self.path[-1])

    def check(self, name: str, value, config: TaskConfig):
        if not self.applies_to(config) and self.path[0] != "objects":
            raise ValueError(f"{name} does not apply to {config.name}: it has no "
                             f"{self.path[0].replace('_', ' ')}")
        if not self.applies_to(config):
            valid = [n for n, o in OPTIONS.items()
                     if o.path[0] == "objects" and o.applies_to(config)]
            kinds = sorted({type(o).__name__.replace("Spec", "").lower()
                            for o in config.objects})
            what = f"its objects are {' and '.join(kinds)}s" if kinds else "it has no object"
            raise ValueError(f"{name} does not apply to {config.name}: {what} "
                             f"(its object options: {', '.join(valid) or 'none'})")
        return self.check_value(name, value)

    def get(self, config: TaskConfig):
        if self.path[0] == "objects":
            return getattr(config.objects[0], self.path[1])
        value = config
        for field in self.path:
            value = getattr(value, field)
        return value

    def set(self, config: TaskConfig, value) -> TaskConfig:
        if self.path[0] == "objects":
            return dataclasses.replace(config, objects=tuple(
                dataclasses.replace(o, **{self.path[1]: value}) for o in config.objects))
        return _replace_path(config, self.path, value)


#: The goals drawn in the goal square (`goal_centre`, `goal_range`; `goals.py`), and those
#: of them that `goal_max_height` and `goal_in_air_probability` lift.
GOAL_SQUARE_GOALS = ("object_position", "tcp_position", "stacked")
LIFTED_GOALS = ("object_position", "tcp_position")


def _lift_unread(config: TaskConfig, name: str, other: str) -> str:
    """Why `name`, one of the two options that lift goals, is not read by `config`."""
    if config.goal not in LIFTED_GOALS:
        return f"{config.name}'s goals ({config.goal}) are never lifted: leave it out"
    value = getattr(config.workspace, other)
    return f"{other}={value:g} lifts no goal: give {other} as well, or leave {name} out"


def _orientation_goal(config: TaskConfig) -> str | None:
    """How `config`'s orientation goals are drawn (`OrientationGoalSettings.kind`); None
    where its goals have no orientation."""
    return None if config.orientation_goal is None else config.orientation_goal.kind


class ReadOnlyWhere(NamedTuple):
    """Where an option that only some configurations read is read: `reads(config)`; what
    such a configuration does instead (`instead`, the refusal's reason), and which other
    setting of the task would read it (`read_with`; None: none, e.g. reach's object
    options), for its page."""

    reads: Callable[[TaskConfig], bool]
    instead: Callable[[TaskConfig], str]
    read_with: Callable[[TaskConfig], str | None]


#: Options that only some configurations read, with the test that one does and what it
#: does instead: given where nothing reads them, they are refused rather than ignored.
#: (Not weld_time_constant: a named timing sets it under every controller, and those
#: without a weld ignore it by design, `ControlSettings`.)
_READ_ONLY_WHERE: dict[str, ReadOnlyWhere] = {
    "max_tcp_step": ReadOnlyWhere(
        lambda c: c.control.moves_the_tcp,
        lambda c: f"control={c.control.kind!r} moves joint targets (max_joint_step): leave "
                  "it out",
        lambda c: "control='mocap' or 'osc'"),
    "max_joint_step": ReadOnlyWhere(
        lambda c: not c.control.moves_the_tcp,
        lambda c: f"control={c.control.kind!r} moves the hand's target (max_tcp_step): "
                  "leave it out",
        lambda c: "control='joints'"),
    "max_finger_step": ReadOnlyWhere(
        lambda c: c.control.actuated_gripper,
        lambda c: "actuated_gripper=False holds the fingers closed: give "
                  "actuated_gripper=True as well, or leave it out",
        lambda c: "actuated_gripper=True"),
    **{name: ReadOnlyWhere(lambda c: bool(c.objects),
                           lambda c: f"{c.name} has no object to place: leave it out",
                           lambda c: None)
       for name in ("object_centre", "object_range")},
    "guard_ignores_carried": ReadOnlyWhere(
        lambda c: bool(c.objects),
        lambda c: f"{c.name} has no object to carry: leave it out",
        lambda c: None),
    **{name: ReadOnlyWhere(lambda c: c.goal in GOAL_SQUARE_GOALS,
                           lambda c: f"{c.name}'s goals ({c.goal}) are not drawn in the goal "
                                     "square: leave it out",
                           lambda c: None)
       for name in ("goal_centre", "goal_range")},
    "goal_yaw_range": ReadOnlyWhere(
        lambda c: _orientation_goal(c) == "face_up",
        lambda c: f"orientation_goal={_orientation_goal(c)!r} draws every orientation, "
                  "not a yaw about face up: leave it out",
        lambda c: "orientation_goal='face_up'"),
    "goal_max_height": ReadOnlyWhere(
        lambda c: c.goal in LIFTED_GOALS and c.workspace.goal_in_air_probability > 0,
        lambda c: _lift_unread(c, "goal_max_height", "goal_in_air_probability"),
        lambda c: "goal_in_air_probability > 0" if c.goal in LIFTED_GOALS else None),
    "goal_in_air_probability": ReadOnlyWhere(
        lambda c: c.goal in LIFTED_GOALS and c.workspace.goal_max_height > 0,
        lambda c: _lift_unread(c, "goal_in_air_probability", "goal_max_height"),
        lambda c: "goal_max_height > 0" if c.goal in LIFTED_GOALS else None),
}


def unread_option(config: TaskConfig, name: str) -> str | None:
    """Why `config` would not read the option `name` (one that applies to its task), or
    None if it does."""
    if name in _READ_ONLY_WHERE and not _READ_ONLY_WHERE[name].reads(config):
        return _READ_ONLY_WHERE[name].instead(config)
    if name in IMAGE_OPTIONS and not config.observations.pixels:
        return (f"observation_mode={config.observations.mode!r} has no camera "
                "observations")
    return None


def read_with(config: TaskConfig, name: str) -> str | None:
    """The other setting of `config`'s task under which it reads the option `name`, which
    it does not read now (`unread_option`); None if none does."""
    if name in _READ_ONLY_WHERE:
        return _READ_ONLY_WHERE[name].read_with(config)
    return "observation_mode='pixels' or 'state+pixels'" if name in IMAGE_OPTIONS else None


def _replace_path(record, path: tuple[str, ...], value):
    if len(path) == 1:
        return dataclasses.replace(record, **{path[0]: value})
    inner = _replace_path(getattr(record, path[0]), path[1:], value)
    return dataclasses.replace(record, **{path[0]: inner})


#: Named timings (task option `timing`), as the options they set. "default": 0.05 s of
#: physics per step (the paper's stated dt; Fetch and panda-gym step 0.04 s), velocities
#: per step, a stiff weld that tracks within it. "reference": what the paper's code
#: (`panda_mujoco_gym`) runs: ten `mj_step(nstep=25)` calls per step, 0.5 s in which the arm
#: settles on its target and the fingers on theirs, with velocities multiplied by its stated
#: 0.05 s, and its weld's time constant, which sets how fast the hand gets there.
TIMINGS: dict[str, dict[str, Any]] = {
    "default": {"control_timestep": 0.05, "velocity_timestep": None,
                "weld_time_constant": WELD_TIME_CONSTANT},
    "reference": {"control_timestep": 0.5, "velocity_timestep": 0.05,
                  "weld_time_constant": REFERENCE_WELD_TIME_CONSTANT},
}


def timing_name(control: str, timing: dict) -> str | None:
    """The name in `TIMINGS` of `timing` (the options a name sets, with their values) under
    the controller `control`, or None for another; the weld counts under mocap only, the
    other controllers having none."""
    for name, named in TIMINGS.items():
        if all(timing[key] == value for key, value in named.items()
               if key != "weld_time_constant" or control == "mocap"):
            return name
    return None


def expand_timing(options: dict) -> dict:
    """`options` with a named `timing` replaced by the options it sets; refused beside one of
    those (one or the other, not both)."""
    if "timing" not in options:
        return options
    options = dict(options)
    timing = TIMINGS[check_choice("timing", options.pop("timing"), tuple(TIMINGS))]
    both = sorted(set(timing) & set(options))
    if both:
        raise ValueError(f"timing sets {', '.join(timing)}: give it or "
                         f"{', '.join(both)}, not both")
    return {**timing, **options}


def plain_value(value):
    """`value` with numpy scalars, also inside a tuple, list or mapping (a randomisation's
    constants), as the Python numbers they hold (JSON, and a dataset's metadata, take
    those)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, list)):
        return type(value)(plain_value(item) for item in value)
    if isinstance(value, dict):
        return {key: plain_value(item) for key, item in value.items()}
    return value


def readable_options(options: dict) -> dict:
    """Task options as a dataset's metadata keeps them: plain values as they are, a
    randomisation as the option takes it (a preset's name, None), others (a custom
    randomisation's distributions) as their repr, which reads like the Python that made
    them."""
    readable = {}
    for name, value in options.items():
        value = plain_value(value)
        if isinstance(value, RandomizationSettings):  # (A config's, not an option given.)
            value = value.option
        readable[name] = (value if isinstance(value, (bool, int, float, str, type(None)))
                          else repr(value))
    return readable


def _positive(name, value):
    return check_number(name, value, above=0.0)


def _non_negative(name, value):
    return check_number(name, value, minimum=0.0)


def _probability(name, value):
    return check_number(name, value, minimum=0.0, maximum=1.0)


def _point(name, value):
    return check_vector(name, value, 2)


def _extent(name, value):
    return check_vector(name, value, 2, minimum=0.0)


def _cameras(name, value):
    cameras = (value,) if isinstance(value, str) else value
    if (not isinstance(cameras, (tuple, list)) or not cameras
            or len(set(map(str, cameras))) != len(cameras)):
        raise ValueError(f"{name} must be a camera name or a non-empty tuple or list of "
                         f"different ones from {', '.join(PIXEL_CAMERAS)}, got {value!r}")
    return tuple(check_choice("camera", camera, PIXEL_CAMERAS) for camera in cameras)


def _pixels(name, value):
    return check_number(name, value, minimum=1, maximum=MAX_RENDER_SIZE, integer=True)


def _physics(name, value):
    if not isinstance(value, PhysicsSettings):
        raise ValueError(f"{name} must be a PhysicsSettings record, got {value!r}")
    return value


#: The options that shape the camera observations alone (goal_marker_visible also hides the
#: goal in render()'s frames): given in a mode without images, they would do nothing.
IMAGE_OPTIONS = ("cameras", "pixel_height", "pixel_width", "camera_meshes")

#: The options users pass, by name: where each goes and what it accepts.
OPTIONS: dict[str, Option] = {
    "object_mass": Option(("objects", "mass"),
                          lambda name, value: check_number(name, value, minimum=MIN_MASS)),
    "object_friction": Option(("objects", "friction"), _non_negative),
    "object_damping": Option(("objects", "joint_damping"), _non_negative),
    "block_half_size": Option(("objects", "half_size"), _positive),
    "puck_radius": Option(("objects", "radius"), _positive),
    "puck_half_height": Option(("objects", "half_height"), _positive),
    "floor_friction": Option(("floor_friction",), _non_negative),
    "object_centre": Option(("workspace", "object_box", "centre"), _point),
    "object_range": Option(("workspace", "object_box", "size"), _extent),
    "goal_centre": Option(("workspace", "goal_box", "centre"), _point),
    "goal_range": Option(("workspace", "goal_box", "size"), _extent),
    "goal_max_height": Option(("workspace", "goal_max_height"), _non_negative),
    "goal_in_air_probability": Option(("workspace", "goal_in_air_probability"), _probability),
    "control": Option(("control", "kind"),
                      lambda name, value: check_choice(name, value, CONTROLS)),
    "actuated_gripper": Option(("control", "actuated_gripper"), check_bool),
    "max_tcp_step": Option(("control", "max_tcp_step"), _positive),
    "max_joint_step": Option(("control", "max_joint_step"), _positive),
    "max_finger_step": Option(("control", "max_finger_step"), _positive),
    "weld_time_constant": Option(("control", "weld_time_constant"), _positive),
    "guard_ignores_carried": Option(("control", "guard_ignores_carried"), check_bool),
    "physics": Option(("physics",), _physics),
    "reward_type": Option(("reward_type",),
                          lambda name, value: check_choice(name, value, REWARD_TYPES)),
    "distance_threshold": Option(("distance_threshold",), _positive),
    "terminate_on_success": Option(("terminate_on_success",), check_bool),
    "control_timestep": Option(("control_timestep",), _positive),
    "velocity_timestep": Option(("velocity_timestep",),
                                lambda name, value: None if value is None
                                else _positive(name, value)),
    "observation_mode": Option(("observations", "mode"),
                               lambda name, value: check_choice(name, value,
                                                                OBSERVATION_MODES)),
    "cameras": Option(("observations", "cameras"), _cameras),
    "pixel_height": Option(("observations", "height"), _pixels),
    "pixel_width": Option(("observations", "width"), _pixels),
    "goal_marker_visible": Option(("observations", "goal_marker_visible"), check_bool),
    "camera_meshes": Option(("observations", "camera_meshes"),
                            lambda name, value: check_choice(name, value, CAMERA_MESHES)),
    "randomization": Option(("randomization",), randomization_settings),
    "orientation_goal": Option(("orientation_goal", "kind"),
                               lambda name, value: check_choice(name, value,
                                                                ORIENTATION_GOALS)),
    "goal_yaw_range": Option(("orientation_goal", "yaw_range"),
                             lambda name, value: check_number(name, value, minimum=0.0,
                                                              maximum=float(np.pi))),
    "neutral_arm_qpos": Option(("neutral_arm_qpos",),
                               lambda name, value: check_vector(name, value, 7)),
}

