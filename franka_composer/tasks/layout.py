"""The flat `observation` vector's layout, in one object, from the task's configuration.

`layout_for(config)` says what the vector holds (the paper's order); the task enables
exactly those observables, the Gymnasium adapter flattens observations with it, the
scripted experts read their fields from it by name, and the guide's tables and each id's
documentation page are generated from it (`markdown_table`, checked by `tests/test_docs.py`).
No offset into the vector is written anywhere else.
"""

from __future__ import annotations

from typing import Mapping, NamedTuple

import numpy as np

#: dtype of the observation vectors.
OBSERVATION_DTYPE = np.float64


class ObservationField(NamedTuple):
    """One slice of the flat `observation` vector."""

    name: str  # What it is, by which experts and users read it: "object_position".
    key: str  # The Composer observable it comes from, "<entity>/<observable>": "block/position".
    size: int
    meaning: str
    unit: str
    per_control_step: bool  # Multiplied by the velocity period (Fetch's velp * dt).
    frame: str = "world"  # "world", or "–" for a quantity without one (a finger width).

    @property
    def quaternion(self) -> bool:
        """Whether it is an orientation as a unit quaternion (angle noise turns it)."""
        return self.key.rsplit("/", 1)[1] == _ORIENTATIONS["quaternion"][0]


class ObservationLayout:
    """The fields of the flat observation vector, in order; velocities (the step's last,
    per second) are multiplied by `velocity_period` (`TaskConfig.velocity_period`: the
    control period, as Fetch's velp * dt, unless `velocity_timestep` sets another)."""

    def __init__(self, fields, velocity_period: float) -> None:
        self.fields: tuple[ObservationField, ...] = tuple(fields)
        self.velocity_period = float(velocity_period)
        self.keys = tuple(field.key for field in self.fields)
        starts = np.cumsum([0] + [field.size for field in self.fields])
        self._slices = {field.name: slice(int(start), int(start) + field.size)
                        for field, start in zip(self.fields, starts)}
        # Per element: the velocity period for per-step fields, else 1 (x * 1.0 == x exactly).
        self.scale = np.concatenate([
            np.full(f.size, self.velocity_period if f.per_control_step else 1.0)
            for f in self.fields])

    @property
    def size(self) -> int:
        return int(sum(field.size for field in self.fields))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._slices)

    def __contains__(self, name: str) -> bool:
        return name in self._slices

    def slice(self, name: str) -> slice:
        """Where field `name` lies in the vector; a KeyError naming the fields otherwise."""
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no field {name!r} in this observation; fields: "
                           f"{', '.join(self._slices)}") from None

    def read(self, vector, name: str) -> np.ndarray:
        """Field `name` of `vector` (any leading batch shape); a ValueError for a vector
        that is not of this layout's size, which would read as a shorter or empty field."""
        vector = np.asarray(vector)
        if vector.shape[-1:] != (self.size,):
            raise ValueError(f"an observation of this layout has {self.size} values, got one "
                             f"of shape {vector.shape}")
        return vector[..., self.slice(name)]

    def flatten(self, observables: Mapping[str, np.ndarray]) -> np.ndarray:
        """The vector from Composer observables (SI units): concatenated, velocities
        multiplied by the velocity period. One concatenation and one multiply: this runs
        every step."""
        vector = np.concatenate([observables[key].ravel() for key in self.keys],
                                dtype=OBSERVATION_DTYPE)
        vector *= self.scale
        return vector

    def markdown_table(self) -> str:
        """The guide's table: index, field name, meaning, unit, frame, Composer observable."""
        lines = ["| index | field | meaning | unit | frame | Composer observable |",
                 "|---|---|---|---|---|---|"]
        for field in self.fields:
            where = self._slices[field.name]
            index = (str(where.start) if field.size == 1
                     else f"{where.start}–{where.stop - 1}")
            unit = (f"{field.unit} × {self.velocity_period:g} s" if field.per_control_step
                    else field.unit)
            lines.append(f"| {index} | `{field.name}` | {field.meaning} | {unit} | "
                         f"{field.frame} | "
                         f"`{field.key}` |")
        return "\n".join(lines)


#: The robot's fields, first: (name, observable, size, meaning, unit, per step). The finger
#: width is in the vector only where the gripper is actuated.
_ROBOT_FIELDS = (
    ("tcp_position", "tcp_position", 3, "end-effector (tool centre point) position", "m",
     False),
    ("tcp_velocity", "tcp_linear_velocity", 3, "end-effector linear velocity", "m/s",
     True),
    ("finger_width", "finger_width", 1, "finger width", "m", False),
)
#: Each object's orientation, as the task observes it: (observable, size, meaning, unit).
_ORIENTATIONS = {
    "euler": ("orientation_euler", 3, "orientation (roll, pitch, yaw; x-y-z extrinsic)", "rad"),
    "quaternion": ("orientation", 4, "orientation (unit quaternion w, x, y, z)", "–"),
}


def layout_for(config) -> ObservationLayout:
    """The observation layout of the task `config` (a `TaskConfig`) describes: the robot's
    fields, then per object its position, orientation, linear and angular velocity (the
    paper's order; fields "object_position"..., or "object1_position"... for several), then,
    under joint control, the arm's joint angles."""
    fields = [ObservationField(name, f"panda/{observable}", size, meaning, unit, per_step,
                               "–" if name == "finger_width" else "world")
              for name, observable, size, meaning, unit, per_step in _ROBOT_FIELDS
              if name != "finger_width" or config.control.actuated_gripper]
    several = len(config.objects) > 1
    orientation, size, meaning, unit = _ORIENTATIONS[config.object_orientation]
    for index, spec in enumerate(config.objects):
        prefix = f"object{index + 1}" if several else "object"
        label = f"object {index + 1}" if several else "object"
        entity = spec.entity_name
        fields += [
            ObservationField(f"{prefix}_position", f"{entity}/position", 3,
                             f"{label} position", "m", False),
            ObservationField(f"{prefix}_orientation", f"{entity}/{orientation}", size,
                             f"{label} {meaning}", unit, False),
            ObservationField(f"{prefix}_linear_velocity", f"{entity}/linear_velocity", 3,
                             f"{label} linear velocity", "m/s", True),
            ObservationField(f"{prefix}_angular_velocity", f"{entity}/angular_velocity", 3,
                             f"{label} angular velocity", "rad/s", True),
        ]
    if config.control.kind == "joints":
        # Last, so every other field keeps its index under every controller.
        fields.append(ObservationField("joint_angles", "panda/joints_pos", 7,
                                       "arm joint angles, joint 1 first", "rad", False, "–"))
    return ObservationLayout(fields, config.velocity_period)
