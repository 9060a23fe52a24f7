"""The task options users pass by flat name, `load("push", distance_threshold=0.03)` or
`gym.make(id, goal_range=(0.2, 0.2))`: `OPTIONS` maps each name to the field of a
`TaskConfig` it sets and the check its value must pass, so a bad value is a ValueError
naming the option and what it accepts, raised before anything is built; an option that the
configuration would not read is refused, with what would (`unread_option`, `read_with`).
The named timings (`TIMINGS`) are options too, and datasets keep options as
`readable_options` writes them.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, Callable, NamedTuple

import numpy as np
from dm_control.composer.variation import noises

from franka_composer.arenas.floor import MAX_RENDER_SIZE
from franka_composer.controllers import CONTROLS
from franka_composer.controllers.settings import (REFERENCE_WELD_TIME_CONSTANT, TCP_CONTROLS,
                                                  WELD_TIME_CONSTANT, has_weld)
from franka_composer.entities.props import MIN_MASS
from franka_composer.randomization import RandomizationSettings, randomization_settings
from franka_composer.randomization.parameters import unread_parameter
from franka_composer.randomization.settings import from_a_preset
from franka_composer.tasks.records import (CAMERA_MESHES, OBSERVATION_MODES, ORIENTATION_GOALS,
                                           PIXEL_CAMERAS, PhysicsSettings)
from franka_composer.tasks.rewards import REWARD_TYPES
from franka_composer.validation import (check_bool, check_choice, check_number, check_vector,
                                        spelling)

if TYPE_CHECKING:
    from franka_composer.tasks.config import TaskConfig


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
            raise ValueError(f"{spelling(name)} does not apply to {config.name}: it has no "
                             f"{self.path[0].replace('_', ' ')}")
        if not self.applies_to(config):
            valid = [n for n, o in OPTIONS.items()
                     if o.path[0] == "objects" and o.applies_to(config)]
            kinds = sorted({type(o).__name__.replace("Spec", "").lower()
                            for o in config.objects})
            what = f"its objects are {' and '.join(kinds)}s" if kinds else "it has no object"
            raise ValueError(f"{spelling(name)} does not apply to {config.name}: {what} "
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
    return (f"{other}={value:g} lifts no goal: give {other}{_grasping(config)} as well, or "
            f"leave {name} out")


def _grasping(config: TaskConfig) -> str:
    """What else lifting `config`'s goals needs: an object lifted to its goal needs fingers
    that grasp (`clearance.py`)."""
    return (" and actuated_gripper=True" if config.goal == "object_position"
            and not config.control.actuated_gripper else "")


def _lift_with(config: TaskConfig, setting: str) -> str | None:
    """The settings under which `config` reads an option that lifts goals, for its page."""
    return f"{setting}{_grasping(config)}" if config.goal in LIFTED_GOALS else None


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
        lambda c: "control=" + " or ".join(repr(kind) for kind in TCP_CONTROLS)),
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
        lambda c: _lift_with(c, "goal_in_air_probability > 0")),
    "goal_in_air_probability": ReadOnlyWhere(
        lambda c: c.goal in LIFTED_GOALS and c.workspace.goal_max_height > 0,
        lambda c: _lift_unread(c, "goal_in_air_probability", "goal_max_height"),
        lambda c: _lift_with(c, "goal_max_height > 0")),
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


def refuse_unread(config: TaskConfig, given) -> None:
    """A ValueError for an option in `given` (names) that `config`, made with them, would
    not read, or a custom randomisation's parameter that would do nothing there: refused
    rather than ignored, with what would read it."""
    for name in given:
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
    images = [name for name in IMAGE_OPTIONS if name in given]
    if images and not config.observations.pixels:
        raise ValueError(f"{', '.join(images)} set the camera observations, and "
                         f"observation_mode={config.observations.mode!r} has none: give "
                         "observation_mode='pixels' or 'state+pixels', or leave "
                         f"{'it' if len(images) == 1 else 'them'} out")


def _replace_path(record, path: tuple[str, ...], value):
    if len(path) == 1:
        return dataclasses.replace(record, **{path[0]: value})
    inner = _replace_path(getattr(record, path[0]), path[1:], value)
    return dataclasses.replace(record, **{path[0]: inner})


#: Named timings (task option `timing`), as the options they set. "default": 0.05 s of
#: physics per step (the reference code's stated dt: the paper gives only the 2 ms physics
#: step; Fetch and panda-gym step 0.04 s), velocities
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
               if key != "weld_time_constant" or has_weld(control)):
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

#: The names `TaskConfig.replace` takes: the options and `timing` (which sets three).
OPTION_NAMES = (*OPTIONS, "timing")
