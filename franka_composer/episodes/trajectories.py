"""Episodes of one policy in one env, as `rollout` records them and the `.npz` file keeps
them."""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from franka_composer.episodes import npz_file
from franka_composer.episodes.record import check_not_diverged


@dataclasses.dataclass
class Trajectories:
    """Episodes of one policy in one environment, each a dict of arrays.

    Each episode of T steps has the env's observation keys (`record.OBSERVATION_KEYS`,
    images in the pixel modes) with T + 1 rows (the reset observation first), and `action`,
    `reward`, `is_success` (the step's `info["is_success"]`), `terminated`, `truncated` with
    T rows. `env_seconds` is the wall time spent inside `env.reset` and `env.step` only;
    `metadata`, what a loaded file says they were recorded with ({} if it says nothing);
    `diverged`, the indices of the episodes that ended where the physics diverged, which
    `save` refuses (`record.check_not_diverged`).
    """

    episodes: list[dict[str, np.ndarray]]
    env_seconds: float = 0.0
    metadata: dict = dataclasses.field(default_factory=dict)
    diverged: list[int] = dataclasses.field(default_factory=list)

    def __len__(self) -> int:
        return len(self.episodes)

    @property
    def lengths(self) -> np.ndarray:
        """Steps per episode."""
        return np.array([len(e["action"]) for e in self.episodes], dtype=np.int64)

    @property
    def successes(self) -> np.ndarray:
        """Whether each episode ended in success (`is_success` of its last step)."""
        return np.array([bool(e["is_success"][-1]) if len(e["is_success"]) else False
                         for e in self.episodes])

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes)) if self.episodes else 0.0

    def save(self, path: str | os.PathLike, metadata: dict | None = None) -> None:
        """Writes every episode to a `.npz` file, with `metadata` (what they were recorded
        with; `franka_composer.episodes.npz_file`), by default their own (`rollout`'s:
        the env's task, controller, reward and options)."""
        check_not_diverged(self.diverged)
        npz_file.write(self.episodes, path, self.metadata if metadata is None else metadata)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Trajectories":
        """Reads what `save` wrote, checked whole: a damaged file is a ValueError naming it."""
        episodes, metadata = npz_file.read(path)
        return cls(episodes, metadata=metadata)
