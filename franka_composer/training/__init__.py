"""Reproducing the paper's benchmark: DDPG, SAC and TQC with HER on the sparse tasks.

Needs the `train` extra (Stable-Baselines3, sb3-contrib, matplotlib); the `jax` extra
(sbx-rl) adds the JAX backend. Table I lives in
`hyperparams.TABLE_I`; `loop.train` runs (and resumes) one run directory.
"""

from franka_composer.training.hyperparams import (ALGOS, BACKENDS, PRECISIONS, TABLE_I,
                                                  UPDATE_SCHEDULES, Hyperparameters,
                                                  hyperparameters)

__all__ = ["ALGOS", "BACKENDS", "PRECISIONS", "TABLE_I", "UPDATE_SCHEDULES", "Hyperparameters",
           "hyperparameters"]
