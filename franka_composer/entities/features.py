"""Observables that read MuJoCo's arrays through NumPy views taken once per compiled model.

`observable.MJCFFeature("xpos", site)` reads through a dm_control binding on every call
(~2 us: attribute dispatch and a dirty-state check), and `observable.Generic(lambda physics:
f(physics.bind(element).attr))` binds again on every call. Per step and per observable that
is most of an observation's cost. `ArrayFeature` takes a view of the element's slice of
MjData when Composer builds the observation callable (once per compiled model), and each
reading copies that slice, through an optional transform.

A view skips dm_control's "dirty" check, which runs `mj_forward` before reading when
positions were written since the last forward. Composer reads observables only after a
reset (whose context ends with `mj_forward`) and after a step (whose legacy stepping ends
with `mj_step1`), where the values are current either way; the equivalence is pinned in
`tests/test_bench.py` against plain Composer observables.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from dm_control.composer.observation import observable


class ArrayFeature(observable.MJCFFeature):
    """Attribute `kind` of `element` (e.g. a sensor's "sensordata", a site's "xpos"), or
    `transform` of it (e.g. a quaternion as Euler angles). Each reading returns a new
    array (Composer's buffers may keep it)."""

    def __init__(self, kind: str, element,
                 transform: Callable[[np.ndarray], np.ndarray] | None = None):
        super().__init__(kind, element)
        self._transform = transform

    def _callable(self, physics):
        binding = physics.bind(self._mjcf_element)
        kind, transform = self._kind, self._transform
        values = getattr(binding, kind)
        if _in_mjdata(physics, self._mjcf_element, kind, values):
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
