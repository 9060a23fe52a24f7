"""How saturated a trained SAC or TQC actor is: where sbx's and SB3's tanh corrections part.

Both squash a Gaussian sample u through tanh, and both subtract the log-determinant of tanh
from its log-probability, differently: sbx takes TensorFlow Probability's exact
log(1 − tanh²u), SB3 log(1 − a² + 1e-6) of the squashed action a, which caps the
correction at 13.8 nats per component. They agree to 0.04 nats up to |u| = 6 and part
beyond (0.26 nats at 7, 1.2 at 8, 4.8 at 10), where the entropy estimate that tunes the
entropy coefficient, and the gradient on a saturated component, differ. Whether a learner
ever acts there is what this measures: it plays a run's deterministic policy in the env it
trained in and reports, per action component, the share of steps whose pre-tanh mean |u|
passes `--threshold`, the median |u| and the policy's median standard deviation, and the
run's entropy coefficient.

    python experiments/actor_saturation.py RUN_DIR [--reference-path DIR] [--episodes 20]

`--reference-path` (a checkout of the reference code) is needed for a run trained in the
reference code's env (`experiments/reference_env_runs.py`).
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int, positive_number
from franka_composer.training.policy_file import trained_on_its_task
from franka_composer.training.runs import RunDir

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import reference_env_runs  # noqa: E402  (experiments/, not a package)

#: SB3's epsilon in log(1 − a² + ε) (`stable_baselines3/common/distributions.py`).
SB3_EPSILON = 1e-6


def exact_correction(u: np.ndarray) -> np.ndarray:
    """log(1 − tanh²u), computed without cancellation (sbx's, through TFP's Tanh)."""
    u = np.abs(np.asarray(u, dtype=np.float64))
    return 2.0 * (math.log(2.0) - u - np.log1p(np.exp(-2.0 * u)))


def sb3_correction(u: np.ndarray) -> np.ndarray:
    """log(1 − a² + 1e-6) of a = tanh(u) in float32, as SB3 computes it from the action."""
    action = np.tanh(np.asarray(u, dtype=np.float32))
    return np.log(1.0 - action.astype(np.float64) ** 2 + SB3_EPSILON)


def gaussian_parameters(model, observation) -> tuple[np.ndarray, np.ndarray]:
    """The actor's pre-tanh mean and standard deviation for one observation, on either
    backend."""
    if hasattr(model.policy, "actor_state"):  # sbx
        flat, _ = model.policy.prepare_obs(observation)
        state = model.policy.actor_state
        gaussian = state.apply_fn(state.params, flat).distribution
        return np.asarray(gaussian.loc)[0], np.asarray(gaussian.stddev())[0]
    import torch

    tensor, _ = model.policy.obs_to_tensor(observation)
    with torch.no_grad():
        mean, log_std, _ = model.policy.actor.get_action_dist_params(tensor)
    return mean.numpy()[0], log_std.exp().numpy()[0]


def entropy_coefficient(model) -> float | None:
    """The learnt entropy coefficient, or None for a policy file (it keeps the actor
    alone)."""
    if hasattr(model, "ent_coef_state"):  # sbx
        state = model.ent_coef_state
        return float(state.apply_fn({"params": state.params}))
    if hasattr(model, "log_ent_coef"):
        return float(model.log_ent_coef.exp().item())
    return None


def play(model, env, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(pre-tanh means, standard deviations) at every step of `episodes` deterministic
    episodes, the first reset seeded `seed`."""
    means, stds = [], []
    observation, _ = env.reset(seed=seed)
    for _ in range(episodes):
        done = False
        while not done:
            mean, std = gaussian_parameters(model, observation)
            means.append(mean)
            stds.append(std)
            action, _ = model.predict(observation, deterministic=True)
            observation, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
        observation, _ = env.reset()
    return np.array(means), np.array(stds)


def table(means: np.ndarray, stds: np.ndarray, threshold: float) -> list[str]:
    lines = [f"| component | steps with \\|u\\| > {threshold:g} | median \\|u\\| | largest \\|u\\| "
             "| median std | SB3 − sbx correction at the largest \\|u\\| (nats) |",
             "|---|---|---|---|---|---|"]
    for index in range(means.shape[1]):
        u = np.abs(means[:, index])
        largest = float(u.max())
        gap = float(sb3_correction(largest) - exact_correction(largest))
        lines.append(f"| {index} | {100 * np.mean(u > threshold):.1f} % | {np.median(u):.2f} "
                     f"| {largest:.2f} | {np.median(stds[:, index]):.3g} | {gap:.2f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=pathlib.Path, metavar="RUN_DIR")
    parser.add_argument("--reference-path", type=pathlib.Path, metavar="DIR")
    parser.add_argument("--episodes", type=positive_int, default=20)
    parser.add_argument("--seed", type=episode_seed, default=100)
    parser.add_argument("--threshold", type=positive_number, default=6.0,
                        help="|u| beyond which the two corrections part (default 6)")
    args = parser.parse_args(argv)
    try:
        config = RunDir(args.run).read_config()
    except (OSError, ValueError) as bad:
        parser.error(str(bad))
    if config.algo not in ("sac", "tqc"):
        parser.error(f"{args.run} trained {config.algo}; only SAC and TQC squash a Gaussian")
    if config.environment == reference_env_runs.NAME:
        if args.reference_path is None:
            parser.error(f"{args.run} trained in the reference code's env: give "
                         "--reference-path")
        error = reference_env_runs.peer_worker.reference_path_error(args.reference_path)
        if error:
            parser.error(error)
        reference_env_runs.install(reference_env_runs.reference_specs(args.reference_path))
    with trained_on_its_task(args.run, device="cpu") as (_, env, model):
        means, stds = play(model, env, args.episodes, args.seed)
        coefficient = entropy_coefficient(model)
    coefficient = ("not in a policy file" if coefficient is None
                   else f"{coefficient:.3g}")
    print(f"{args.run}: {config.algo} on {config.backend}, {model.num_timesteps:,} steps; "
          f"{args.episodes} deterministic episodes (first reset seed {args.seed}), "
          f"{len(means)} steps; entropy coefficient {coefficient}\n")
    print("\n".join(table(means, stds, args.threshold)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
