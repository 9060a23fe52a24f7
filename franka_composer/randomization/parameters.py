"""What can be randomised, each parameter once: its group, what a sample is, what it means.

A randomisation is data: a mapping from these names to `composer.variation` distributions
(or constants), `RandomizationSettings`. Each episode every episode parameter is drawn once,
by calling its distribution with `initial_value` set to the parameter's nominal value in its
own terms (`Parameter.nominal`: 1 for a factor, the object's colour for `object_rgb`, zeros
for an offset), so `Uniform(0.8, 1.2)` and `noises.Multiplicative(Uniform(0.8, 1.2))` both
work. A noise parameter's distribution (or constant, or arithmetic on distributions)
draws what is added to each reading (or action), one number per component, afresh every
control step; Composer's noise wrappers (`noises.Additive`, `noises.Multiplicative`) are
applied to the reading as its corruptors are (`noisy`).

Samples are checked before anything reaches MuJoCo: a factor must be finite and > 0, a
colour within [0, 1], a delay a whole number of control steps >= 0. Where the range a
distribution draws in is known (`ranges.draw_range`), it is checked as the option is set: a factor
drawn from `Normal(1, 0.1)` is refused then, not at the episode, hours into a run, whose
draw first goes below 0.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from dm_control.composer.variation import noises, variation_values

from franka_composer.randomization.ranges import Interval

#: The groups, in the order their streams are split off (`randomizer.py`): each group
#: draws from its own stream, so randomising one never changes what another draws.
GROUPS = ("physics", "visual", "sensing", "action")

#: Longest observation delay (control steps): Composer keeps every reading in flight.
MAX_DELAY = 50


#: What a sample of each bounded kind must be, and the bounds (a factor's open at 0).
_REQUIREMENTS = {"factor": "is a factor and must draw > 0",
                 "colour": "is a colour and must draw numbers in [0, 1]",
                 "steps": f"must draw a whole number of control steps in [0, {MAX_DELAY}]"}
_BOUNDS = {"factor": (0.0, np.inf), "colour": (0.0, 1.0), "steps": (0.0, float(MAX_DELAY))}


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One randomisable quantity.

    Attributes:
      group: one of `GROUPS`.
      kind: "factor" (scales a nominal value, > 0), "colour" (RGB in [0, 1]), "offset" (a
        3-vector added to a nominal one), "angle" (rad), "steps" (control steps, >= 0), or
        "noise" (added to every reading or action).
      meaning: what it changes, for the guide's table.
      unit: of a sample.
      per_object: drawn once per object (each object its own), else once per episode.
      on_objects: drawn once per episode, and acts on the objects alone (their contacts):
        nothing without one, as a per-object parameter.
      observed_cameras: it moves the cameras whose images are observed.
    """

    group: str
    kind: str
    meaning: str
    unit: str = "–"
    per_object: bool = False
    on_objects: bool = False
    observed_cameras: bool = False

    @property
    def needs_objects(self) -> bool:
        """Whether it does nothing on a task without objects (reach)."""
        return self.per_object or self.on_objects

    @property
    def episode(self) -> bool:
        """Whether it is drawn once per episode (reported), rather than every step."""
        return self.kind != "noise"

    def nominal(self, colour=None):
        """The `initial_value` its distribution is called with: the identity of its kind."""
        if self.kind == "factor":
            return 1.0
        if self.kind == "colour":
            return np.ones(3) if colour is None else np.asarray(colour[:3], dtype=np.float64)
        if self.kind == "offset":
            return np.zeros(3)
        if self.kind in ("angle", "steps"):
            return 0
        raise ValueError(f"a {self.kind} parameter has no episode value")

    def check_range(self, name: str, distribution, drawn: Interval | None) -> None:
        """A ValueError naming `name` where the range `distribution` draws in (`drawn`,
        `ranges.draw_range`; None: not known) holds values a sample may not take."""
        if drawn is None or self.kind not in _BOUNDS:
            return
        if np.isnan([drawn.low, drawn.high]).any():
            return  # No range: the draws say why (`Uniform(nan, 1)` cannot draw).
        least, most = _BOUNDS[self.kind]
        if not drawn.within(least, most, above_least=self.kind == "factor"):
            raise ValueError(f"randomization {name!r} {_REQUIREMENTS[self.kind]}, and "
                             f"{distribution!r} draws in {drawn}: refused now, "
                             f"not at the first reset that draws outside (maybe hours into "
                             f"a run); bound it")

    def check(self, name: str, value) -> np.ndarray | float | int:
        """A sample as a float, int or float array, or a ValueError naming `name`."""
        array = np.asarray(value, dtype=np.float64) if _real(value) else None
        shape = (3,) if self.kind in ("colour", "offset") else ()
        if array is None or array.shape != shape or not np.isfinite(array).all():
            what = "3 finite numbers" if shape else "one finite number"
            raise ValueError(f"randomization {name!r} must draw {what}, drew {value!r}")
        requirement = f"randomization {name!r} {_REQUIREMENTS.get(self.kind)}"
        if self.kind == "factor" and not array > 0:
            raise ValueError(f"{requirement}, drew {float(array)!r}")
        if self.kind == "colour" and not ((array >= 0) & (array <= 1)).all():
            raise ValueError(f"{requirement}, drew {array.tolist()}")
        if self.kind == "steps":
            if array != np.round(array) or not 0 <= array <= MAX_DELAY:
                raise ValueError(f"{requirement}, drew {value!r}")
            return int(array)
        return array if shape else float(array)


def noisy(distribution, value: np.ndarray, random_state) -> np.ndarray:
    """`value` (a reading or an action) with the noise `distribution` gives it
    (`noise`)."""
    return value + noise(distribution, value, random_state)


def noise(distribution, value: np.ndarray, random_state) -> np.ndarray:
    """What the noise `distribution` adds to `value`: a distribution, arithmetic on them or
    a constant draws it (one number per component: Composer sizes a draw to
    `initial_value`); a noise wrapper is applied to the value itself (`noises.Additive(d)`
    gives value + d's draw, `noises.Multiplicative(d)` value times it), as Composer's
    corruptors apply them, and adds the difference."""
    drawn = variation_values.evaluate(distribution, value, value, random_state)
    if relative(distribution):
        return np.asarray(drawn, dtype=np.float64) - value
    return drawn


def relative(distribution) -> bool:
    """Whether `distribution` is one of Composer's noise wrappers, which vary the value
    they are called with (`noises.Additive`, `noises.Multiplicative`), rather than draw
    independently of it (a distribution, arithmetic on distributions, a constant)."""
    return isinstance(distribution, (noises.Additive, noises.Multiplicative))


def _real(value) -> bool:
    try:
        array = np.asarray(value)
    except Exception:  # pylint: disable=broad-except
        return False
    return array.dtype.kind in "iuf"


#: Every randomisable parameter, by the name a randomisation mapping uses.
PARAMETERS: dict[str, Parameter] = {
    # Physics: model values written each episode, no recompilation.
    "object_mass": Parameter("physics", "factor", "each object's mass (its inertia with it)",
                             per_object=True),
    "object_friction": Parameter("physics", "factor",
                                 "each object's sliding friction: scales its contacts with the "
                                 "floor and the other objects (the hand's keep theirs: the "
                                 "finger pads' friction 2 rules the grip)", per_object=True),
    "floor_friction": Parameter("physics", "factor",
                                "the floor's sliding friction: scales its contacts with the "
                                "objects", on_objects=True),
    "gripper_gain": Parameter("physics", "factor",
                              "the gripper servo's stiffness (damping kept at its ratio)"),
    "joint_damping": Parameter("physics", "factor", "the arm joints' damping"),
    "controller_gain": Parameter("physics", "factor",
                                 "the controller's stiffness: mocap's weld, osc's impedance, "
                                 "the joint servos (each keeps its damping rule)"),
    # Visual: what the cameras see, nothing the simulation computes.
    "object_rgb": Parameter("visual", "colour",
                            "each object's colour, and its goal marker's where the marker "
                            "wears it (stack's blocks, flip's cube)", "RGB", per_object=True),
    "floor_tint": Parameter("visual", "colour", "the floor's colour, multiplying its checker",
                            "RGB"),
    "robot_tint": Parameter("visual", "colour", "the Panda's colours, multiplied", "RGB"),
    "light_direction": Parameter("visual", "offset",
                                 "added to each light's direction (then normalised)", "–"),
    "light_intensity": Parameter("visual", "factor", "the lights' diffuse intensity"),
    "camera_position": Parameter("visual", "offset",
                                 "added to each observed camera's position (its body's frame)",
                                 "m", observed_cameras=True),
    "camera_rotation": Parameter("visual", "angle",
                                 "each observed camera turned by this about a random axis",
                                 "rad", observed_cameras=True),
    # Sensing: what the policy reads of the robot and the objects (not the goals).
    "position_noise": Parameter("sensing", "noise",
                                "added to every position reading (TCP, objects, fingers)", "m"),
    "angle_noise": Parameter("sensing", "noise",
                             "added to every angle reading (Euler angles, joint angles); a "
                             "quaternion is turned by a rotation vector of three draws",
                             "rad"),
    "velocity_noise": Parameter("sensing", "noise",
                                "added to every velocity reading, before it is made per step",
                                "m/s, rad/s"),
    "observation_delay": Parameter("sensing", "steps",
                                   "the observation (state and images) is this many control "
                                   "steps old", "steps"),
    # Actuation.
    "action_noise": Parameter("action", "noise", "added to every action component before it "
                              "is clipped to [-1, 1]"),
}


def noise_parameter(field) -> str:
    """The noise parameter a state-vector field's readings get (`layout.ObservationField`):
    velocities (per step in the vector), positions (m), or angles (orientations, joints)."""
    if field.per_control_step:
        return "velocity_noise"
    return "position_noise" if field.unit == "m" else "angle_noise"


def unread_parameter(name: str, task: str, objects: bool, cameras: bool,
                     state: bool) -> str | None:
    """Why the parameter `name` would do nothing on `task` (with `objects` to move,
    `cameras` whose images are observed, and a `state` vector observed), or None: a custom
    mapping naming it is refused (a preset, and a mapping's entries taken from one, give
    what applies where they are used)."""
    parameter = PARAMETERS[name]
    if parameter.needs_objects and not objects:
        return f"{task} has no object"
    if parameter.observed_cameras and not cameras:
        return "no camera's images are observed (observation_mode 'state')"
    if parameter.group == "sensing" and parameter.kind == "noise" and not state:
        return ("no state vector is observed (observation_mode 'pixels'), and the noise is "
                "added to its readings, not to images")
    return None
