"""Demonstration datasets in the ecosystem's formats: `record(task, ...)` (and `franka-composer
rollout`) writes the scripted expert's or a trained policy's episodes as

- "npz": this package's own file (`policies.Trajectories`),
- "minari": a Minari dataset (Gymnasium; `minari.load_dataset`, `recover_environment`),
- "rlds": RLDS through envlogger around the Composer environment (`envlogger.Reader`).

Minari and envlogger are the `[data]` extra.
"""

from __future__ import annotations

import pathlib

import gymnasium as gym

from franka_composer.adapters.registration import env_id
from franka_composer.datasets.sources import make_policy, source_name
from franka_composer.policies import rollout
from franka_composer.validation import check_choice, check_number

#: The formats `record` writes.
FORMATS = ("npz", "minari", "rlds")


def default_dataset_id(task: str, control: str, source: str) -> str:
    """Minari's id for a dataset: "franka_composer/push/expert-v0",
    "franka_composer/push-osc/policy-noisy-v0"."""
    name = task if control == "mocap" else f"{task}-{control}"
    return f"franka_composer/{name}/{source}-v0"


def record(task: str, episodes: int, out, *, format: str = "npz", seed: int = 0,
           control: str = "mocap", reward_type: str = "sparse", policy_dir=None,
           action_noise: float = 0.0, dataset_id: str | None = None, **options) -> dict:
    """Records `episodes` episodes of `task` (episode i reset with `seed` + i) by its scripted
    expert, or by the policy trained in `policy_dir`, with N(0, `action_noise`) added to each
    action, in `format` under `out` (a file for npz, a folder otherwise). `options` are task
    options (`gym.make(id, **options)`). Returns {"episodes", "steps", "success_rate",
    "path"}; every argument is checked before anything is written."""
    check_choice("format", format, FORMATS)
    check_number("episodes", episodes, minimum=1, integer=True)
    check_number("seed", seed, minimum=0, integer=True)
    out = pathlib.Path(out)
    if format == "npz" and out.suffix != ".npz":  # numpy would write to out + ".npz".
        raise ValueError(f"an npz dataset's path must end in .npz, got {str(out)!r}")
    env = gym.make(env_id(task, reward_type, control), **options)
    try:
        policy = make_policy(env, policy_dir=policy_dir, action_noise=action_noise, seed=seed)
        source = source_name(policy_dir, action_noise)
        if format == "npz":
            trajectories = rollout(env, policy, episodes, seed=seed)
            out.parent.mkdir(parents=True, exist_ok=True)
            trajectories.save(out)
            return {"episodes": len(trajectories), "steps": int(trajectories.lengths.sum()),
                    "success_rate": trajectories.success_rate, "path": str(out)}
        if format == "minari":
            from franka_composer.datasets import minari_format

            dataset_id = dataset_id or default_dataset_id(task, control, source)
            summary = minari_format.write(env, policy, episodes, seed, out, dataset_id,
                                          f"franka_composer {task} ({control}), {source}")
            return dict(summary, path=str(out), dataset_id=dataset_id)
        from franka_composer.datasets import rlds_format

        metadata = {"task": task, "control": control, "reward_type": reward_type,
                    "source": source, "seed": seed, "action_noise": float(action_noise),
                    "options": {name: value if isinstance(value, (bool, int, float, str))
                                else repr(value) for name, value in options.items()}}
        summary = rlds_format.write(env, policy, episodes, seed, out, metadata)
        return dict(summary, path=str(out))
    finally:
        env.close()


__all__ = ["FORMATS", "default_dataset_id", "record"]
