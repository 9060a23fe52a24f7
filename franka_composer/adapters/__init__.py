"""Other worlds' interfaces to the suite: Gymnasium's GoalEnv and its registry."""

from franka_composer.adapters.goal_env import FrankaGoalEnv
from franka_composer.adapters.registration import ENV_IDS, env_id, register_envs

__all__ = ["ENV_IDS", "FrankaGoalEnv", "env_id", "register_envs"]
