"""What an episode is wherever episodes are kept (a rollout's `Trajectories`, the npz, Minari
and RLDS datasets, demonstrations): its keys, and the check every reader makes of the
episodes it gives back, so that a damaged or foreign file is refused by name, saying what is
wrong, before anything trains.

An episode of T steps holds the observation's keys (at least the two goals; the state
vector and camera images as its observation mode has them) with T + 1 rows (the reset's
first) and one row per step of `action`, `reward`, `is_success`, `terminated`,
`truncated`; it ends on its last step (terminated or truncated there, at no step before).
"""

from __future__ import annotations

import numpy as np

#: Keys of the Gymnasium goal observation dict in the state modes (the pixel modes add
#: "<camera>_pixels" images, and "pixels" alone has no "observation").
OBSERVATION_KEYS = ("observation", "achieved_goal", "desired_goal")
#: What every observation mode observes.
GOAL_KEYS = ("achieved_goal", "desired_goal")
#: Per-step arrays (one entry per action taken).
STEP_KEYS = ("action", "reward", "is_success", "terminated", "truncated")
#: The per-step arrays that are true or false.
FLAG_KEYS = ("is_success", "terminated", "truncated")


def check_not_diverged(diverged) -> None:
    """A ValueError naming the episodes (their indices, `diverged`) that ended where the
    physics diverged (`info["diverged"]`): MuJoCo reset the simulation there, so each one's
    last transition leads to a state it never reached, which a dataset would hand a learner
    as a real one (and as a truncation its time limit does not explain)."""
    if len(diverged):
        which = ", ".join(str(index) for index in diverged)
        raise ValueError(f"episode{'s' if len(diverged) > 1 else ''} {which} ended where the "
                         "physics diverged (MuJoCo found the simulation unstable and reset "
                         "it): a dataset keeps no transition into such a reset; record with "
                         "options that keep the simulation stable (a smaller max_tcp_step or "
                         "action_noise, the task's own object sizes and physics)")


def check_episodes(path, episodes: list[dict]) -> None:
    """A ValueError naming `path` unless `episodes` is at least one episode, each whole."""
    if not episodes:
        raise ValueError(f"{path} holds no episodes (an empty or damaged dataset?)")
    for index, episode in enumerate(episodes):
        missing = [key for key in GOAL_KEYS + STEP_KEYS if key not in episode]
        if missing:
            raise ValueError(f"{path}: episode {index} has no {', '.join(missing)}")
        steps = len(episode["action"])
        if steps == 0:
            raise ValueError(f"{path}: episode {index} has no steps")
        for key in (key for key in episode if key not in STEP_KEYS):
            if len(episode[key]) != steps + 1:
                raise ValueError(f"{path}: episode {index} has {len(episode[key])} rows of "
                                 f"{key} for {steps} actions, not {steps + 1} (the reset's "
                                 "first)")
        for key in STEP_KEYS[1:]:
            if len(episode[key]) != steps:
                raise ValueError(f"{path}: episode {index} has {len(episode[key])} rows of "
                                 f"{key} for {steps} actions")
        _check_values(path, index, episode)
        ends = np.flatnonzero(np.asarray(episode["terminated"], dtype=bool)
                              | np.asarray(episode["truncated"], dtype=bool))
        if ends.tolist() != [steps - 1]:
            raise ValueError(f"{path}: episode {index} ({steps} steps) ends at step(s) "
                             f"{ends.tolist()} by its terminated and truncated flags, not at "
                             f"its last, {steps - 1}: its episode boundaries do not match "
                             "its arrays")


def _check_values(path, index: int, episode: dict) -> None:
    """Every number in the episode a real one, finite as the float32 a buffer keeps it in,
    and every flag true or false, one per step: a NaN observation or reward would reach a
    critic's targets, a NaN flag would count as true (`bool(nan)`), and strings, complex
    numbers or a column of rewards were taken (or failed deep inside training)."""
    for key, values in episode.items():
        values = np.asarray(values)
        if key in STEP_KEYS[1:] and values.ndim != 1:
            raise ValueError(f"{path}: episode {index} has {key} of shape {values.shape}, not "
                             "one value per step")
        if key not in FLAG_KEYS and values.dtype.kind not in "fiu":
            raise ValueError(f"{path}: episode {index} has {key} of type {values.dtype}, not "
                             "real numbers")
        if values.dtype.kind == "f" and values.dtype.itemsize > 4:
            with np.errstate(over="ignore"):  # Past float32's range: inf, refused below.
                values = values.astype(np.float32)
        if key in FLAG_KEYS:
            if values.dtype != bool and not np.isin(values, (0, 1)).all():
                step = int(np.flatnonzero(~np.isin(values, (0, 1)))[0])
                value = values[step]
                raise ValueError(f"{path}: episode {index} has {key} values other than true "
                                 f"and false ({getattr(value, 'item', lambda: value)()!r} at "
                                 f"step {step})")
        elif values.dtype.kind == "f" and not np.isfinite(values).all():
            row = int(np.flatnonzero(~np.isfinite(values.reshape(len(values), -1)).all(
                axis=1))[0])
            raise ValueError(f"{path}: episode {index} has a non-finite {key} in row {row} "
                             f"({values[row].tolist() if values.ndim < 3 else 'an image'})")
