"""What a run keeps that is small enough to commit while it goes on (`franka-composer keep`,
`sweep --sync`): its config.json, the evaluations a resume keeps and, once it has finished,
outcome.json and policy.pt, copied into KEPT/<run name>. Every run is read and checked whole
before any file is copied, so a damaged one is named and nothing is left half-copied."""

from __future__ import annotations

import dataclasses
import pathlib
import shutil

from franka_composer.training.runs import RunDir, run_finished, write_eval_rows


@dataclasses.dataclass(frozen=True)
class KeptFiles:
    """What `keep_run` copies of `run`, read and checked by `files_to_keep`."""

    run: RunDir
    evaluations: list[dict[str, float]]
    finished: bool


def files_to_keep(run: RunDir, budget: int | None = None) -> KeptFiles:
    """What `run` has kept: its evaluations that a resume keeps, and whether it has finished
    (`run_finished` at `budget`); a damaged config.json, eval.csv or outcome.json is a
    ValueError naming it."""
    run.read_config()  # Copied as it is: checked here.
    return KeptFiles(run, run.kept_evaluations(), run_finished(run, budget))


def keep_run(files: KeptFiles, kept: RunDir) -> None:
    """Copies `files` into `kept`. A run taken on to a larger budget than it finished at
    loses its outcome and policy here until it finishes again."""
    run = files.run
    kept.root.mkdir(parents=True, exist_ok=True)
    shutil.copy(run.config_path, kept.config_path)
    write_eval_rows(kept.eval_csv, files.evaluations)
    for path, copy in ((run.outcome_path, kept.outcome_path),
                       (run.policy_file, kept.policy_file)):
        if files.finished and path.is_file():
            shutil.copy(path, copy)
        elif copy.is_file():
            copy.unlink()


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
