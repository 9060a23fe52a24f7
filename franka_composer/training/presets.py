"""Named training recipes (`train --preset NAME`): each is the settings it gives a run, in
one record here and nowhere else. Options given beside a preset override its settings; the
run's config.json names the preset and holds every setting as resolved, and its variant
label says "NAME preset" plus whatever was changed from it.

Table I's settings stay the default; the Table II cells are trained without a preset.
"""

from __future__ import annotations

import dataclasses
import types

from franka_composer.training.hyperparams import Hyperparameters, hyperparameters

#: The `RunConfig` fields a preset may set, beside hyperparameters.
RUN_FIELDS = ("algo", "backend", "precision", "terminate_on_success", "expert_demos")
_HYPERPARAMETERS = frozenset(field.name for field in dataclasses.fields(Hyperparameters))


@dataclasses.dataclass(frozen=True)
class TrainingPreset:
    """A recipe: `settings` maps `RUN_FIELDS` and `Hyperparameters` field names to values
    (each also a `train` option of the same name); `why` says what it is for."""

    why: str
    settings: types.MappingProxyType

    def __post_init__(self) -> None:
        unknown = sorted(set(self.settings) - _HYPERPARAMETERS - set(RUN_FIELDS))
        if unknown:
            raise ValueError(f"a preset cannot set {', '.join(unknown)}")

    def hyperparameters(self, task: str, algo: str) -> Hyperparameters:
        """Table I's record for `task` and `algo` with this preset's hyperparameters."""
        return hyperparameters(task, algo).replace(**{
            name: value for name, value in self.settings.items() if name in _HYPERPARAMETERS})

    def run_fields(self) -> dict:
        """Its settings that are `RunConfig` fields rather than hyperparameters."""
        return {name: value for name, value in self.settings.items() if name in RUN_FIELDS}

    def describe(self) -> str:
        """Its settings as the `train` options that give them, for --help and the docs."""
        parts = []
        for name, value in self.settings.items():
            option = "--" + name.replace("_", "-")
            if isinstance(value, bool):  # The flags: --clip-q-targets, --no-terminate-...
                parts.append(option if value else f"--no-{option[2:]}")
            else:
                text = ",".join(map(str, value)) if isinstance(value, tuple) else value
                parts.append(f"{option} {text}")
        return " ".join(parts)


TRAINING_PRESETS: dict[str, TrainingPreset] = {
    # What each setting bought, and what was tried and left out:
    # docs/experiments/fast-preset.md.
    "fast": TrainingPreset(
        why="SAC in bf16, bounded targets and 1000 expert episodes recorded by the run: "
            "fewer steps and minutes to success than Table I's recipe",
        settings=types.MappingProxyType(dict(
            algo="sac", backend="sb3", precision="bf16", expert_demos=1000,
            clip_q_targets=True))),
}
