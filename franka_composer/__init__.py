"""franka_composer: goal-conditioned Franka Panda manipulation as a dm_control Composer suite.

Six tasks: push, slide and pick_and_place (the paper's), reach, stack and flip (panda-gym's).
`load(name)` gives a dm_env environment; importing this package also registers the
Gymnasium ids `Franka{Push,Slide,PickAndPlace,Reach}{Sparse,Dense}-v0` and
`Franka{Stack,Flip}{Sparse,Dense}-v1`, with `Osc` (same versions) and `Joints` (one version up:
the surface guard acts under joints) after the task name for the other controllers.
"""

import warnings as _warnings

from franka_composer import headless_gl as _headless_gl

# Headless by default (EGL where there is no display): see `headless_gl`.
_headless_gl.choose_headless_backend()

# Importing dm_control.composer runs `warnings.simplefilter('always', DeprecationWarning)`
# (composer/environment.py), which would print every library's deprecation notices, every
# time, in our users' programs and logs; import it first with their filters put back after.
with _warnings.catch_warnings():
    from dm_control import composer as _composer  # noqa: E402, F401

from franka_composer import gl_fork as _gl_fork  # noqa: E402

# Forked vector-env workers render with GL state of their own: see `gl_fork`.
_gl_fork.install()

from franka_composer.adapters import ENV_IDS, FrankaGoalEnv, register_envs  # noqa: E402
from franka_composer.suite import load  # noqa: E402
from franka_composer.tasks import ALL_TASKS  # noqa: E402

__version__ = "0.5.0.dev0"

register_envs()

__all__ = ["ALL_TASKS", "ENV_IDS", "FrankaGoalEnv", "load", "__version__"]
