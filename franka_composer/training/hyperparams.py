"""The paper's Table I as data: one record per (task, algorithm), nothing scattered in code.

`hyperparameters("slide", "tqc")` is the record a `franka-composer train` run starts from;
command-line overrides go through `Hyperparameters.replace`, which names the valid fields.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from franka_composer.tasks import ALL_TASKS
from franka_composer.validation import (check_bool, check_choice, check_names, check_number,
                                        spelling)

#: Learning algorithms, in the column order of the paper's Table II.
ALGOS = ("ddpg", "sac", "tqc")

#: How often gradient steps happen: "step" is the paper's (and SB3's default) setup, one
#: gradient step after every environment step; "episode" collects a whole episode first and
#: then does as many gradient steps as it collected (same updates per step, batched).
UPDATE_SCHEDULES = ("step", "episode")

#: Which implementation runs the algorithms: "sb3" is Stable-Baselines3 / sb3-contrib on
#: PyTorch (the paper's); "sbx" is sbx-rl, SB3's port to JAX (the `jax` extra), with the
#: same Table I settings and SB3's replay buffers and rollout loop.
BACKENDS = ("sb3", "sbx")

#: The arithmetic of the networks' passes (sb3): "fp32" is the paper's; "bf16" runs them
#: under torch.autocast in bfloat16, weights and optimiser state kept in fp32
#: (`training/precision.py`).
PRECISIONS = ("fp32", "bf16")

#: Where HER takes a transition's substitute goals from (SB3's `GoalSelectionStrategy`).
HER_GOAL_SELECTION_STRATEGIES = ("future", "final", "episode")

#: The hyperparameters that count something, each at least 1.
_COUNTS = ("batch_size", "buffer_size", "her_n_sampled_goal", "total_steps", "eval_every",
           "eval_episodes", "train_every", "stop_after_evaluations")
#: TQC's, None for the other algorithms.
_TQC_COUNTS = ("n_critics", "n_quantiles", "top_quantiles_to_drop_per_net")
#: The hyperparameters each algorithm is built with that are None in others' records.
ALGORITHM_SETTINGS = {"ddpg": (), "sac": ("ent_coef",), "tqc": ("ent_coef", *_TQC_COUNTS)}


def _check_ent_coef(value) -> None:
    """SB3's entropy coefficients: a number > 0, "auto", or "auto_X" (X > 0, the start)."""
    if isinstance(value, str) and value.startswith("auto"):
        start = value[len("auto_"):] if value.startswith("auto_") else ""
        try:
            if value == "auto" or float(start) > 0:
                return
        except ValueError:
            pass
    elif isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
        return
    raise ValueError(f"ent_coef must be a number > 0, 'auto' or 'auto_X' (X > 0, its "
                     f"start), got {value!r}")


@dataclasses.dataclass(frozen=True)
class Hyperparameters:
    """Everything a training run is made of (paper Table I unless noted).

    Attributes:
      net_arch: hidden layer sizes, shared by actor and critic(s).
      batch_size, buffer_size, learning_rate, tau (polyak), gamma: as in Table I.
      action_noise_std: std of Gaussian exploration noise added to actions (None: none;
        TQC explores through its entropy bonus alone).
      ent_coef: SAC/TQC entropy coefficient, "auto" = autotuned (unused by DDPG).
      n_critics, n_quantiles, top_quantiles_to_drop_per_net: TQC's distributional critics.
      her_goal_selection_strategy, her_n_sampled_goal: Hindsight Experience Replay.
      total_steps: environment steps to train for.
      eval_every: environment steps between evaluations; eval_episodes: deterministic
        episodes per evaluation.
      learning_starts: steps of random actions before learning (not in Table I, which
        leaves SB3's default, 100; the paper's curves imply 1e5: docs/guide/training.md).
      update_schedule: one of `UPDATE_SCHEDULES` (not in Table I; "step" is the paper's).
      train_every: with the "step" schedule, environment steps per gradient step (not in
        Table I; 1 is the paper's). 4 does a quarter of the updates: about 4x the steps/s
        on CPU, where gradient steps dominate, but less learning per step: a budget
        setting, not the paper's.
      stop_success_rate, stop_after_evaluations: stop before `total_steps` once
        `stop_after_evaluations` consecutive evaluations all reach `stop_success_rate` (not
        in Table I; None, the default, never stops early; the Table II campaign uses 0.95
        and 5).
      clip_q_targets: clamp the target critic's values to the returns the sparse reward
        allows, [-1/(1-gamma), 0], as OpenAI baselines' HER does (not in Table I, whose SB3
        has no such bound; `training/target_bounds.py`).
    """

    net_arch: tuple[int, ...] = (256, 256, 256)
    batch_size: int = 512
    buffer_size: int = 1_000_000
    learning_rate: float = 1e-3
    tau: float = 0.05
    gamma: float = 0.95
    action_noise_std: float | None = None
    ent_coef: str | None = None
    n_critics: int | None = None
    n_quantiles: int | None = None
    top_quantiles_to_drop_per_net: int | None = None
    her_goal_selection_strategy: str = "future"
    her_n_sampled_goal: int = 4
    total_steps: int = 500_000
    eval_every: int = 2_000
    eval_episodes: int = 15
    learning_starts: int = 100
    update_schedule: str = "step"
    train_every: int = 1
    stop_success_rate: float | None = None
    stop_after_evaluations: int = 5
    clip_q_targets: bool = False

    def __post_init__(self) -> None:
        # Every record is checked where it is made (Table I, `replace`, a run's config.json),
        # so a bad value is named here, not by SB3 or MuJoCo partway into a run.
        if isinstance(self.net_arch, (str, bytes)) or not isinstance(self.net_arch, tuple) \
                or not self.net_arch:
            raise ValueError(f"net_arch must be a non-empty tuple of layer sizes, "
                             f"got {self.net_arch!r}")
        object.__setattr__(self, "net_arch", tuple(
            check_number(f"net_arch[{i}]", size, minimum=1, integer=True)
            for i, size in enumerate(self.net_arch)))
        for name in _COUNTS:
            check_number(name, getattr(self, name), minimum=1, integer=True)
        check_number("learning_starts", self.learning_starts, minimum=0, integer=True)
        check_number("learning_rate", self.learning_rate, above=0)
        check_number("tau", self.tau, above=0, maximum=1)
        check_number("gamma", self.gamma, minimum=0)
        if self.gamma >= 1:  # The sparse returns' bound -1/(1 - gamma) must be finite.
            raise ValueError(f"gamma must be < 1, got {self.gamma!r}")
        if self.action_noise_std is not None:
            check_number("action_noise_std", self.action_noise_std, minimum=0)
        if self.ent_coef is not None:
            _check_ent_coef(self.ent_coef)
        for name in _TQC_COUNTS:
            if getattr(self, name) is not None:
                check_number(name, getattr(self, name), minimum=1, integer=True)
        if self.n_quantiles is not None and self.top_quantiles_to_drop_per_net is not None \
                and self.top_quantiles_to_drop_per_net >= self.n_quantiles:
            raise ValueError(f"top_quantiles_to_drop_per_net ({self.top_quantiles_to_drop_per_net})"
                             f" must be below n_quantiles ({self.n_quantiles})")
        check_choice("her_goal_selection_strategy value", self.her_goal_selection_strategy,
                     HER_GOAL_SELECTION_STRATEGIES)
        check_choice("update_schedule", self.update_schedule, UPDATE_SCHEDULES)
        if self.train_every != 1 and self.update_schedule != "step":
            raise ValueError(f"{spelling('train_every')} > 1 needs "
                             f"{spelling('update_schedule')} 'step'")
        if self.stop_success_rate is not None:
            check_number("stop_success_rate", self.stop_success_rate, above=0, maximum=1)
        check_bool("clip_q_targets", self.clip_q_targets)

    def replace(self, **overrides) -> "Hyperparameters":
        """A copy with `overrides` (None values are ignored); unknown names and bad values
        are a ValueError."""
        return self._with({k: v for k, v in overrides.items() if v is not None})

    def _with(self, values: dict) -> "Hyperparameters":
        """A copy with `values`, None ones included; unknown names and bad values are a
        ValueError."""
        check_names("hyperparameter", values, (f.name for f in dataclasses.fields(self)))
        if isinstance(values.get("net_arch"), list):  # As config.json holds it.
            values = {**values, "net_arch": tuple(values["net_arch"])}
        return dataclasses.replace(self, **values)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Hyperparameters":
        """A run's recorded hyperparameters; a KeyError names one every run has recorded
        but `data` lacks (a damaged or hand-edited file: defaulted, a run missing its
        total_steps read as 500,000 steps). Runs recorded before the stopping rule or
        clip_q_targets existed lack those, and had neither. A null is read as one, not as
        "not given" (`replace`'s): refused where the field takes none (total_steps)."""
        for field in dataclasses.fields(cls):
            if field.name not in data and field.name not in _ADDED_SINCE_THE_FIRST_RUNS:
                raise KeyError(f"hyperparameters.{field.name}")
        return cls()._with(data)


#: Hyperparameters that the first runs' config.json files do not record.
_ADDED_SINCE_THE_FIRST_RUNS = ("stop_success_rate", "stop_after_evaluations", "clip_q_targets")


_PER_TASK: dict[str, dict[str, Any]] = {
    "push": dict(net_arch=(256, 256, 256), batch_size=512, total_steps=500_000),
    "pick_and_place": dict(net_arch=(256, 256, 256), batch_size=512, total_steps=500_000),
    "slide": dict(net_arch=(512, 512, 512), batch_size=2048, total_steps=1_000_000),
}
# The paper has no row for panda-gym's other tasks: they take push's settings.
for _task in ALL_TASKS:
    _PER_TASK.setdefault(_task, _PER_TASK["push"])
_PER_ALGO: dict[str, dict[str, Any]] = {
    "ddpg": dict(action_noise_std=0.2),
    "sac": dict(action_noise_std=0.2, ent_coef="auto"),
    "tqc": dict(ent_coef="auto", n_critics=2, n_quantiles=25, top_quantiles_to_drop_per_net=2),
}

#: Table I, keyed by (task, algorithm) (reach, stack and flip: push's rows, not the paper's).
TABLE_I: dict[tuple[str, str], Hyperparameters] = {
    (task, algo): Hyperparameters(**_PER_TASK[task], **_PER_ALGO[algo])
    for task in ALL_TASKS for algo in ALGOS
}


def hyperparameters(task: str, algo: str) -> Hyperparameters:
    """Table I's record for `task` and `algo`."""
    check_choice("task", task, tuple(ALL_TASKS))
    check_choice("algorithm", algo, ALGOS)
    return TABLE_I[(task, algo)]
