"""Domain randomisation as data (the `randomization` task option): physics, visual, sensing
and action parameters, each a `composer.variation` distribution, drawn per episode without
recompiling, and reported (`GoalTask.randomization`, `info["randomization"]`)."""

from franka_composer.randomization.parameters import GROUPS, PARAMETERS, Parameter
from franka_composer.randomization.randomizer import Randomizer
from franka_composer.randomization.settings import (PRESET_REASONS, PRESETS,
                                                     RandomizationSettings,
                                                     randomization_settings)

__all__ = ["GROUPS", "PARAMETERS", "PRESETS", "PRESET_REASONS", "Parameter",
           "RandomizationSettings", "Randomizer", "randomization_settings"]
