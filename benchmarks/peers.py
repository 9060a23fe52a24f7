"""Env steps/s of this suite beside Fetch and the paper's reference code, all in one run.

    python benchmarks/peers.py --reference-path DIR [--steps 1000] [--rounds 5] [--out peers.md]

Push, slide and pick-and-place through `gym.make` (default wrappers) under seeded random
actions, resets included, every suite timed by `franka-composer bench`'s loop
(`peer_worker.py`): this suite at its default timing and at the reference code's
(`timing="reference"`: 250 physics steps per env step, as the reference runs), Fetch
(Gymnasium-Robotics: `pip install -c constraints.txt -e ".[peers]"`; skipped, saying so, when
not installed) and the reference code (`panda_mujoco_gym`, not on PyPI: DIR holds a checkout
of its repository, imported from there; skipped, saying so, without --reference-path). Each
suite runs in a process of its own, and the suites take turns (A B C A B C ...) through every
task and round, so a burst of load on the shared machine falls on all alike: each figure is
the median of the rounds, and each ratio is taken within the run.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
from importlib import metadata

import franka_composer
from bench import child_environment, machine, versions
from franka_composer.cli.options import add_tasks_argument, output_file, positive_int
from peer_worker import RESULT_PREFIX, SUITES, TASK_NAMES, reference_path_error

WORKER = pathlib.Path(__file__).with_name("peer_worker.py")
#: Column titles, in the order the suites take turns.
TITLES = {"ours": "this suite", "ours_reference_timing": 'this suite, timing="reference"',
          "fetch": "Fetch", "reference": "reference code"}
#: (numerator, denominator) suites of each ratio column: the same physics per env step in
#: the last (250 steps of 2 ms), 10x less for this suite's default timing and Fetch's.
RATIOS = (("ours", "fetch"), ("ours", "reference"), ("ours_reference_timing", "reference"))


class Worker:
    """A `peer_worker.py` process measuring one suite, answering one request at a time."""

    def __init__(self, suite: str, reference_path: pathlib.Path | None):
        self.suite = suite
        self.stderr = tempfile.TemporaryFile(mode="w+")
        command = [sys.executable, str(WORKER), "--suite", suite]
        if suite == "reference":
            command += ["--reference-path", str(reference_path)]
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=self.stderr, text=True, env=child_environment())
        self.facts = self._answer()

    def _answer(self) -> dict:
        for line in self.process.stdout:
            if line.startswith(RESULT_PREFIX):
                return json.loads(line[len(RESULT_PREFIX):])
        self.process.wait()
        self.stderr.seek(0)
        raise RuntimeError(f"the {self.suite} worker exited ({self.process.returncode}):\n"
                           + self.stderr.read()[-3000:])

    def steps_per_second(self, task: str, steps: int) -> float:
        self.process.stdin.write(f"{task} {steps}\n")
        self.process.stdin.flush()
        return self._answer()["steps_per_s"]

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait()
        self.stderr.close()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, tuple(TASK_NAMES),
                       f"tasks to time (default: the three the peers share, "
                       f"{','.join(TASK_NAMES)})")
    parser.add_argument("--suites", nargs="+", choices=SUITES, default=SUITES,
                        help="suites to time, ours always among them (default: all)")
    parser.add_argument("--reference-path", type=pathlib.Path, metavar="DIR",
                        help="a checkout of the reference code's repository (the folder "
                             "holding panda_mujoco_gym/); without it the reference is skipped")
    # Many short turns rather than a few long ones: a burst of load on a shared machine then
    # spoils one turn of one suite, which the median leaves out.
    parser.add_argument("--steps", type=positive_int, default=1000,
                        help="env steps per measurement, after 100 warm-up steps "
                             "(default: 1000)")
    parser.add_argument("--rounds", type=positive_int, default=5,
                        help="turns each suite takes at each task; the median counts "
                             "(default: 5)")
    parser.add_argument("--out", type=output_file,
                        help="also write the report (markdown) to this file")
    return parser


def check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse what would fail later, before any process starts."""
    unshared = [task for task in args.tasks if task not in TASK_NAMES]
    if unshared:
        parser.error(f"--tasks: the peers have no {', '.join(unshared)}; "
                     f"choose from {', '.join(TASK_NAMES)}")
    if "ours" not in args.suites:
        parser.error("--suites: the ratios are to this suite, so 'ours' must be among them")
    error = reference_path_error(args.reference_path)
    if error:
        parser.error(error)


def skipped_suites(args: argparse.Namespace) -> dict[str, str]:
    """{suite: why it is not measured} for the requested suites that cannot run here."""
    skipped = {}
    if "fetch" in args.suites and importlib.util.find_spec("gymnasium_robotics") is None:
        skipped["fetch"] = ("gymnasium-robotics is not installed "
                            "(pip install -c constraints.txt -e \".[peers]\")")
    if "reference" in args.suites and args.reference_path is None:
        skipped["reference"] = "no --reference-path given"
    return skipped


def measure(args: argparse.Namespace, suites: list[str]) -> tuple[dict, dict]:
    """({suite: {task: [steps/s per round]}}, {suite: the worker's facts}), the suites
    taking turns at each task in each round."""
    workers = [Worker(suite, args.reference_path) for suite in suites]
    rates = {suite: {task: [] for task in args.tasks} for suite in suites}
    try:
        for _ in range(args.rounds):
            for task in args.tasks:
                for worker in workers:
                    rates[worker.suite][task].append(
                        worker.steps_per_second(task, args.steps))
    finally:
        for worker in workers:
            worker.close()
    return rates, {worker.suite: worker.facts for worker in workers}


def format_report(args: argparse.Namespace, rates: dict, facts: dict, skipped: dict,
                  setting: dict) -> str:
    """The markdown report: how the run was taken, then a row per task."""
    suites = list(rates)
    ratios = [(a, b) for a, b in RATIOS if a in rates and b in rates]
    medians = {suite: {task: statistics.median(values) for task, values in per_task.items()}
               for suite, per_task in rates.items()}
    lines = [f"`{setting['command']}`", "",
             f"{setting['date']}; {setting['machine']}; load average "
             f"{setting['load_before']} before, {setting['load_after']} after; "
             f"{setting['versions']}.",
             f"Env steps/s through `gym.make`, seeded random actions, resets included: the "
             f"median (and range) of {args.rounds} rounds of {args.steps} steps, the suites "
             f"taking turns.", ""]
    header = ["task"] + [TITLES[suite] for suite in suites] + [
        f"{TITLES[a]} / {TITLES[b]}" for a, b in ratios]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for task in args.tasks:
        cells = [task] + [f"{medians[suite][task]:.0f} ({min(rates[suite][task]):.0f}–"
                          f"{max(rates[suite][task]):.0f})" for suite in suites]
        cells += [f"{medians[a][task] / medians[b][task]:.2f}" for a, b in ratios]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    for suite in suites:
        ids = ", ".join(facts[suite]["ids"][task] for task in args.tasks)
        lines.append(f"- {TITLES[suite]}: {ids}")
    if any(facts[suite].get("joint_types_as_ints") for suite in suites):
        lines.append("- joint_types_as_ints: Gymnasium-Robotics' joint helpers were given "
                     "mujoco's joint types as ints (`peer_worker.joint_types_as_ints`)")
    lines += [f"- {TITLES[suite]}: skipped, {why}" for suite, why in skipped.items()]
    return "\n".join(lines)


def run(args: argparse.Namespace, argv: list[str]) -> int:
    skipped = skipped_suites(args)
    suites = [suite for suite in SUITES if suite in args.suites and suite not in skipped]
    for suite, why in skipped.items():
        print(f"{TITLES[suite]}: skipped, {why}", file=sys.stderr)
    setting = {"command": " ".join(["python", "benchmarks/peers.py", *argv]),
               "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
               "load_before": _load()}
    rates, facts = measure(args, suites)
    # The package imported here and in the workers, not the version an install recorded.
    found = {**versions(), "franka-composer": franka_composer.__version__}
    if "fetch" in facts or "reference" in facts:
        found["gymnasium-robotics"] = metadata.version("gymnasium-robotics")
    about = machine()
    setting.update(load_after=_load(), machine=f"{about['cpu_model']}, {about['nproc']} CPUs",
                   versions=", ".join(f"{name} {version}" for name, version in found.items()))
    report = format_report(args, rates, facts, skipped, setting)
    print(report)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(report + "\n")
    return 0


def _load() -> str:
    return " ".join(f"{value:.1f}" for value in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser()
    args = parser.parse_args(argv)
    check_arguments(parser, args)
    return run(args, argv)


if __name__ == "__main__":
    sys.exit(main())
