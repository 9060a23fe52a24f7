"""What SAC's (or TQC's) critic and entropy coefficient do over the first steps of a run,
with or without demonstrations in the replay buffer: the diagnosis behind issue 17.

    python benchmarks/critic_probe.py --demos DATASET [--task pick_and_place] [--algo sac]
        [--seed 0] [--steps 4000] [--every 250] [--no-prefill] [--clip-q-targets]
    python benchmarks/critic_probe.py --demos DATASET --model RUN_DIR/model.zip [--algo sac]

Builds and fills the model as `franka-composer train --demos DATASET` does (Table I, the
episode update schedule of issue 17's runs, the same seed; `--no-prefill` leaves the buffer
empty, as a run without demonstrations), then trains and prints, every `--every` steps:
the entropy coefficient, and on every state of the dataset the actor's mean log-probability
of its own sampled actions, the critic's mean value of them (min over SAC's critics, mean
over TQC's quantiles), the fraction of states where the actor's mean action is saturated
(|tanh| > 0.95) per action dimension, and the mean log standard deviation per dimension.
With `--model` it prints the same for a trained model instead, on its run's task.
Under the sparse reward every return lies in [-1/(1-gamma), 0] = [-20, 0], plus the
entropy bonus (alpha * -log pi per step, while alpha is large early on): values far
outside that are the critic diverging.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from franka_composer.cli.options import positive_int, training_seed
from franka_composer.policies.rollout import OBSERVATION_KEYS
from franka_composer.tasks import ALL_TASKS
from franka_composer.training import demos, hyperparameters
from franka_composer.training.models import build_model, load_model, make_env
from franka_composer.training.target_bounds import clip_target_critic


def probe_states(episodes) -> dict[str, np.ndarray]:
    """Every state the demonstrations act in (their final observations left out)."""
    return {key: np.concatenate([e[key][:-1] for e in episodes]) for key in OBSERVATION_KEYS}


def critic_report(model, states) -> dict:
    """The entropy coefficient and the actor's and critic's statistics on `states`. Its
    action samples come from a fork of torch's generator, so probing leaves the run as
    `train` makes it."""
    import torch

    policy = model.policy
    with torch.no_grad(), torch.random.fork_rng():
        obs = policy.obs_to_tensor(states)[0]
        mean, log_std, _ = policy.actor.get_action_dist_params(obs)
        actions, log_prob = policy.actor.action_log_prob(obs)
        values = policy.critic(obs, actions)
        if isinstance(values, tuple):  # SAC: one value per critic, the least counts.
            q = torch.min(torch.cat(values, dim=1), dim=1).values
        else:  # TQC: (batch, critics, quantiles).
            q = values.mean(dim=(1, 2))
        return {"alpha": float(torch.exp(model.log_ent_coef)),
                "log_pi": float(log_prob.mean()), "q": float(q.mean()),
                "saturated": (torch.tanh(mean).abs() > 0.95).float().mean(0).numpy(),
                "log_std": log_std.mean(0).numpy()}


HEADER = "| steps | alpha | log pi | Q | saturated | log std |\n|---|---|---|---|---|---|"


def _row(model, states) -> str:
    r = critic_report(model, states)
    numbers = {key: " ".join(f"{v:.2f}" for v in r[key]) for key in ("saturated", "log_std")}
    return (f"| {model.num_timesteps} | {r['alpha']:.3g} | {r['log_pi']:.2f} | {r['q']:.3g} | "
            f"{numbers['saturated']} | {numbers['log_std']} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--demos", type=pathlib.Path, required=True, metavar="DATASET",
                        help="the demonstrations (their states are probed either way)")
    parser.add_argument("--task", choices=ALL_TASKS, default="pick_and_place")
    parser.add_argument("--algo", choices=("sac", "tqc"), default="sac")
    parser.add_argument("--seed", type=training_seed, default=0)
    parser.add_argument("--steps", type=positive_int, default=4000)
    parser.add_argument("--every", type=positive_int, default=250)
    parser.add_argument("--no-prefill", dest="prefill", action="store_false",
                        help="leave the replay buffer empty (a run without demonstrations)")
    parser.add_argument("--clip-q-targets", action="store_true",
                        help="as `train --clip-q-targets`")
    parser.add_argument("--model", type=pathlib.Path, default=None,
                        help="a trained model to probe instead of training one")
    args = parser.parse_args()

    from stable_baselines3.common.callbacks import BaseCallback

    hp = hyperparameters(args.task, args.algo).replace(update_schedule="episode")
    env = make_env(args.task)
    episodes = demos.load_episodes(args.demos, env)
    if args.model is not None:
        print(f"{args.model}: {args.demos.name}'s {len(episodes)} episodes\n{HEADER}")
        print(_row(load_model(args.algo, args.model, env=env, device="cpu"),
                   probe_states(episodes)))
        return
    model = build_model(args.task, args.algo, hp, env, seed=args.seed, device="cpu")
    if args.prefill:
        demos.prefill(model, episodes, hp.total_steps)
    if args.clip_q_targets:
        clip_target_critic(model, hp.gamma)
    states = probe_states(episodes)

    class Report(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % args.every == 0:
                print(_row(self.model, states), flush=True)
            return True

    print(f"{args.task} {args.algo} seed {args.seed}, "
          f"{'prefilled with' if args.prefill else 'without'} {len(episodes)} episodes of "
          f"{args.demos.name}{', clipped targets' if args.clip_q_targets else ''}")
    print(HEADER)
    model.learn(args.steps, callback=Report())
    env.close()


if __name__ == "__main__":
    main()
