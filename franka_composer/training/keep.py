"""What a run keeps that is small enough to commit while it goes on (`franka-composer keep`,
`sweep --sync`): its config.json, the evaluations a resume keeps and, once it has finished,
outcome.json and policy.pt, copied into KEPT/<run name>. Every run is read and checked whole
before any file is copied, so a damaged one is named and nothing is left half-copied; and
what is kept already is only ever extended by the same run, never cut back or replaced (a
run begun again from zero on a machine that lost it is kept once it has passed its kept
evaluations, which it retraces)."""

from __future__ import annotations

import dataclasses
import pathlib
import shutil

from franka_composer.atomic_files import replace_atomically
from franka_composer.training.runs import (EvalRow, RunDir, is_run, read_eval_rows,
                                           run_finished, runs_holding, write_eval_rows)


@dataclasses.dataclass(frozen=True)
class KeptFiles:
    """What `keep_run` copies of `run`, read and checked by `files_to_keep`."""

    run: RunDir
    evaluations: list[EvalRow]
    finished: bool


def files_to_keep(run: RunDir, kept: RunDir, budget: int | None = None) -> KeptFiles:
    """What `run` has kept, to be copied into `kept`: its evaluations that a resume keeps,
    and whether it has finished (`run_finished` at `budget`). A damaged config.json,
    eval.csv or outcome.json is a ValueError naming it, and so is a copy in `kept` that
    keeping `run` would replace or cut back (`check_extends`), a policy file of a finished
    run that is not one (`read_policy_file`: it would replace a whole one kept), and a
    folder where a model file belongs (`check_no_folders`: the policy would be left out)."""
    from franka_composer.training.policy_file import check_no_folders, read_policy_file

    run.check_config_checkpointed()  # Else a hand edit is kept, and plays as another run.
    check_no_folders(run)
    files = KeptFiles(run, run.kept_evaluations(), run_finished(run, budget))
    check_extends(files, kept)
    if files.finished and run.policy_file.is_file():
        read_policy_file(run.read_config(), run.policy_file)
    return files


def check_extends(files: KeptFiles, kept: RunDir) -> None:
    """A ValueError unless `files` only extend what `kept` holds (a folder, or nothing yet):
    the same run's settings (its budget aside), and every kept evaluation among the run's,
    with the same success rate and mean reward (its wall time aside: a run begun again from
    zero retraces them bit for bit on the same machine, at its own pace)."""
    config = files.run.read_config()  # Copied as it is: checked here.
    if kept.root.exists() and not kept.root.is_dir():
        raise ValueError(f"{kept.root} is a file, not a folder: move it away to keep "
                         f"{files.run.root} there")
    if kept.config_path.is_file():
        differences = config.differences(kept.read_config())
        if differences:
            raise ValueError(f"{kept.config_path} is another run's than {files.run.root}'s "
                             f"({'; '.join(differences)}): move {kept.root} away to keep "
                             "this run there")
    kept_rows = read_eval_rows(kept.eval_csv)
    left = departure(kept_rows, files.evaluations)
    if left:
        row, mine = left
        theirs = ("no evaluation" if mine is None else
                  f"success rate {mine['success_rate']:g}, mean reward "
                  f"{mine['mean_reward']:g}")
        raise ValueError(
            f"{kept.eval_csv} is not {files.run.root}'s evaluations: at step {row['steps']:,} "
            f"it holds success rate {row['success_rate']:g}, mean reward "
            f"{row['mean_reward']:g}, and the run {theirs}. Move {kept.root} away to keep "
            "this run there")
    reached = max((row["steps"] for row in files.evaluations), default=None)
    beyond = [row["steps"] for row in kept_rows if reached is None or row["steps"] > reached]
    if beyond:
        ends = "it has kept none" if reached is None else f"its own end at step {reached:,}"
        raise ValueError(
            f"{kept.eval_csv} holds evaluations from step {beyond[0]:,} on, which "
            f"{files.run.root} has not reached ({ends}; begun again from zero?): keeping "
            f"it now would drop them. Keep it once it has passed them, or move "
            f"{kept.root} away")


def departure(kept: list[EvalRow], ours: list[EvalRow]) -> tuple[EvalRow, EvalRow | None] | None:
    """Where the evaluations `ours` leave those `kept` (eval.csv rows), up to the last of
    ours: the first kept one they do not hold with the same success rate and mean reward,
    and theirs at its step (None: no evaluation there); None where they retrace them."""
    by_step = {row["steps"]: row for row in ours}
    reached = max(by_step, default=-1)
    for row in kept:
        if row["steps"] > reached:
            break
        mine = by_step.get(row["steps"])
        if mine is None or (mine["success_rate"], mine["mean_reward"]) != (
                row["success_rate"], row["mean_reward"]):
            return row, mine
    return None


def keep_run(files: KeptFiles, kept: RunDir) -> None:
    """Copies `files` into `kept`. A run taken on to a larger budget than it finished at
    loses its outcome and policy here until it finishes again; a finished one that has
    lost a file keeps the copy kept of it (the same run's, `check_extends`)."""
    run = files.run
    kept.root.mkdir(parents=True, exist_ok=True)
    _copy(run.config_path, kept.config_path)
    write_eval_rows(kept.eval_csv, files.evaluations)
    for path, copy in ((run.outcome_path, kept.outcome_path),
                       (run.policy_file, kept.policy_file)):
        if files.finished and path.is_file():
            _copy(path, copy)
        elif not files.finished and copy.is_file():
            copy.unlink()


def _copy(path: pathlib.Path, copy: pathlib.Path) -> None:
    """`path` copied to `copy` whole or not at all (a committed file is never half one)."""
    replace_atomically(copy, lambda partial: shutil.copy(path, partial))


def check_kept_apart(roots, kept: pathlib.Path, option: str) -> None:
    """A ValueError where keeping the runs at `roots` into `kept`/<run name> (the folder
    `option` names) would copy a run onto itself or into itself."""
    inside = kept.resolve()
    for root in (pathlib.Path(given).resolve() for given in roots):
        if (kept / root.name).resolve() == root:
            raise ValueError(f"{root} is the run itself: give {option} a folder other than "
                             "the one holding the runs")
        if inside == root:
            raise ValueError(f"{option} {kept} is the run itself: give a folder outside the "
                             "runs")
        if root in inside.parents:
            raise ValueError(f"{option} {kept} is inside the run {root}: give a folder "
                             "outside the runs")
    folder = inside if is_run(inside) else next(runs_holding(inside), None)
    if folder is not None:  # Another run, kept or training.
        raise ValueError(f"{option} {kept} is {'' if folder == inside else 'inside '}"
                         f"the run {folder}: give a folder outside the runs")
