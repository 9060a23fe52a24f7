"""The records a task is composed of, each default defined once: where objects start and
goals lie (`Workspace`), the object (`BlockSpec` or `PuckSpec`, which builds its prop), what
is observed (`ObservationSettings`), MuJoCo's solver options (`PhysicsSettings`) and how an
orientation goal is drawn (`OrientationGoalSettings`). `TaskConfig` (`config.py`) holds them
with the task's own numbers; the builder hands them to the entities and the task as they are.
"""

from __future__ import annotations

import dataclasses
from typing import Union

import numpy as np

from franka_composer.entities import Block, Prop, Puck
from franka_composer.validation import check_choice, check_number


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

#: The most physics steps one control step may take: 100 s at the tasks' 2 ms, 200 times the
#: reference code's 0.5 s and about a second of computing. MuJoCo runs them in one call,
#: which Ctrl-C and SIGTERM wait for: a mistyped timestep (2000001 for 0.002) made each
#: step run for hours, past their reach.
MAX_SUBSTEPS = 50_000

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
    """A cube: `half_size` (m), `mass` (kg), sliding `friction` (its contacts with the floor
    and other objects take the smaller coefficient, `contacts.surface_friction`), colour;
    `coloured_faces` tells its faces apart in images; `entity_name` names its observables
    ("block/position"); `joint_damping` damps its free joint's six degrees of freedom
    (N s/m, N m s/rad; none by default, as a real block)."""

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
    """A cylinder: `radius` and `half_height` (m), `mass` (kg), sliding `friction` and
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
