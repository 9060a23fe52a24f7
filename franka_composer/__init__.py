"""franka_composer: goal-conditioned Franka Panda manipulation as a dm_control Composer suite.

`load(name)` gives a dm_env environment; importing this package also registers the
Gymnasium ids `Franka{Push,Slide,PickAndPlace}{Sparse,Dense}-v0`.
"""

import os as _os

# Headless by default: without a display, dm_control would try GLFW (and warn) on import.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"

from franka_composer.adapters import ENV_IDS, FrankaGoalEnv, register_envs  # noqa: E402
from franka_composer.suite import load  # noqa: E402
from franka_composer.tasks import ALL_TASKS  # noqa: E402

__version__ = "0.1.0"

register_envs()

__all__ = ["ALL_TASKS", "ENV_IDS", "FrankaGoalEnv", "load", "__version__"]
