"""What a checkpoint holds besides SB3's model and replay buffer, so that a resumed run goes
on bit for bit as the uninterrupted run would (same code, same machine).

A checkpoint taken where an episode has just ended, after that step's transition is stored
and its gradient steps are done, leaves only two things outside the model and the buffer:

- the random generators the learner draws from: torch's, NumPy's and Python's global ones
  (SB3's action sampling, replay sampling, HER's goals, action noise), the action space's
  (random actions before learning starts) and sbx's JAX keys;
- the training env, which has just reset: the episode a reset draws depends only on its
  episode stream's seed and how many resets came before (`FrankaGoalEnv.reset`), so
  seeding a new env the same way and resetting it as often rebuilds it. The reset's
  observation must equal the model's saved `_last_obs`; where it does not, the resume is
  not exact and says so.

A run resumed from any other checkpoint (an interrupt that could not wait for the episode's
end, a run stopped mid-episode at its budget, checkpoints written before these existed)
starts a fresh episode stream, seeded by the run's seed and step: reproducible, not the
uninterrupted run.
"""

from __future__ import annotations

import dataclasses
import pathlib
import pickle
import random

import numpy as np

from franka_composer.training.run_files import unpickling

#: The JAX keys of an sbx model and its policy (absent from SB3 models).
_JAX_KEYS = (("model", "key"), ("policy", "key"), ("policy", "noise_key"))


@dataclasses.dataclass(frozen=True)
class EpisodeStream:
    """How the training env's episodes were seeded: `seed` given to its reset when the
    model had finished `episodes_before` training episodes (0 for a fresh run)."""

    seed: int
    episodes_before: int = 0

    def resets(self, model) -> int:
        """Resets the env has made since it was seeded: the first, one per episode since."""
        return 1 + model._episode_num - self.episodes_before


def _owners(model) -> dict:
    return {"model": model, "policy": model.policy}


def save(model, stream: EpisodeStream, path: pathlib.Path) -> None:
    """Writes the generators' states and the episode stream of `model`, now."""
    import torch

    owners = _owners(model)
    state = {"stream": dataclasses.asdict(stream), "torch": torch.get_rng_state(),
             "numpy": np.random.get_state(), "python": random.getstate(),
             "action_space": model.action_space.np_random.bit_generator.state,
             "jax": {f"{owner}.{name}": np.asarray(getattr(owners[owner], name))
                     for owner, name in _JAX_KEYS if hasattr(owners[owner], name)}}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    path.write_bytes(pickle.dumps(state))


def restore(model, path: pathlib.Path) -> EpisodeStream | None:
    """Rebuilds `model`'s training env from the episode stream saved at `path` and sets the
    generators to their saved states; returns the stream, or None (nothing changed but the
    env's resets) where the rebuilt env's observation is not the model's `_last_obs`."""
    import torch

    with unpickling(path):
        state = pickle.loads(path.read_bytes())
        stream = EpisodeStream(**state["stream"])
    env = model.get_env()
    env.seed(stream.seed)
    for _ in range(stream.resets(model)):
        observation = env.reset()
    if not _same_observation(observation, model._last_obs):
        return None
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])
    np.random.set_state(state["numpy"])
    random.setstate(state["python"])
    model.action_space.np_random.bit_generator.state = state["action_space"]
    if state["jax"]:
        import jax.numpy as jnp

        for name, key in state["jax"].items():
            owner, attribute = name.split(".")
            setattr(_owners(model)[owner], attribute, jnp.asarray(key))
    return stream


def _same_observation(a, b) -> bool:
    if b is None or a.keys() != b.keys():
        return False
    return all(np.array_equal(a[key], b[key]) for key in a)
