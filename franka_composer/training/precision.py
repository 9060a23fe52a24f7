"""The arithmetic of the gradient steps while training (`RunConfig.precision`).

Training is gradient-bound on a CPU (25-60 ms per update with Table I's networks), and CPUs
with bfloat16 units (AVX512-BF16, AMX) do matrix products in bf16 at a fraction of fp32's
cost. "bf16" runs SB3's gradient steps (`model.train`: every network pass of the actor,
critics and targets, forward and backward) under `torch.autocast`: the matrix products in
bf16, reductions, losses and whatever else autocast keeps in fp32 in fp32, and the weights,
their gradients and the optimisers' state in fp32, so a bf16 run saves ordinary fp32
models. bf16 keeps fp32's exponent range, so unlike fp16 no loss scaling is needed. The
rollouts (one observation per pass: nothing to gain) and the evaluations (the policy a user
loads) stay fp32.
"""

from __future__ import annotations

import contextlib
import warnings

from stable_baselines3.common.callbacks import BaseCallback


#: SAC's gradient step on pick_and_place (Table I), ms in fp32 and bf16 on a CPU without
#: bf16 units (AMD EPYC, AVX2): `python benchmarks/precision.py --task pick_and_place
#: --algos sac --steps 20 --rounds 2`, 2026-11-30.
_EMULATED_MS = (41.8, 706.7)


def warn_if_emulated(precision: str, device) -> None:
    """A RuntimeWarning where a run computes in bf16 on a CPU without bf16 units
    (`machine.bf16_units`): torch emulates them there, and bf16, the fast option elsewhere
    (and `--preset fast`'s), trains many times slower than fp32."""
    import torch

    from franka_composer.training.machine import bf16_units

    if precision == "fp32" or torch.device(device).type != "cpu" or bf16_units() is not False:
        return
    fp32, bf16 = _EMULATED_MS
    warnings.warn(f"this run's gradient steps are in bf16 and this CPU has no bf16 units "
                  "(AVX512-BF16, AMX-BF16 or Arm's BF16): torch emulates them, and a step "
                  f"takes many times fp32's ({bf16 / fp32:.0f}x with SAC on pick_and_place on "
                  "an AVX2 EPYC; `python benchmarks/precision.py` measures it here); "
                  "--precision fp32 trains the same settings in fp32 (after --preset fast "
                  "too)", RuntimeWarning, stacklevel=2)


def autocast(precision: str, device):
    """A context in which network passes run in `precision` ("fp32": unchanged)."""
    import torch

    if precision == "fp32":
        return contextlib.nullcontext()
    return torch.autocast(device_type=torch.device(device).type, dtype=torch.bfloat16)


class GradientStepPrecision(BaseCallback):
    """Runs the gradient steps of `learn` in `precision`: SB3 calls `train` between a
    rollout's end and the next rollout's start, so the autocast context is entered at
    every rollout's end and left at the next one's start (and when training ends, also by
    an interruption: `close`)."""

    def __init__(self, precision: str) -> None:
        super().__init__()
        self._precision = precision
        self._context = contextlib.ExitStack()

    def _on_rollout_end(self) -> None:
        self._context.enter_context(autocast(self._precision, self.model.device))

    def _on_rollout_start(self) -> None:
        self.close()

    def _on_training_end(self) -> None:
        self.close()

    def _on_step(self) -> bool:
        return True

    def close(self) -> None:
        """Back to fp32 (a no-op outside the gradient steps)."""
        self._context.close()
