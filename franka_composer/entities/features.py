"""Observables that read MuJoCo's arrays through NumPy views taken once per compiled model.

`observable.MJCFFeature("xpos", site)` reads through a dm_control binding on every call
(~2 us: attribute dispatch and a dirty-state check), and `observable.Generic(lambda physics:
f(physics.bind(element).attr))` binds again on every call. Per step and per observable that
is most of an observation's cost. `ArrayFeature` takes a view of the element's slice of
MjData when Composer asks for the observation callable (once per compiled model), and each
reading copies that slice, through an optional transform. It is a `Generic` observable
whose public `observation_callable` returns that reader (with the observable's corruptor,
as Composer's own does).

A view skips dm_control's "dirty" check, which runs `mj_forward` before reading when
positions were written since the last forward. Composer reads observables only after a
reset (whose context ends with `mj_forward`) and after a step (whose legacy stepping ends
with `mj_step1`), where the values are current either way; the equivalence is pinned in
`tests/test_observables.py` against fresh binding reads.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from dm_control.composer.observation import observable


class ArrayFeature(observable.Generic):
    """Attribute `kind` of `element` (e.g. a sensor's "sensordata", a site's "xpos"), or
    `transform` of it (e.g. a quaternion as Euler angles). Each reading returns a new
    array (Composer's buffers may keep it)."""

    def __init__(self, kind: str, element,
                 transform: Callable[[np.ndarray], np.ndarray] | None = None, **kwargs):
        self._read_kind, self._read_element, self._transform = kind, element, transform
        super().__init__(self._read_through_binding, **kwargs)

    def _read_through_binding(self, physics) -> np.ndarray:
        """The reading the slow way (for `Generic`'s own uses; the reader below is faster)."""
        value = np.array(getattr(physics.bind(self._read_element), self._read_kind))
        return value if self._transform is None else self._transform(value)

    def observation_callable(self, physics, random_state=None):
        """A reader of this physics' values (a view, when the element's values are one
        slice of MjData), wrapped in the observable's corruptor if it has one."""
        read = _reader(physics, self._read_element, self._read_kind, self._transform)
        corruptor = self.corruptor
        if corruptor is None:
            return read
        return lambda: corruptor(read(), random_state=random_state)


def _reader(physics, element, kind: str, transform) -> Callable[[], np.ndarray]:
    binding = physics.bind(element)
    values = getattr(binding, kind)
    if _in_mjdata(physics, element, kind, values):
        read = values.view(np.ndarray).copy  # A slice of MjData, read without binding.
    else:  # Scattered indices (e.g. two joints): a binding read, which is a copy.
        read = lambda: np.array(getattr(binding, kind))  # noqa: E731
    if transform is None:
        return read
    return lambda: transform(read())


def _in_mjdata(physics, element, kind: str, values: np.ndarray) -> bool:
    """Whether `values` is a view of MjData's array for `kind`: MjData names it `kind`
    (sensordata, qpos) or `<element tag>_<kind>` (site_xpos, geom_xpos)."""
    names = [kind] + ([f"{element.tag}_{kind}"] if hasattr(element, "tag") else [])
    return any(np.shares_memory(values, getattr(physics.data, name))
               for name in names if hasattr(physics.data, name))
