"""`load(name)`: a task by name as a dm_env `composer.Environment`."""

from __future__ import annotations

import numpy as np
from dm_control import composer

from franka_composer import seeding
from franka_composer.environment import GoalEnvironment, check_time_limit
from franka_composer.fast_path import make_environment
from franka_composer.tasks import build_task, task_config
from franka_composer.tasks.options import OPTION_NAMES
from franka_composer.validation import check_bool, check_names, named_parameters

#: Times Composer retries an episode whose initialisation raised EpisodeInitializationError.
MAX_RESET_ATTEMPTS = 10

#: `load`'s default time limit: the task's episode length (`TaskConfig.time_limit`).
TASK_TIME_LIMIT = "task"


def load(name: str, *, reward_type: str = "sparse", seed=None, renderable: bool | None = True,
         time_limit=TASK_TIME_LIMIT, **task_kwargs) -> GoalEnvironment:
    """Builds the named task as a Composer (dm_env) environment.

    Args:
      name: one of `franka_composer.ALL_TASKS`.
      reward_type: "sparse" (0 at the goal, else -1) or "dense" (-distance).
      seed: a non-negative int (any size: `franka_composer.seeding`), a
        `np.random.RandomState`, or None; the only randomness of the episodes.
      renderable: False leaves the Panda's visual meshes out of the model (~50 MB less per
        env, for processes that never render; `physics.render` then shows no arm). The
        simulation is bit-identical either way: the visual geoms have no mass or contacts.
        None: renderable only where the camera observations draw the visual meshes.
      time_limit: seconds of physics before an episode times out, rounded up to whole
        control steps; by default the task's `max_episode_steps` control periods (2.5 s,
        50 steps, for push; 25 s under `timing="reference"`); None: no time limit.
      **task_kwargs: task options (the names of `franka_composer.tasks.OPTIONS`, and
        `timing`), e.g. `terminate_on_success=False`, `distance_threshold=0.03`.

    Raises:
      ValueError: unknown task name or option, naming the valid ones; a seed that is not a
        non-negative int; a time limit that is not a positive number or None.

    Episodes end with a LAST step: discount 0 on reaching the goal under
    `terminate_on_success`, discount 1 on a time-out (the Gymnasium adapter truncates
    there). If the physics diverges, the episode ends with a warning, not an exception,
    and discount 0 (the step gets the task's reward).

    It is a `fast_path.FastEnvironment` where the installed dm_control allows, else Composer's stock stepping (`GoalEnvironment`), with
    the same trajectories; `FRANKA_COMPOSER_FAST_PATH=0` forces the stock path.
    """
    if renderable is not None:
        check_bool("renderable", renderable)
    if seed is not None and not isinstance(seed, np.random.RandomState):
        try:
            seed = seeding.random_state(seed)
        except ValueError:  # check_seed's words, which know of ints alone.
            raise ValueError(f"seed must be a non-negative int, a np.random.RandomState or "
                             f"None, got {seed!r}") from None
    check_names("task option", task_kwargs, OPTION_NAMES, own=("load", named_parameters(load)))
    config = task_config(name, reward_type=reward_type, **task_kwargs)
    seconds = (config.time_limit if isinstance(time_limit, str) and time_limit == TASK_TIME_LIMIT
               else check_time_limit(time_limit))
    task = build_task(config, renderable=renderable)
    return make_environment(
        task,
        random_state=seed,
        time_limit=seconds,
        recompile_mjcf_every_episode=False,
        strip_singleton_obs_buffer_dim=True,
        raise_exception_on_physics_error=False,
        max_reset_attempts=MAX_RESET_ATTEMPTS,
        # A delayed observation (`randomization`) shows the reset's reading until the first
        # delayed one arrives, not zeros.
        delayed_observation_padding=composer.ObservationPadding.INITIAL_VALUE,
    )
