"""Milliseconds per gradient step in fp32 and in bf16 (`train --precision`), same model, same
replay buffer, one process, as ratios.

    python benchmarks/precision.py [--task push] [--algos sac tqc ddpg] [--steps 100]
                                   [--rounds 3] [--threads 1] [--device cpu]

For each algorithm: a model with Table I's settings for the task, its HER buffer filled by
1000 steps of the untrained policy; then `rounds` alternating rounds of `steps` gradient
steps (SB3's own `train`) in each precision, the fastest round of each counted, so a burst
of load on the shared machine spoils one round, not the ratio. Prints a Markdown table and
whether the CPU has bf16 units (without them autocast emulates bf16 and is slower). With
`--device cuda` the networks run on the GPU and each round ends with a synchronisation, so
it counts the kernels, not just their launches.
"""

from __future__ import annotations

import argparse
import time

from franka_composer.cli.options import positive_int
from franka_composer.tasks import ALL_TASKS
from franka_composer.training import ALGOS, PRECISIONS, hyperparameters
from franka_composer.training.machine import bf16_units
from franka_composer.training.models import DEVICES, build_model, make_env, quiet_logger
from franka_composer.training.precision import autocast

FILL_STEPS = 1000


def time_gradient_steps(task: str, algo: str, steps: int, rounds: int,
                        device: str) -> dict[str, float]:
    """Fastest ms per gradient step per precision."""
    import torch

    hp = hyperparameters(task, algo).replace(learning_starts=FILL_STEPS)
    env = make_env(task)
    model = build_model(algo, hp, env, seed=0, device=device)
    synchronize = torch.cuda.synchronize if device == "cuda" else lambda: None
    model.set_logger(quiet_logger())
    model.learn(total_timesteps=FILL_STEPS)  # Fills the buffer.
    best = {precision: float("inf") for precision in PRECISIONS}
    for _ in range(rounds):
        for precision in PRECISIONS:
            with autocast(precision, model.device):
                synchronize()
                start = time.perf_counter()
                model.train(gradient_steps=steps, batch_size=hp.batch_size)
                synchronize()
                elapsed = time.perf_counter() - start
            best[precision] = min(best[precision], 1000 * elapsed / steps)
    env.close()
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="push", choices=ALL_TASKS)
    parser.add_argument("--algos", nargs="+", default=["sac", "tqc", "ddpg"], choices=ALGOS)
    parser.add_argument("--steps", type=positive_int, default=100,
                        help="gradient steps per round and precision (default: 100)")
    parser.add_argument("--rounds", type=positive_int, default=3,
                        help="rounds, the best of which is reported (default: 3)")
    parser.add_argument("--threads", type=positive_int, default=1)
    parser.add_argument("--device", default="cpu", choices=DEVICES[1:])
    args = parser.parse_args(argv)
    import torch

    if args.device == "cuda" and not torch.cuda.is_available():  # Before any work.
        parser.error("--device cuda, but torch sees no CUDA GPU (torch.cuda.is_available() is "
                     "False); use --device cpu")
    device = args.device
    torch.set_num_threads(args.threads)
    where = torch.cuda.get_device_name() if device == "cuda" else "CPU"
    units = {True: "yes", False: "no", None: "unknown"}[bf16_units()]
    print(f"{where}; CPU bf16 units: {units}; torch "
          f"{torch.__version__}; {args.threads} thread(s); {args.task}, Table I networks and "
          f"batch")
    print("\n| algorithm | fp32 ms/step | bf16 ms/step | fp32 / bf16 |\n|---|---|---|---|")
    for algo in args.algos:
        ms = time_gradient_steps(args.task, algo, args.steps, args.rounds, device)
        print(f"| {algo} | {ms['fp32']:.1f} | {ms['bf16']:.1f} | "
              f"{ms['fp32'] / ms['bf16']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
