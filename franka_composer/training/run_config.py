"""What a training run trains, as its config.json holds it: task, algorithm, seed,
backend, controller, options and hyperparameters (`RunConfig`), and the cell it belongs
to in a report (`RunConfig.variant`)."""

from __future__ import annotations

import dataclasses
import pathlib

from franka_composer.controllers import CONTROLS, DEFAULT_CONTROL, has_weld
from franka_composer.controllers.settings import WELD_TIME_CONSTANT
from franka_composer.randomization import PRESETS
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.tasks.options import timing_name
from franka_composer.training.hyperparams import (ALGORITHM_SETTINGS, ALGOS, BACKENDS,
                                                  PRECISIONS, Hyperparameters,
                                                  hyperparameters)
from franka_composer.training.presets import TRAINING_PRESETS
from franka_composer.validation import (check_bool, check_choice, check_names, check_number,
                                        spelling)

#: Training seeds stay below 2**31: SB3 seeds NumPy's legacy generator (at most 2**32 - 1)
#: with the seed plus the evaluation offset, and with the seed plus the steps on a resume.
MAX_TRAINING_SEED = 2**31 - 1

#: The reset seed of seed 0's first expert demonstration (`RunConfig.expert_demo_seed`).
EXPERT_DEMO_SEED = 1_000_000

#: Hyperparameters that leave what is learned alone: the budget, evaluation and stopping.
NOT_LEARNING = ("total_steps", "eval_every", "eval_episodes", "stop_success_rate",
                "stop_after_evaluations")


def variant_label(setup: str, computation: str) -> str:
    """A run's variant (`RunConfig.variant`) from its setup and computation labels."""
    return ", ".join(part for part in (setup, computation) if part)


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """What a run trains: enough to rebuild its model and environments on resume.

    `demos` is the dataset the replay buffer was filled from before learning (its first
    `demo_episodes` episodes, or all), or None. `expert_demos` is, instead, how many
    episodes of the task's scripted expert the run records itself at its start
    (`expert_demo_seed`) and fills the buffer with; their recording is part of the run's
    time.

    `control_timestep` is the seconds of physics per step (None: the task's, 0.05 s), and
    `velocity_timestep` the seconds the observation's velocities are multiplied by (None:
    the control period), and `weld_time_constant` the mocap weld's (None: the task's, 0.01
    s). The paper's code runs 0.5 s per step, multiplies by 0.05 s and welds with 0.02 s
    (`tasks.options.TIMINGS["reference"]`, `train --timing reference`).

    `object_damping` damps the objects' free joints (the task option; 0: undamped, this
    suite's default; 0.01 the reference code's block, `tasks.records.REFERENCE_OBJECT_DAMPING`).

    `guard_ignores_carried` is the surface guard's setting the run trained under (the task
    option; None: the task's own, kept as that value): stack's v1 leaves a carried block out
    of the hand's rays, and a run from before it (no such field) trained under v0's guard.

    `backend` is one of `BACKENDS`: a checkpoint can only be loaded by the library that
    wrote it, so resume and evaluate read it from here. `precision` (one of `PRECISIONS`)
    is how the networks' passes are computed while training; the weights are fp32 either
    way, so evaluation and loading do not depend on it.

    `environment` names another env of the task the run trained in (the reference code's,
    through experiments/reference_env_runs.py; this suite's with one of its differences from
    the reference code undone, through experiments/altered_runs.py), or None for this
    package's: only a process that can build it (`models.ENVIRONMENTS`) resumes or plays
    the run.
    """

    task: str
    algo: str
    seed: int
    hyperparameters: Hyperparameters
    terminate_on_success: bool = True
    backend: str = "sb3"
    control: str = DEFAULT_CONTROL
    precision: str = "fp32"
    randomization: str | None = None
    demos: str | None = None
    demo_episodes: int | None = None
    expert_demos: int | None = None
    preset: str | None = None
    control_timestep: float | None = None
    velocity_timestep: float | None = None
    weld_time_constant: float | None = None
    object_damping: float = 0.0
    environment: str | None = None
    guard_ignores_carried: bool | None = None

    def __post_init__(self) -> None:
        check_choice("task", self.task, tuple(TASK_CONFIGS))
        # A hand-edited config.json's types are checked too (7.9 read as seed 7, "false"
        # as True, a number as demos failing later inside `setup`).
        object.__setattr__(self, "seed", check_number("seed", self.seed, minimum=0,
                                                      maximum=MAX_TRAINING_SEED,
                                                      integer=True))
        object.__setattr__(self, "terminate_on_success",
                           check_bool("terminate_on_success", self.terminate_on_success))
        if self.demos is not None and not isinstance(self.demos, str):
            raise ValueError(f"demos must be a dataset's path or None, got {self.demos!r}")
        if self.demo_episodes is not None:
            check_number("demo_episodes", self.demo_episodes, minimum=1, integer=True)
        # Checked as the task checks it (a whole number of physics steps), and kept as a
        # number, the task's where none is given, so that the two are one run.
        task = TASK_CONFIGS[self.task]
        timing = task.replace(
            control_timestep=task.control_timestep if self.control_timestep is None
            else self.control_timestep, velocity_timestep=self.velocity_timestep,
            weld_time_constant=task.control.weld_time_constant
            if self.weld_time_constant is None else self.weld_time_constant)
        object.__setattr__(self, "control_timestep", timing.control_timestep)
        object.__setattr__(self, "velocity_timestep", timing.velocity_timestep)
        object.__setattr__(self, "weld_time_constant", timing.control.weld_time_constant)
        damping = self.object_damping  # Checked as the task checks it (reach has no object).
        if isinstance(damping, bool) or damping != 0:  # (False == 0: the task refuses it.)
            damping = task.replace(object_damping=damping).objects[0].joint_damping
        object.__setattr__(self, "object_damping", float(damping))
        ignores = self.guard_ignores_carried  # Checked as the task checks it (reach: none).
        if ignores is None:
            ignores = task.control.guard_ignores_carried
        elif ignores is not task.control.guard_ignores_carried:
            ignores = task.replace(guard_ignores_carried=ignores).control.guard_ignores_carried
        object.__setattr__(self, "guard_ignores_carried", ignores)
        check_choice("algorithm", self.algo, ALGOS)
        unset = [name for name in ALGORITHM_SETTINGS[self.algo]
                 if getattr(self.hyperparameters, name) is None]
        if unset:  # (Else a TypeError from inside SB3 once the env is built.)
            raise ValueError(f"{self.algo} needs {', '.join(unset)}, which the "
                             "hyperparameters leave unset (None)")
        check_choice("backend", self.backend, BACKENDS)
        check_choice("control", self.control, CONTROLS)
        check_choice("precision", self.precision, PRECISIONS)
        if self.preset is not None:
            check_choice("preset", self.preset, tuple(TRAINING_PRESETS), also="None")
        if self.randomization is not None:
            check_choice("randomization", self.randomization, tuple(PRESETS), also="None")
        if self.precision != "fp32" and self.backend != "sb3":
            preset = (TRAINING_PRESETS[self.preset].settings if self.preset is not None
                      else {})
            precision, backend = spelling("precision"), spelling("backend")
            whose = (f" (the {self.preset} preset's; {precision} fp32 with it trains in "
                     "fp32)" if preset.get("precision") == self.precision else "")
            raise ValueError(f"{precision} {self.precision}{whose} runs the networks under "
                             f"torch.autocast: it needs {backend} sb3, not {self.backend} "
                             "(which trains in JAX)")
        if self.expert_demos is not None:
            check_number("expert_demos", self.expert_demos, minimum=1, integer=True)
            if self.demos is not None:
                raise ValueError(f"a run's demonstrations come from a dataset "
                                 f"({spelling('demos')}) or are recorded by its expert "
                                 f"({spelling('expert_demos')}), not both")
        if self.hyperparameters.clip_q_targets and self.backend != "sb3":
            raise ValueError(f"{spelling('clip_q_targets')} clamps a PyTorch target critic: "
                             f"it needs {spelling('backend')} sb3, not {self.backend}")
        self._check_first_update()

    def _check_first_update(self) -> None:
        """HER samples from finished episodes only, and SB3 stops a run whose first gradient
        step comes before one has ended (after its directory is made). With an update
        every step, that step follows step `learning_starts` + 1, and the first episode may
        last its whole horizon."""
        hp = self.hyperparameters
        horizon = TASK_CONFIGS[self.task].max_episode_steps
        prefilled = self.demos is not None or self.expert_demos is not None
        if hp.update_schedule == "step" and not prefilled and hp.learning_starts + 1 < horizon:
            raise ValueError(
                f"{spelling('learning_starts')} must be >= {horizon - 1} for {self.task} with "
                f"an update every step, got {hp.learning_starts}: the first gradient step "
                f"would come before the first episode ends (it may last {horizon} steps), "
                f"and HER samples from ended episodes only; or use "
                f"{spelling('update_schedule')} 'episode' or {spelling('demos')}")

    def to_dict(self) -> dict:
        return {"task": self.task, "algo": self.algo, "seed": self.seed,
                "terminate_on_success": self.terminate_on_success, "backend": self.backend,
                "control": self.control, "precision": self.precision,
                "randomization": self.randomization, "demos": self.demos,
                "demo_episodes": self.demo_episodes, "expert_demos": self.expert_demos,
                "preset": self.preset,
                "control_timestep": self.control_timestep,
                "velocity_timestep": self.velocity_timestep,
                "weld_time_constant": self.weld_time_constant,
                "object_damping": self.object_damping,
                "environment": self.environment,
                "guard_ignores_carried": self.guard_ignores_carried,
                "hyperparameters": self.hyperparameters.to_dict()}

    @property
    def _baseline(self) -> dict:
        """What its setup is measured against: the paper's (Table I for its task and
        algorithm, SB3 in fp32, terminating on success, nothing added), or its preset's."""
        baseline = dict(hyperparameters=hyperparameters(self.task, self.algo),
                        **{name: FIELD_DEFAULTS[name] for name in (
                            "backend", "precision", "terminate_on_success", "expert_demos")})
        if self.preset is None:
            return baseline
        preset = TRAINING_PRESETS[self.preset]
        return {**baseline, **preset.run_fields(),
                "hyperparameters": preset.hyperparameters(self.task, self.algo)}

    @property
    def setup(self) -> str:
        """What this run learns that its baseline does not (`_baseline`: the paper's setup,
        or its preset's, named first), as a label; "" for none."""
        baseline = self._baseline
        base = baseline["hyperparameters"].to_dict()
        parts = [f"{self.preset} preset"] if self.preset else []
        parts += [f"{name} {','.join(map(str, value)) if isinstance(value, tuple) else value}"
                  for name, value in self.hyperparameters.to_dict().items()
                  if name not in NOT_LEARNING and value != base[name]]
        parts += [label for differs, label in (
            (self.environment is not None, f"{self.environment}'s env"),
            (self.control != DEFAULT_CONTROL, f"{self.control} control"),
            (self.timing_label != "", self.timing_label),
            (self.object_damping != 0.0, f"object damping {self.object_damping:g}"),
            (self.guard_ignores_carried != self._own_guard,
             f"guard_ignores_carried={self.guard_ignores_carried}"),
            (self.randomization is not None, f"randomization {self.randomization}"),
            (self.demos is not None, f"demos {pathlib.Path(self.demos or '').name}"
             + (f"[:{self.demo_episodes}]" if self.demo_episodes else "")),
            (self.expert_demos != baseline["expert_demos"],
             f"{self.expert_demos or 'no'} expert demos"),
            (self.terminate_on_success != baseline["terminate_on_success"],
             "termination on success" if self.terminate_on_success
             else "no termination on success")) if differs]
        return ", ".join(parts)

    @property
    def timing_label(self) -> str:
        """"reference timing", "0.5 s per step" (velocities per step, the default weld),
        "0.5 s per step, velocities per 0.05 s" (the default weld), "0.05 s per step, weld
        0.02 s", or "" for the task's own timing."""
        name = timing_name(self.control, self.timing_options)
        if name is not None:
            return "" if name == "default" else f"{name} timing"
        label = f"{self.control_timestep} s per step"
        if self.velocity_timestep is not None:
            label += f", velocities per {self.velocity_timestep} s"
        if self._timing_that_acts.get("weld_time_constant",
                                      WELD_TIME_CONSTANT) != WELD_TIME_CONSTANT:
            label += f", weld {self.weld_time_constant} s"
        return label

    @property
    def _timing_that_acts(self) -> dict:
        """`timing_options` less the weld where the controller has none (osc, joints)."""
        options = self.timing_options
        if not has_weld(self.control):
            del options["weld_time_constant"]
        return options

    @property
    def timing_options(self) -> dict:
        """The task options of its timing (`tasks.options.TIMINGS` names some)."""
        return {"control_timestep": self.control_timestep,
                "velocity_timestep": self.velocity_timestep,
                "weld_time_constant": self.weld_time_constant}

    @property
    def computation(self) -> str:
        """How its networks were computed, where not as its baseline's (the paper's SB3 in
        fp32, or its preset's): "bf16", "sbx" or ""."""
        baseline = self._baseline
        return ", ".join(label for differs, label in (
            (self.precision != baseline["precision"], self.precision),
            (self.backend != baseline["backend"], self.backend)) if differs)

    @property
    def variant(self) -> str:
        """Its setup and computation: runs with different variants are not seeds of one
        cell (`evaluate`, `plot` and `report` keep them apart)."""
        return variant_label(self.setup, self.computation)

    def differing(self, other: "RunConfig") -> dict[str, tuple]:
        """What makes `other` a different run from this one: {setting: (ours, theirs)};
        the step budget is not among them (a run may go on to a larger one), nor the weld
        unless both controllers have one (where one has none, `control` differs)."""
        weld_counts = all("weld_time_constant" in config._timing_that_acts
                          for config in (self, other))

        def settings(config: RunConfig) -> dict:
            flat = {**config.to_dict(), **config.hyperparameters.to_dict()}
            del flat["hyperparameters"], flat["total_steps"]
            if not weld_counts:
                del flat["weld_time_constant"]
            return flat
        ours, theirs = settings(self), settings(other)
        return {name: (ours[name], theirs[name]) for name in ours if ours[name] != theirs[name]}

    def differences(self, other: "RunConfig") -> list[str]:
        """`differing` as "name: ours, not theirs"."""
        return [f"{name}: {ours}, not {theirs}"
                for name, (ours, theirs) in self.differing(other).items()]

    @property
    def expert_demo_seed(self) -> int:
        """The reset seed of the first expert demonstration (episode i: this + i), so that
        runs of other seeds record other episodes (up to 100,000 each)."""
        return EXPERT_DEMO_SEED + 100_000 * self.seed

    @property
    def _own_guard(self) -> bool:
        """The task's own `guard_ignores_carried` in this version."""
        return TASK_CONFIGS[self.task].control.guard_ignores_carried

    @property
    def dynamics_options(self) -> dict:
        """The task options its dynamics were set with: its timing's, the objects' damping
        where they are damped, and the guard's setting where it is not the task's own (a
        stack run from before v1)."""
        damping = {"object_damping": self.object_damping} if self.object_damping else {}
        guard = ({"guard_ignores_carried": self.guard_ignores_carried}
                 if self.guard_ignores_carried != self._own_guard else {})
        return {**self.timing_options, **damping, **guard}

    @property
    def env_options(self) -> dict:
        """The options its environments are made with (`models.make_env`)."""
        return dict(terminate_on_success=self.terminate_on_success, control=self.control,
                    randomization=self.randomization, environment=self.environment,
                    **self.dynamics_options)

    @classmethod
    def from_dict(cls, data: dict) -> "RunConfig":
        # A key a run has not recorded reads as its field's default (`FIELD_DEFAULTS`), save
        # one (`_BEFORE_THE_FIELD`). Runs written before the JAX backend, the controllers,
        # bf16 or randomisation existed have no "backend", "control", "precision" or
        # "randomization": they are SB3's, the default controller's, fp32, not randomised;
        # those before the control timestep option, the task's; those before the velocity
        # timestep, velocities per control period; those before the weld's time constant, the
        # default weld (the reference timing's runs included); those before other suites'
        # envs, this package's; those before object damping, undamped objects; those before
        # the guard could leave carried blocks out, v0's guard, which counted them as
        # surfaces. A name no run has recorded (a misspelt "contrl" would else read as the
        # default controller) is refused.
        names = [field.name for field in dataclasses.fields(cls)]
        check_names("key", data, names)
        settings = {name: data[name] if name in _ALWAYS_RECORDED
                    else data.get(name, _BEFORE_THE_FIELD.get(name, FIELD_DEFAULTS[name]))
                    for name in names if name != "hyperparameters"}
        return cls(**settings,
                   hyperparameters=Hyperparameters.from_dict(data["hyperparameters"]))


#: Each `RunConfig` field's default, by name (the fields without one left out): what a
#: setting not given is, and what a config.json from before the field reads as.
FIELD_DEFAULTS = {field.name: field.default for field in dataclasses.fields(RunConfig)
                  if field.default is not dataclasses.MISSING}
#: The fields every config.json has held (`RunConfig.from_dict` reads them without a default).
_ALWAYS_RECORDED = ("task", "algo", "seed", "terminate_on_success")
#: What a config.json from before a field read as, where that is not the field's default
#: (`RunConfig.from_dict`): the guard counted carried blocks as surfaces (v0's) before it
#: could leave them out.
_BEFORE_THE_FIELD = {"guard_ignores_carried": False}
