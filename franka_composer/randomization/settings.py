"""The `randomization` task option: None (off, the default), a preset's name, or a mapping
from `PARAMETERS` names to `composer.variation` distributions (or constants).

`PRESETS["default"]` holds ranges a sim-to-real user would start from, each with its reason.
Build on it in Python: `{**PRESETS["default"], "object_mass": Uniform(0.2, 2.0)}`; a value of
None leaves that parameter out.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

import numpy as np
from dm_control.composer.variation import distributions, variation_values

from franka_composer.randomization.parameters import PARAMETERS, noisy, relative
from franka_composer.randomization.ranges import draw_range, is_constant
from franka_composer.validation import check_choice, check_names

#: Each preset: parameter -> (distribution class, its arguments, why this range).
PRESET_REASONS: dict[str, dict[str, tuple[type, tuple, str]]] = {"default": {
    "object_mass": (distributions.Uniform, (0.5, 1.5),
                    "the objects' real mass is rarely known: +-50 % of each task's (1 kg "
                    "on push and slide, 0.1 kg on the others)"),
    "object_friction": (distributions.Uniform, (0.7, 1.3),
                        "friction coefficients are known to +-30 % at best (tables for common "
                        "material pairs spread that much); an object on the table top slides "
                        "at the product of both factors, the grip stays the finger pads'"),
    "floor_friction": (distributions.Uniform, (0.7, 1.3), "the same, for the table top"),
    "gripper_gain": (distributions.Uniform, (0.8, 1.2),
                     "a real gripper's grip force varies with its firmware and wear"),
    "joint_damping": (distributions.Uniform, (0.5, 1.5),
                      "Menagerie's 1 N m s is nominal; identified joint friction differs "
                      "from it by about this much (one factor scales all seven joints)"),
    "controller_gain": (distributions.Uniform, (0.8, 1.2),
                        "the real controller tracks differently from the simulated one: "
                        "+-20 % stiffness is +-10 % bandwidth"),
    "object_rgb": (distributions.Uniform, (0.05, 0.95),
                   "any colour: a pixel policy must find the object by shape, not hue"),
    "floor_tint": (distributions.Uniform, (0.6, 1.0), "table tops differ in shade and hue"),
    "robot_tint": (distributions.Uniform, (0.7, 1.0),
                   "the arm's paint and lighting make it look different on every camera"),
    "light_direction": (distributions.Uniform, (-0.3, 0.3),
                        "room lights come from anywhere within ~30 degrees of the nominal "
                        "(half the draws within 13: experiments/light_angles.py)"),
    "light_intensity": (distributions.Uniform, (0.6, 1.4),
                        "brightness changes with the room and the time of day"),
    "camera_position": (distributions.Uniform, (-0.01, 0.01),
                        "a camera mount is calibrated to about 1 cm"),
    "camera_rotation": (distributions.Uniform, (-0.035, 0.035),
                        "and to about 2 degrees in orientation"),
    "position_noise": (distributions.Normal, (0.0, 0.001),
                       "pose estimates (motion capture, fiducials) are good to ~1 mm"),
    "angle_noise": (distributions.Normal, (0.0, 0.01),
                    "and to ~0.6 degrees in orientation"),
    "velocity_noise": (distributions.Normal, (0.0, 0.01),
                       "velocities are differences of noisy positions: ~1 cm/s"),
    "observation_delay": (distributions.UniformInteger, (0, 2),
                          "a camera-based estimate often arrives one 50 ms step late: 0 or 1 "
                          "(numpy's high end is exclusive)"),
    "action_noise": (distributions.Normal, (0.0, 0.05),
                     "commands are not executed exactly: 5 % of a full command"),
}}

#: The attribute that marks a preset's own entry with (preset, parameter): it travels with
#: the distribution through copies and pickles (a vector env's spawned worker), as identity
#: does not, and an entry of one's own that draws the same has none (`from_a_preset`).
PRESET_MARK = "_franka_composer_preset"


def _preset_entry(name: str, parameter: str, kind, arguments):
    entry = kind(*arguments)
    setattr(entry, PRESET_MARK, (name, parameter))
    return entry


#: The presets, as mappings the option takes.
PRESETS: dict[str, dict[str, Any]] = {
    name: {parameter: _preset_entry(name, parameter, kind, arguments)
           for parameter, (kind, arguments, _) in reasons.items()}
    for name, reasons in PRESET_REASONS.items()}


def from_a_preset(parameter: str, distribution) -> bool:
    """Whether `distribution` is a preset's own for `parameter` (a mapping built on a preset,
    `{**PRESETS["default"], ...}`, or a copy or pickle of one: `PRESET_MARK`): such an entry
    applies where it can, as the preset does, rather than being refused where the env does
    not have what it varies; one's own that draws the same is refused there."""
    mark = getattr(distribution, PRESET_MARK, None)
    return isinstance(mark, tuple) and len(mark) == 2 and mark[1] == parameter


#: Draws taken from each distribution when the option is set, to refuse a range that can
#: leave its parameter's domain (e.g. a negative mass factor) before any episode.
PROBE_DRAWS = 64


@dataclasses.dataclass(frozen=True)
class RandomizationSettings:
    """Which parameters are randomised, and how: (name, distribution) pairs in `PARAMETERS`
    order; `name` is the preset's name, or "custom"."""

    ranges: tuple[tuple[str, Any], ...] = ()
    name: str = "off"

    @property
    def enabled(self) -> bool:
        return bool(self.ranges)

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.ranges)

    def __hash__(self) -> int:
        # Composer's distributions compare by value but are not hashable.
        return hash((self.name, self.parameters))

    @property
    def option(self):
        """What the option was given: None, a preset's name, or the mapping."""
        if not self.ranges:
            return None
        return self.name if self.name in PRESETS else dict(self.ranges)

    def __repr__(self) -> str:
        return repr(self.option)


def markdown_table(preset: str = "default") -> str:
    """The guide's table: every parameter, what a sample is and does, the preset's range
    and why."""
    reasons = PRESET_REASONS[preset]
    lines = [f"| parameter | group | sample | unit | what it does | `{preset}` | why |",
             "|---|---|---|---|---|---|---|"]
    for name, parameter in PARAMETERS.items():
        kind, arguments, reason = reasons.get(name, (None, (), "–"))
        drawn = (f"`{kind.__name__}{arguments}`" if kind else "off")
        each = ", per object" if parameter.per_object else ""
        lines.append(f"| `{name}` | {parameter.group} | {parameter.kind}{each} | "
                     f"{parameter.unit} | {parameter.meaning} | {drawn} | {reason} |")
    return "\n".join(lines)


def randomization_settings(name: str, value) -> RandomizationSettings:
    """The option's value as settings: None, a preset's name, a mapping or settings."""
    if isinstance(value, RandomizationSettings):
        return value
    if value is None:
        return RandomizationSettings()
    if isinstance(value, str):
        check_choice(name, value, tuple(PRESETS), also="None or a mapping")
        return _settings(name, PRESETS[value], value)
    if isinstance(value, Mapping):
        return _settings(name, value, "custom")
    raise ValueError(f"{name} must be None, a preset ({', '.join(PRESETS)}) or a mapping from "
                     f"parameter names to composer.variation distributions, got {value!r}")


def _settings(name: str, mapping: Mapping, label: str) -> RandomizationSettings:
    check_names(f"{name} parameter", mapping, PARAMETERS)
    ranges = tuple((parameter, mapping[parameter]) for parameter in PARAMETERS
                   if mapping.get(parameter) is not None)
    probe = np.random.RandomState(0)
    for parameter, distribution in ranges:
        spec = PARAMETERS[parameter]
        if not (callable(distribution) or is_constant(distribution)):
            raise ValueError(f"{name} {parameter!r} must be a composer.variation distribution "
                             f"or a constant, got {distribution!r}")
        for _ in range(PROBE_DRAWS):
            if spec.episode:
                sample = _probe_draw(name, parameter, distribution, spec.nominal(), probe)
                if spec.per_object and spec.kind == "colour" and relative(distribution):
                    # About each object's own colour: its range is probed from that
                    # colour where it is known (`Randomizer`); here its shape, finite.
                    sample = np.clip(sample, 0.0, 1.0)
                spec.check(parameter, sample)
            else:
                # Readings of one number (a finger width) and of seven (joint angles).
                for reading in (np.ones(1), np.ones(7)):
                    _check_noise(parameter, reading, _probe_draw(
                        name, parameter, distribution, reading, probe, noise=True))
        if spec.episode and not (spec.per_object and spec.kind == "colour"
                                 and relative(distribution)):
            # Draws it could make later (a jitter about each object's own colour is checked
            # from that colour: `Randomizer`).
            spec.check_range(parameter, distribution, draw_range(distribution, spec.nominal()))
    return RandomizationSettings(ranges, label)


def _probe_draw(name: str, parameter: str, distribution, nominal, probe, noise=False):
    """One draw of `distribution` (for a `noise`, the noisy `nominal` reading); whatever
    it raises (numpy's bare "scale < 0", an OverflowError for a NaN or infinite bound, a
    draw that does not fit the reading) becomes a ValueError naming the parameter."""
    try:
        if noise:
            return noisy(distribution, nominal, probe)
        return variation_values.evaluate(distribution, nominal, nominal, probe)
    except Exception as error:  # pylint: disable=broad-except
        raise ValueError(f"{name} {parameter!r} cannot draw from {distribution!r}: "
                         f"{type(error).__name__}: {error}") from error


def _check_noise(parameter: str, reading: np.ndarray, sample) -> None:
    """The noisy `reading` must be finite numbers of its shape: noise draws one number per
    component of whatever reading it is added to (a distribution without a size, or one
    number), not a fixed number of them (a finger width is one number, the joint angles
    seven)."""
    array = np.asarray(sample)
    what = (f"randomization {parameter!r} is noise added to each reading, one finite number "
            "per component (a distribution without a size, or one number)")
    if array.dtype.kind not in "iuf":
        raise ValueError(f"{what}: it drew {sample!r}")
    if array.shape != reading.shape:
        raise ValueError(f"{what}: added to a reading of {reading.size} number(s), it makes "
                         f"{array.size}")
    if not np.isfinite(array).all():
        raise ValueError(f"{what}: it drew {(array - reading).tolist()}")
