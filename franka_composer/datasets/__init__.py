"""Demonstration datasets in the ecosystem's formats: `record(task, ...)` (and `franka-composer
rollout`) writes the scripted expert's or a trained policy's episodes as

- "npz": this package's own file (`policies.Trajectories`),
- "minari": a Minari dataset (Gymnasium; `minari.load_dataset`, `recover_environment`),
- "rlds": RLDS through envlogger around the Composer environment (`envlogger.Reader`).

Minari and envlogger are the `[data]` extra.
"""

from __future__ import annotations

import json
import pathlib

import gymnasium as gym

from franka_composer.adapters.registration import env_id
from franka_composer.atomic_files import folders_made_for
from franka_composer.controllers import DEFAULT_CONTROL
from franka_composer.datasets.sources import make_policy, source_name
from franka_composer.episodes import npz_file
from franka_composer.policies import rollout
from franka_composer.policies.rollout import check_episodes_end, recorded_with
from franka_composer.tasks.options import expand_timing, plain_value, readable_options
from franka_composer.validation import check_choice, check_number, check_path, check_writable

#: The formats `record` writes.
FORMATS = ("npz", "minari", "rlds")


def default_dataset_id(task: str, control: str, source: str) -> str:
    """Minari's id for a dataset: "franka_composer/push/expert-v0",
    "franka_composer/push-osc/policy-noisy-v0"."""
    name = task if control == DEFAULT_CONTROL else f"{task}-{control}"
    return f"franka_composer/{name}/{source}-v0"


def record(task: str, episodes: int, out, *, format: str = "npz", seed: int = 0,
           control: str = DEFAULT_CONTROL, reward_type: str = "sparse", policy_dir=None,
           action_noise: float = 0.0, dataset_id: str | None = None, **options) -> dict:
    """Records `episodes` episodes of `task` (episode i reset with `seed` + i) by its scripted
    expert, or by the policy trained in `policy_dir`, with N(0, `action_noise`) added to each
    action, in `format` under `out` (a file for npz, a folder otherwise). `options` are task
    options (`gym.make(id, **options)`). Returns {"episodes", "steps", "success_rate",
    "path"} (and "dataset_id" for minari); every argument is checked before anything is
    written."""
    check_choice("format", format, FORMATS)
    registered = env_id(task, reward_type, control)  # Checks the three by name.
    check_number("episodes", episodes, minimum=1, integer=True)
    check_number("seed", seed, minimum=0, integer=True)
    action_noise = check_number("action_noise", action_noise, minimum=0.0)
    out = check_path("out", out)
    source = source_name(policy_dir, action_noise)
    if format == "minari":
        _check_minari_seeds(seed, episodes)
        dataset_id = _check_dataset_id(dataset_id or default_dataset_id(task, control, source))
    elif dataset_id is not None:
        raise ValueError("--dataset-id names a Minari dataset: give it with --format minari")
    _check_destination(out, format, dataset_id)
    # A named timing is kept as the values it sets: what the name stands for may change;
    # numpy's scalars as the numbers they hold, for the metadata and Minari's JSON.
    options = {name: plain_value(value) for name, value in expand_timing(options).items()}
    if format == "minari":
        _check_json_options(options)
    env = gym.make(registered, **options)
    # What the episodes were recorded with, as a rollout's trajectories say it, and by whom.
    metadata = dict(recorded_with(env), source=source, seed=seed,
                    action_noise=float(action_noise))
    try:
        check_episodes_end(env)  # Before anything is written.
        policy = make_policy(env, policy_dir=policy_dir, action_noise=action_noise, seed=seed)
        if format == "npz":
            trajectories = rollout(env, policy, episodes, seed=seed)
            with folders_made_for(out):
                trajectories.save(out, metadata)
            return {"episodes": len(trajectories), "steps": int(trajectories.lengths.sum()),
                    "success_rate": trajectories.success_rate, "path": str(out)}
        if format == "minari":
            from franka_composer.datasets import minari_format

            assert dataset_id is not None
            summary = minari_format.write(env, policy, episodes, seed, out, dataset_id,
                                          f"franka_composer {task} ({control}), {source}")
            return dict(summary, path=str(out), dataset_id=dataset_id)
        from franka_composer.datasets import rlds_format

        summary = rlds_format.write(env, policy, episodes, seed, out, metadata)
        return dict(summary, path=str(out))
    finally:
        env.close()


def _check_dataset_id(dataset_id) -> str:
    """Minari's form for an id, versioned, checked before the episodes are recorded (Minari
    checks it when it makes the dataset, after them)."""
    from minari.dataset.minari_dataset import parse_dataset_id

    try:
        parse_dataset_id(dataset_id)  # A TypeError for an id without a version.
    except (ValueError, TypeError):
        raise ValueError(f"--dataset-id {dataset_id!r} is not a Minari dataset id: "
                         "[namespace/]name-v<version>, e.g. franka_composer/push/expert-v0"
                         ) from None
    return dataset_id


def _check_minari_seeds(seed: int, episodes: int) -> None:
    """Minari keeps each episode's seed as a uint64 (HDF5 has no larger integer): seeds
    past it are refused before the first episode is recorded, not at the one that
    reaches them."""
    last = seed + episodes - 1
    if last >= 2**64:
        raise ValueError(f"a Minari dataset keeps each episode's seed as a uint64 (below "
                         f"2**64), and episode {episodes - 1}'s would be {last}: give a "
                         "smaller --seed, or record as npz or rlds, which keep any")


def _check_json_options(options: dict) -> None:
    """Minari keeps the env's options as JSON, for `recover_environment` to make the env
    again: an option JSON cannot hold (a custom randomisation's distributions) is refused
    before anything is recorded, not after every episode was."""
    for name, value in options.items():
        try:
            json.dumps(value)
        except (TypeError, ValueError):
            raise ValueError(
                f"a Minari dataset keeps its env's options as JSON (recover_environment "
                f"makes the env from them), and {name}={value!r} is not JSON: use a preset "
                f"name, or record as npz or rlds, which keep it as text") from None


def _check_destination(out: pathlib.Path, format: str, dataset_id: str | None) -> None:
    """Where `record` writes must take a new dataset whole, found out before the episodes
    are recorded: an npz file (`npz_file.check_destination`); Minari and RLDS
    datasets are folders (not named .npz), and one already there is not added to (envlogger
    would append the new episodes to an RLDS dataset's, Minari refuses at the end); either
    can be written there (`check_writable`)."""
    if format == "npz":
        npz_file.check_destination(out)
        return
    if out.is_file():
        raise ValueError(f"a {format} dataset is a folder, and {out} is a file")
    if out.suffix == ".npz":
        raise ValueError(f"a {format} dataset is a folder, and {str(out)!r} is named as an "
                         "npz file: give a folder's name, or --format npz")
    if format == "rlds" and out.is_dir() and any(out.iterdir()):
        raise ValueError(f"{out} is not empty: an RLDS dataset takes a folder of its own "
                         "(envlogger would add these episodes to the ones there)")
    if format == "minari" and dataset_id is not None and (out / dataset_id).exists():
        raise ValueError(f"{out} already holds the Minari dataset {dataset_id}: choose "
                         "another --out or --dataset-id")
    check_writable(out, folder=True)


__all__ = ["FORMATS", "default_dataset_id", "readable_options", "record"]
