"""Named training recipes (`train --preset`, training/presets.py): what a preset gives a
run, how options beside it override it, and how its runs are labelled and recorded."""

from __future__ import annotations

import dataclasses
import types

import pytest

from franka_composer import cli
from franka_composer.cli import train
from franka_composer.training import hyperparameters
from franka_composer.training.presets import TRAINING_PRESETS, TrainingPreset
from franka_composer.training.run_config import RunConfig


def _config(*options):
    return train.run_config(cli.build_parser().parse_args(["train", *options]))


def test_the_fast_preset_gives_a_run_its_settings_over_table_i():
    config = _config("--preset", "fast", "--task", "pick_and_place", "--seed", "2")
    assert (config.algo, config.backend, config.precision) == ("sac", "sb3", "bf16")
    assert (config.expert_demos, config.preset, config.seed) == (1000, "fast", 2)
    assert config.terminate_on_success  # The paper's episodes: the preset leaves them.
    assert config.hyperparameters == hyperparameters("pick_and_place", "sac").replace(
        clip_q_targets=True)
    assert (config.setup, config.computation, config.variant) == ("fast preset", "",
                                                                   "fast preset")


def test_options_beside_a_preset_override_it_and_the_label_says_what_changed():
    config = _config("--preset", "fast", "--expert-demos", "100", "--batch-size", "256",
                     "--no-terminate-on-success")
    assert (config.expert_demos, config.hyperparameters.batch_size) == (100, 256)
    assert config.variant == ("fast preset, batch_size 256, 100 expert demos, "
                              "no termination on success")
    assert _config("--preset", "fast", "--precision", "fp32").variant == "fast preset, fp32"
    # Without a preset, the same settings are labelled against the paper's.
    plain = _config("--algo", "sac", "--precision", "bf16", "--expert-demos", "1000",
                    "--clip-q-targets")
    assert plain.variant == "clip_q_targets True, 1000 expert demos, bf16"
    assert dataclasses.replace(plain, preset="fast") == _config("--preset", "fast")


def test_a_presets_demonstrations_and_bounded_targets_give_way_to_the_users(tmp_path):
    """--demos stands in for the preset's recorded expert (not refused as both), and
    --no-clip-q-targets undoes its bounded targets."""
    dataset = tmp_path / "push.npz"
    config = _config("--preset", "fast", "--demos", str(dataset))
    assert (config.demos, config.expert_demos) == (str(dataset), None)
    assert config.variant == "fast preset, demos push.npz, no expert demos"
    unclipped = _config("--preset", "fast", "--no-clip-q-targets")
    assert not unclipped.hyperparameters.clip_q_targets
    assert unclipped.variant == "fast preset, clip_q_targets False"
    assert _config("--algo", "sac", "--no-clip-q-targets") == _config("--algo", "sac")


def test_a_presets_run_keeps_its_name_in_config_json():
    config = _config("--preset", "fast", "--task", "push")
    assert config.to_dict()["preset"] == "fast"
    assert RunConfig.from_dict(config.to_dict()) == config
    assert RunConfig.from_dict({**config.to_dict(), "preset": None}).preset is None
    with pytest.raises(ValueError, match="unknown preset 'slow'; valid presets: None, fast"):
        RunConfig.from_dict({**config.to_dict(), "preset": "slow"})


def test_a_preset_names_only_settings_a_run_has():
    with pytest.raises(ValueError, match="a preset cannot set colour, speed"):
        TrainingPreset(why="", settings=types.MappingProxyType({"speed": 2, "colour": 1,
                                                                "algo": "sac"}))
    assert set(TRAINING_PRESETS) == {"fast"}


def test_train_help_lists_each_presets_options(capsys):
    with pytest.raises(SystemExit):
        cli.main(["train", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert ("fast: --algo sac --backend sb3 --precision bf16 --expert-demos 1000 "
            "--clip-q-targets") in help_text
