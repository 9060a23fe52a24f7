"""An observable computed from one MJCF attribute, with the binding made once per physics.

`observable.Generic(lambda physics: f(physics.bind(element).attr))` binds on every reading;
this binds when Composer builds the observation callable (once per compiled model), which
is most of the cost of a small derived observable on the step's hot path.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from dm_control.composer.observation import observable


class DerivedFeature(observable.MJCFFeature):
    """`transform(<attribute `kind` of `element`>)`, e.g. a quaternion sensor as Euler
    angles. `transform` must return a new array (Composer's buffer may keep it)."""

    def __init__(self, kind: str, element, transform: Callable[[np.ndarray], np.ndarray]):
        super().__init__(kind, element)
        self._transform = transform

    def _callable(self, physics):
        binding = physics.bind(self._mjcf_element)
        kind, transform = self._kind, self._transform
        return lambda: transform(getattr(binding, kind))
