"""A trained run's policy alone (`RunDir.policy_file`, policy.pt): the actor's weights.

Deterministic actions come from the actor alone, so this is all `evaluate`, `rollout
--policy` and `demo --policy` need, and it is small enough to commit: 0.56 MB for Table I's
[256]^3 networks, against 2.3-2.9 MB for SB3's model.zip with its critics, target critics
and optimiser state (Table II's 23 runs: 13 MB). The actor is rebuilt from the run's
config.json (the same `policy_kwargs` the model was built with) and acts as the trained
model does, to the bit. An sbx run's actor is a flax network: its parameters are stored the
same way, by their flax path ("params/Dense_0/kernel"), and put back into a freshly built
sbx model (its model.zip is 17.3 MB for Table I's TQC, with its optimiser states).
"""

from __future__ import annotations

import contextlib
import pathlib
import warnings

import gymnasium as gym
import numpy as np

from franka_composer.signals import jax_imported
from franka_composer.training.models import (algorithm_class, build_model, check_saved_by,
                                             load_model, make_env, policy_kwargs,
                                             resolve_device)
from franka_composer.training.run_config import RunConfig
from franka_composer.training.run_files import model_damage
from franka_composer.training.runs import RunDir

#: Bumped when the file's layout changes; a file of another version is refused by name.
FORMAT = 1


def _actor_weights(model) -> tuple[str, dict]:
    """(backend, the actor's weights as CPU tensors by name) of an SB3 or sbx model."""
    import torch

    actor = getattr(model, "actor", None)
    if isinstance(actor, torch.nn.Module):
        return "sb3", {name: tensor.detach().cpu() for name, tensor in actor.state_dict().items()}
    actor_state = getattr(getattr(model, "policy", None), "actor_state", None)
    if actor_state is None:
        raise ValueError(f"a policy file holds an SB3 or sbx actor; {type(model).__name__} "
                         "has neither")
    from flax.traverse_util import flatten_dict

    return "sbx", {name: torch.from_numpy(np.array(leaf)) for name, leaf in
                   flatten_dict(dict(actor_state.params), sep="/").items()}


def save_policy(model, path: pathlib.Path) -> None:
    """Writes `model`'s actor and step count to `path` (an SB3 or sbx model), with their
    digest (`_digest`)."""
    import torch

    backend, weights = _actor_weights(model)
    steps = int(model.num_timesteps)
    torch.save({"format": FORMAT, "backend": backend, "steps": steps, "actor": weights,
                "sha256": _digest(backend, steps, weights)}, path)


def _digest(backend: str, steps: int, actor: dict) -> str:
    """A SHA-256 of a policy file's backend, steps and each actor parameter's name, dtype,
    shape and bytes, in name order. torch's zip reader checks no checksum: a changed byte
    in a weight, or in the pickle that says where each weight lies, read as another actor
    (a weight 1.6e37 off played without a word)."""
    import hashlib

    import torch

    digest = hashlib.sha256(f"{backend} {steps}\n".encode())
    for name in sorted(actor):
        tensor = actor[name].detach().cpu().contiguous()
        digest.update(f"{name} {tensor.dtype} {tuple(tensor.shape)}\n".encode())
        digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


class ActorPolicy:
    """An SB3 or sbx policy whose actor holds saved weights; `predict` and `num_timesteps`
    as on the trained model, for code that takes either."""

    def __init__(self, policy, num_timesteps: int) -> None:
        self.policy = policy
        self.num_timesteps = num_timesteps

    def predict(self, observation, deterministic: bool = True):
        return self.policy.predict(observation, deterministic=deterministic)


def load_policy(config: RunConfig, path: pathlib.Path, env: gym.Env,
                device: str = "auto") -> ActorPolicy:
    """The actor saved at `path` by a run of `config`, on `env`'s spaces."""
    device = resolve_device(device)
    state = read_policy_file(config, path, device)
    if config.backend == "sbx":
        return ActorPolicy(_sbx_policy(config, state["actor"], env, path), state["steps"])
    policy_class = algorithm_class(config.algo).policy_aliases["MultiInputPolicy"]
    policy = policy_class(env.observation_space, env.action_space, lr_schedule=lambda _: 0.0,
                          **policy_kwargs(config.algo, config.hyperparameters))
    try:
        policy.actor.load_state_dict(state["actor"])
    except RuntimeError:  # Other layers or shapes: another algorithm or network.
        raise ValueError(f"{path}: its actor's parameters do not fit the network its run's "
                         f"config.json describes ({config.algo}, net_arch "
                         f"{list(config.hyperparameters.net_arch)})") from None
    policy.set_training_mode(False)
    return ActorPolicy(policy.to(device), state["steps"])


#: What torch's weights-only unpickler says before what it met: its first lines advise
#: loading the file with `weights_only=False`, which runs whatever code a file holds.
_WEIGHTS_ONLY_DETAIL = "WeightsUnpickler error:"


def _what_torch_met(error: Exception) -> str:
    """The first line of torch's error, or of what its weights-only unpickler met."""
    text = str(error)
    if _WEIGHTS_ONLY_DETAIL in text:
        text = text.split(_WEIGHTS_ONLY_DETAIL, 1)[1].strip()
    return (text.splitlines() or [""])[0]


def read_policy_file(config: RunConfig, path: pathlib.Path, device: str = "cpu") -> dict:
    """The contents of the policy file at `path` of a run of `config` ({"actor", "steps",
    ...}); a ValueError naming it if it is not one franka_composer wrote for such a run."""
    import torch

    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as error:  # torch raises what its unpickler or zip reader meets.
        raise ValueError(f"{path} is not a policy file (torch cannot read it: "
                         f"{type(error).__name__} {_what_torch_met(error)})") from None
    if not isinstance(state, dict) or not {"actor", "steps"} <= state.keys():
        raise ValueError(f"{path} is not a policy file franka_composer wrote (no actor and "
                         "steps in it)")
    if state.get("format") != FORMAT:
        raise ValueError(f"{path} is a policy file of format {state.get('format')!r}; this "
                         f"version of franka_composer reads format {FORMAT}")
    saved_by = state.get("backend", "sb3")  # Files from before sbx's were SB3's.
    if saved_by != config.backend:
        raise ValueError(f"{path} holds an actor of {saved_by}, and its run's config.json "
                         f"says {config.backend}")
    actor = state["actor"]
    if not isinstance(actor, dict) or not all(torch.is_tensor(t) for t in actor.values()):
        raise ValueError(f"{path} is not a policy file franka_composer wrote (its actor is "
                         "not a mapping of parameter names to tensors)")
    if "sha256" in state and state["sha256"] != _digest(saved_by, state["steps"], actor):
        # Files written before the digest have none, and pass.
        raise ValueError(f"{path} is not the policy file its run wrote: its actor and steps "
                         "do not give the SHA-256 it holds (damaged or edited since)")
    broken = [name for name, tensor in actor.items()
              if tensor.is_floating_point() and not torch.isfinite(tensor).all()]
    if broken:  # It would act NaN, or raise from inside torch's distributions.
        raise ValueError(f"{path}'s actor has parameters that are not finite (NaN or inf in "
                         f"{', '.join(broken)}): saved from a run that diverged?")
    return state


def _sbx_policy(config: RunConfig, weights: dict, env: gym.Env, path: pathlib.Path):
    """A freshly built sbx model's policy with the saved actor parameters in place (its
    critics stay untrained: acting needs the actor alone)."""
    jax_imported()
    import flax
    import jax.numpy as jnp
    from flax.traverse_util import flatten_dict, unflatten_dict

    hp = config.hyperparameters.replace(buffer_size=1_000)  # Acting never reads the buffer.
    policy = build_model(config.algo, hp, env, seed=config.seed, device="cpu",
                         backend="sbx").policy
    fresh = flatten_dict(dict(policy.actor_state.params), sep="/")
    if {name: tuple(leaf.shape) for name, leaf in fresh.items()} != {
            name: tuple(tensor.shape) for name, tensor in weights.items()}:
        raise ValueError(f"{path}: its actor's parameters do not fit the network its run's "
                         "config.json describes")
    params = unflatten_dict({name: jnp.asarray(weights[name].numpy()) for name in fresh},
                            sep="/")
    if isinstance(policy.actor_state.params, flax.core.FrozenDict):
        params = flax.core.freeze(params)
    policy.actor_state = policy.actor_state.replace(params=params)
    return policy


def check_trained(run: RunDir) -> None:
    """A ValueError naming `run` if it holds nothing trained to load (a run still training
    and kept without a checkpoint, say), or only a policy file that is not one
    (`read_policy_file`), only damaged models (`model_damage`), or a model another
    algorithm or library saved than its config.json says (`check_saved_by`): asked before
    an env is made for it, so that `evaluate` finds a bad run among many before playing any."""
    config = run.read_config()
    run.check_config_checkpointed()  # (A hand edit: played at settings it never trained at.)
    check_no_folders(run)
    models = [path for path in (run.final_model, run.checkpoint_model) if path.is_file()]
    damages = [model_damage(path) for path in models]
    for path, damage in zip(models, damages):
        if damage is None:
            check_saved_by(path, config.algo, config.backend)
    if None in damages:
        return
    if not run.policy_file.is_file():
        if models:
            damaged = "; ".join(f"{path} is damaged ({damage})"
                                for path, damage in zip(models, damages))
            raise ValueError(f"{damaged}, and the run has no whole model to play instead "
                             "(model.zip, a checkpoint, policy.pt)")
        if run.read_outcome():  # A finished run's kept copy, its policy.pt left out.
            raise ValueError(f"{run.root} has ended ({run.outcome_path.name}) and was kept "
                             "without its model (no model.zip, no checkpoint, no policy.pt)")
        raise ValueError(f"{run.root} has no model yet (no model.zip, no checkpoint, "
                         "no policy.pt)")
    read_policy_file(config, run.policy_file)


def check_no_folders(run: RunDir) -> None:
    """A ValueError naming the first of `run`'s model files that is a folder (made by hand,
    or a copy gone wrong), where it would otherwise read as absent: the run taken for one
    not trained yet, or kept without its policy."""
    for path in (run.final_model, run.checkpoint_model, run.policy_file):
        if path.is_dir():
            raise ValueError(f"{path} is a folder, where {run.root} keeps a model file: "
                             "move it away")


def split_trained(roots) -> tuple[list[pathlib.Path], list[pathlib.Path]]:
    """`roots` split into the runs with something trained to play (each checked,
    `check_trained`) and those not yet (a sweep under way: a cell not begun, or before its
    first checkpoint); a run that ended with nothing to play, or none with anything, is a
    ValueError naming it."""
    trained, waiting = [], []
    for root in roots:
        run = RunDir(pathlib.Path(root))
        run.read_config()
        check_no_folders(run)
        if (not any(path.is_file() for path in (run.final_model, run.checkpoint_model,
                                                 run.policy_file))
                and not run.read_outcome()):
            waiting.append(root)
            continue
        check_trained(run)
        trained.append(root)
    if not trained:
        raise ValueError(f"nothing trained yet in {', '.join(map(str, waiting))} (no "
                         "model.zip, no checkpoint, no policy.pt)")
    return trained, waiting


def load_trained(run: RunDir, env: gym.Env, device: str = "auto"):
    """What `run` trained, ready to act on `env`: its full model (model.zip, else its latest
    checkpoint: `RunDir.best_model`) where it has one whole, else its policy file (a run as
    committed; a warning says which damaged model was passed over)."""
    config = run.read_config()
    check_trained(run)
    if run.final_model.is_file() or run.checkpoint_model.is_file():
        try:
            model = run.best_model()
        except ValueError as damaged:
            if not run.policy_file.is_file():
                raise
            warnings.warn(f"{damaged}: using its policy file, {run.policy_file}",
                          RuntimeWarning, stacklevel=2)
        else:
            return load_model(config.algo, model, env=env, device=device,
                              backend=config.backend)
    return load_policy(config, run.policy_file, env, device)


@contextlib.contextmanager
def trained_on_its_task(root: pathlib.Path, device: str = "auto", wrap=None, **options):
    """(config, env, policy): the run at `root`, its task's env made with the options it
    trained with, less those `options` give instead (wrapped by `wrap`, if given), and what
    it trained, acting on that env, which is closed on leaving, whatever happens inside."""
    run = RunDir(pathlib.Path(root))
    config = run.read_config()
    check_trained(run)
    env = make_env(config.task, **{**config.env_options, **options})
    try:
        if wrap is not None:
            env = wrap(env)
        yield config, env, load_trained(run, env, device=device)
    finally:
        env.close()
