"""How far are bf16's gradients from fp32's (`train --precision`)? For trained SB3 runs: the
cosine and relative error, bf16 against fp32, of the critic's and the actor's gradients of
one of SB3's own gradient steps, on the same batch with the same noise.

    python benchmarks/precision_fidelity.py RUN [RUN ...] [--batches 20] [--fill-steps 3000]

Each run's model (model.zip) plays `fill-steps` steps of its own policy into a fresh HER
buffer, without training; then for each of `batches` seeds the gradient step runs in fp32
and in bf16 from the same state (optimisers' steps and the target update held back) and
the gradients the optimisers would have applied are compared. Issue 15's learning checks
ask whether bf16 learns as fp32 does; this shows where it departs.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import pathlib

import numpy as np

from franka_composer.cli.options import positive_int
from franka_composer.training.models import load_model, make_env
from franka_composer.training.precision import autocast
from franka_composer.training.runs import RunDir


@contextlib.contextmanager
def _steps_held_back(model, captured: dict):
    """Within it, the optimisers record the gradients they are given instead of stepping,
    and the target networks are put back afterwards: a gradient step changes nothing."""
    import torch

    optimisers = {"critic": model.critic.optimizer, "actor": model.actor.optimizer}
    if getattr(model, "ent_coef_optimizer", None) is not None:
        optimisers["entropy coefficient"] = model.ent_coef_optimizer
    targets = [(net, copy.deepcopy(net.state_dict()))
               for net in (getattr(model, "critic_target", None),
                           getattr(model, "actor_target", None)) if net is not None]

    def recorder(name, optimiser):
        def step(*args, **kwargs):
            captured[name] = torch.cat([p.grad.flatten().clone()
                                        for group in optimiser.param_groups
                                        for p in group["params"] if p.grad is not None])
        return step

    own = {name: optimiser.__dict__.get("step") for name, optimiser in optimisers.items()}
    for name, optimiser in optimisers.items():
        optimiser.step = recorder(name, optimiser)
    try:
        yield
    finally:
        for name, optimiser in optimisers.items():
            if own[name] is None:
                del optimiser.step  # The class's step again.
            else:
                optimiser.step = own[name]
        for net, state in targets:
            net.load_state_dict(state)


def gradients(model, precision: str, seed: int) -> dict:
    """The gradients of one SB3 gradient step in `precision`, its batch and noise drawn
    from `seed` (SB3 samples with NumPy and acts with torch)."""
    import torch

    captured: dict = {}
    np.random.seed(seed)
    torch.manual_seed(seed)
    with _steps_held_back(model, captured), autocast(precision, model.device):
        model.train(gradient_steps=1, batch_size=model.batch_size)
    return captured


def compare(model, batches: int, against: str = "bf16") -> dict[str, np.ndarray]:
    """Per network: (cosine, relative error) of `against`'s gradients to fp32's, per batch."""
    import torch

    rows: dict[str, list] = {}
    for seed in range(batches):
        reference, other = gradients(model, "fp32", seed), gradients(model, against, seed)
        for name in ("critic", "actor"):
            cosine = torch.nn.functional.cosine_similarity(reference[name], other[name], dim=0)
            error = (other[name] - reference[name]).norm() / reference[name].norm()
            rows.setdefault(name, []).append((float(cosine), float(error)))
    return {name: np.array(values) for name, values in rows.items()}


def fill(model, steps: int) -> None:
    """`steps` of the model's own play into its (fresh) buffer, no gradient step."""
    gradient_steps, learning_starts = model.gradient_steps, model.learning_starts
    model.gradient_steps, model.learning_starts = 0, 0
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    model.gradient_steps, model.learning_starts = gradient_steps, learning_starts


def main(argv: list[str] | None = None) -> None:
    import torch

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=pathlib.Path, metavar="RUN")
    parser.add_argument("--batches", type=positive_int, default=20)
    parser.add_argument("--fill-steps", type=positive_int, default=3000)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    print("| run | steps | network | cosine, mean (min) | relative error, mean (max) |")
    print("|---|---|---|---|---|")
    for root in args.runs:
        run = RunDir(root)
        config = run.read_config()
        if config.backend != "sb3":
            raise SystemExit(f"{root}: bf16 is SB3's (torch.autocast); this run used "
                             f"{config.backend}")
        env = make_env(config.task, **config.env_options)
        model = load_model(config.algo, run.best_model(), env=env, device="cpu")
        trained = model.num_timesteps
        fill(model, args.fill_steps)
        for name, values in compare(model, args.batches).items():
            print(f"| {root.name} ({config.algo}, {config.precision}) | "
                  f"{trained:,} | {name} | {values[:, 0].mean():.3f} "
                  f"({values[:, 0].min():.3f}) | {values[:, 1].mean():.3f} "
                  f"({values[:, 1].max():.3f}) |")
        env.close()


if __name__ == "__main__":
    main()
