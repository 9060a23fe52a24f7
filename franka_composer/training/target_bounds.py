"""Bootstrap values kept within the returns a sparse reward allows
(`Hyperparameters.clip_q_targets`).

Under the sparse reward (-1 per step until the goal is reached, 0 once it is) every
return lies in [-1/(1-gamma), 0], so a target critic value outside that range is the
critic's error, not something to learn from. Bootstrapping from such values lets a critic
that extrapolates feed on itself without bound: SAC with expert demonstrations in its
replay buffer did on pick_and_place, its values rising to 2e5-4e5 within 4k steps
(docs/experiments/demonstrations.md). OpenAI baselines' HER clips its TD targets to this range
(`clip_return`); SB3 has no such bound. Here the target critic's outputs are clamped to
it, so SB3 forms r + gamma (1 - done) (clamp(Q') - alpha log pi') for SAC and TQC (each
quantile clamped) and r + gamma (1 - done) clamp(Q') for DDPG.
"""

from __future__ import annotations


def sparse_return_range(gamma: float) -> tuple[float, float]:
    """The returns of a -1/0 reward discounted by `gamma`: (-1/(1-gamma), 0)."""
    return -1.0 / (1.0 - gamma), 0.0


def clip_target_critic(model, gamma: float):
    """Clamps what `model`'s target critic (SB3 / sb3-contrib DDPG, SAC, TQC) returns to
    `sparse_return_range(gamma)`; returns the hook's handle (`.remove()` undoes it). The
    target critic only ever serves the TD targets, so nothing else changes; a saved model
    does not keep the hook, so a resumed run clips again (`training/loop.py`)."""
    low, high = sparse_return_range(gamma)

    def clamp(module, inputs, output):
        if isinstance(output, tuple):  # One value per critic (DDPG, SAC).
            return tuple(values.clamp(low, high) for values in output)
        return output.clamp(low, high)  # TQC: (batch, critics, quantiles).

    return model.policy.critic_target.register_forward_hook(clamp)
