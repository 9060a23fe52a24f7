"""Camera observations that start GL only when an episode is observed."""

from __future__ import annotations

from typing import Callable

import numpy as np
from dm_control.composer.observation import observable


class EpisodeCamera(observable.MJCFCamera):
    """Composer's camera observable, blank until the first episode starts.

    Composer reads every observable once as it builds the environment (to size its
    buffers); a render there would start GL in processes that never observe an episode,
    such as the parent of forked vector-env workers (Gymnasium builds an env there for its
    spaces), whose children then inherit a started GL driver (`franka_composer.gl_fork`).
    """

    def __init__(self, element, *, episode_started: Callable[[], bool], **kwargs) -> None:
        super().__init__(element, **kwargs)
        self._episode_started = episode_started

    def _callable(self, physics):
        render = super()._callable(physics)
        spec = self.array_spec

        def get_observation():
            if self._episode_started():
                return render()
            return np.zeros(spec.shape, spec.dtype)

        return get_observation
