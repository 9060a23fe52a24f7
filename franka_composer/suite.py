"""`load(name)`: a task by name as a dm_env `composer.Environment`."""

from __future__ import annotations

import numpy as np
from dm_control import composer

from franka_composer import seeding
from franka_composer.environment import GoalEnvironment
from franka_composer.fast_path import make_environment
from franka_composer.tasks import build_task, task_config

#: Times Composer retries an episode whose initialisation raised EpisodeInitializationError.
MAX_RESET_ATTEMPTS = 10


def load(name: str, *, reward_type: str = "sparse", seed=None, renderable: bool | None = True,
         **task_kwargs) -> GoalEnvironment:
    """Builds the named task as a Composer (dm_env) environment.

    Args:
      name: one of `franka_composer.ALL_TASKS`.
      reward_type: "sparse" (0 at the goal, else -1) or "dense" (-distance).
      seed: a non-negative int (any size: `franka_composer.seeding`), a
        `np.random.RandomState`, or None; the only randomness of the episodes.
      renderable: False leaves the Panda's visual meshes out of the model (~40 MB less per
        env, for processes that never render; `physics.render` then shows no arm). The
        simulation is bit-identical either way: the visual geoms have no mass or contacts.
        None: renderable only where the camera observations draw the visual meshes.
      **task_kwargs: overrides of the task's `TaskConfig` fields, e.g.
        `terminate_on_success=False`, `distance_threshold=0.03`.

    Raises:
      ValueError: unknown task name or option, naming the valid ones; a seed that is not a
        non-negative int.

    The environment has no time limit of its own (the Gymnasium adapter truncates at 50
    steps) and ends an episode with a warning, not an exception, if the physics diverges
    (the step gets the task's reward). It is a `fast_path.FastEnvironment` where the
    installed dm_control allows, else Composer's stock stepping (`GoalEnvironment`), with
    the same trajectories; `FRANKA_COMPOSER_FAST_PATH=0` forces the stock path.
    """
    if seed is not None and not isinstance(seed, np.random.RandomState):
        seed = seeding.random_state(seed)
    task = build_task(task_config(name, reward_type=reward_type, **task_kwargs),
                      renderable=renderable)
    return make_environment(
        task,
        random_state=seed,
        time_limit=float("inf"),
        recompile_mjcf_every_episode=False,
        strip_singleton_obs_buffer_dim=True,
        raise_exception_on_physics_error=False,
        max_reset_attempts=MAX_RESET_ATTEMPTS,
        # A delayed observation (`randomization`) shows the reset's reading until the first
        # delayed one arrives, not zeros.
        delayed_observation_padding=composer.ObservationPadding.INITIAL_VALUE,
    )
