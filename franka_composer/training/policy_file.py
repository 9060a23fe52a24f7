"""A trained run's policy alone (`RunDir.policy_file`, policy.pt): the actor's weights.

Deterministic actions come from the actor alone, so this is all `evaluate`, `rollout
--policy` and `demo --policy` need, and it is small enough to commit: 0.56 MB for Table I's
[256]^3 networks, against 2.3-2.9 MB for SB3's model.zip with its critics, target critics
and optimiser state (Table II's 23 runs: 13 MB). The actor is rebuilt from the run's
config.json (the same `policy_kwargs` the model was built with) and acts as the trained
model does, to the bit. SB3 runs only: sbx's actors are JAX functions; their runs keep
model.zip.
"""

from __future__ import annotations

import pathlib

import gymnasium as gym

from franka_composer.training.models import (algorithm_class, load_model, policy_kwargs,
                                             resolve_device)
from franka_composer.training.runs import RunConfig, RunDir

#: Bumped when the file's layout changes; a file of another version is refused by name.
FORMAT = 1


def save_policy(model, path: pathlib.Path) -> None:
    """Writes `model`'s actor and step count to `path` (an SB3 model)."""
    import torch

    actor = getattr(model, "actor", None)
    if not isinstance(actor, torch.nn.Module):
        raise ValueError(f"a policy file holds a torch actor; {type(model).__name__} has none "
                         "(sbx runs keep their model.zip)")
    torch.save({"format": FORMAT, "steps": int(model.num_timesteps),
                "actor": {name: tensor.detach().cpu()
                          for name, tensor in actor.state_dict().items()}}, path)


class ActorPolicy:
    """An SB3 policy whose actor holds saved weights; `predict` and `num_timesteps` as on the
    trained model, for code that takes either."""

    def __init__(self, policy, num_timesteps: int) -> None:
        self.policy = policy
        self.num_timesteps = num_timesteps

    def predict(self, observation, deterministic: bool = True):
        return self.policy.predict(observation, deterministic=deterministic)


def load_policy(config: RunConfig, path: pathlib.Path, env: gym.Env,
                device: str = "auto") -> ActorPolicy:
    """The actor saved at `path` by a run of `config`, on `env`'s spaces."""
    import torch

    if config.backend != "sb3":
        raise ValueError(f"{path}: policy files hold SB3 actors, and this run used "
                         f"{config.backend}")
    device = resolve_device(device)
    state = torch.load(path, map_location=device, weights_only=True)
    if state.get("format") != FORMAT:
        raise ValueError(f"{path} is a policy file of format {state.get('format')!r}; this "
                         f"version of franka_composer reads format {FORMAT}")
    policy_class = algorithm_class(config.algo).policy_aliases["MultiInputPolicy"]
    policy = policy_class(env.observation_space, env.action_space, lr_schedule=lambda _: 0.0,
                          **policy_kwargs(config.algo, config.hyperparameters))
    policy.actor.load_state_dict(state["actor"])
    policy.set_training_mode(False)
    return ActorPolicy(policy.to(device), state["steps"])


def load_trained(run: RunDir, env: gym.Env, device: str = "auto"):
    """What `run` trained, ready to act on `env`: its full model (model.zip, else its latest
    checkpoint) where it has one, else its policy file (a run as committed)."""
    config = run.read_config()
    try:
        path = run.best_model()
    except ValueError:
        if not run.policy_file.is_file():
            raise ValueError(f"{run.root} has no model yet (no model.zip, no checkpoint, "
                             "no policy.pt)") from None
        return load_policy(config, run.policy_file, env, device)
    return load_model(config.algo, path, env=env, device=device, backend=config.backend)
