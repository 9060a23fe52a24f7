"""`franka-composer evaluate`: the paper's final test (20 episodes per trained model) and a
Table II-style summary over runs."""

from __future__ import annotations

import argparse

from franka_composer.cli.options import (add_run_dirs, episode_seed, output_file,
                                         positive_int, report_waiting)
from franka_composer.training.models import DEVICES
from franka_composer.wording import counted


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "evaluate", help="success rate of trained runs, and a Table II-style Markdown table",
        description="Run each trained model (RUN_DIR/model.zip, else its latest checkpoint, "
                    "else its policy.pt) "
                    "for --episodes deterministic episodes on its task; print the success "
                    "rate per run, then a Markdown table of mean ± std over seeds per task "
                    "(and setup) and algorithm, in the layout of the paper's Table II.")
    add_run_dirs(parser)
    parser.add_argument("--episodes", type=positive_int, default=20,
                        help="test episodes per model (default: 20, the paper's final "
                             "test)")
    parser.add_argument("--seed", type=episode_seed, default=2024,
                        help="seed of the test episodes, the same for every run (default: "
                             "2024, the final tests' in RESULTS.md)")
    parser.add_argument("--device", choices=DEVICES, default="auto",
                        help="where the policy runs (default: auto, cuda where torch sees "
                             "a GPU)")
    parser.add_argument("--out", type=output_file, default=None,
                        help="also write the Markdown table (and per-seed notes) here")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from franka_composer.training.evaluation import measure_success
    from franka_composer.training.models import resolve_device
    from franka_composer.training.policy_file import split_trained, trained_on_its_task
    from franka_composer.training.report import (RunResult, markdown_table, seeds_note,
                                                 with_variant)
    from franka_composer.training.runs import check_out_apart
    from franka_composer.training.sweep import run_directories

    resolve_device(args.device)  # Before an env is built for the first run.
    roots = run_directories(args.runs)
    check_out_apart(args.out, roots)
    # Every run checked before the first is played, not after; those not trained yet (a
    # sweep under way) are left out and named.
    roots, waiting = split_trained(roots)
    report_waiting(waiting, "has nothing trained yet (no model.zip, no checkpoint, no "
                            "policy.pt)")
    results = []
    for root in roots:
        with trained_on_its_task(root, device=args.device) as (config, env, model):
            outcome = measure_success(model, env, args.episodes, seed=args.seed)
        result = RunResult(str(root), config.task, config.algo, config.seed,
                           int(model.num_timesteps), outcome.success_rate, config.setup,
                           config.computation)
        results.append(result)
        print(f"{root}: {with_variant(config.task, config.variant)} {config.algo} seed "
              f"{config.seed}, {result.steps} steps: "
              f"success {100 * outcome.success_rate:.1f} % over "
              f"{counted(args.episodes, 'episode')}")
    table = markdown_table(results)
    notes = seeds_note(results)
    print(f"\nSuccess rate %, mean ± std over seeds, {counted(args.episodes, 'episode')} "
          "per model:\n")
    print(table + "\n" + notes, end="")
    if args.out:
        from franka_composer.atomic_files import folders_made_for, replace_atomically

        with folders_made_for(args.out):
            replace_atomically(args.out, lambda path: path.write_text(table + "\n" + notes))
    return 0
