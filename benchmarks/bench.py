"""Every speed and memory figure of docs/guide/benchmarks.md, as a table and a JSON file.

    python benchmarks/bench.py                    # every task (make bench)
    python benchmarks/bench.py --tasks push --steps 200 --skip-render --vector-workers

Each task is measured in a fresh process (`benchmarks/measure.py`) with BLAS
threads set to 1 before NumPy loads, so peak RSS and cold start are per task and no run
inherits another's caches. Compare figures as ratios taken in the same run: the machine may
be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time
from importlib import metadata

from franka_composer.adapters.registration import env_id
from franka_composer.cli.options import add_tasks_argument, output_file, positive_int
from franka_composer.tasks import ALL_TASKS

#: Issue 5's targets: (JSON path within a task's result, comparison, bound).
TARGETS = {
    "random steps/s": (("random", "steps_per_s_resets_included"), ">=", 1000.0),
    "expert steps/s": (("expert", "steps_per_s_resets_included"), ">=", 600.0),
    "random overhead vs floor": (("random", "overhead_ratio"), "<=", 1.3),
    "expert overhead vs floor": (("expert", "overhead_ratio"), "<=", 1.3),
    "reset ms (median)": (("reset_ms_median",), "<=", 1.0),
    "compute_reward(1024) us": (("compute_reward_1024_us",), "<=", 50.0),
    "peak RSS MB": (("peak_rss_mb",), "<=", 200.0),
    "cold start s": (("cold_start", "median_s"), "<=", 1.5),
    "MB per extra env, not rendering": (("memory", "none", "per_additional_env_mb"), "<=", 40.0),
}
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
#: The per-task measurement, run in a fresh process per task.
MEASURE = pathlib.Path(__file__).with_name("measure.py")
_COLD_START = """\
import time
start = time.perf_counter()
import resource
import gymnasium as gym
import franka_composer
env = gym.make({env_id!r})
env.reset(seed=0)
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, ALL_TASKS,
                       f"tasks to measure (default: all of {','.join(ALL_TASKS)})")
    parser.add_argument("--steps", type=positive_int, default=3000,
                        help="env steps per measured run: random actions, then the scripted "
                        "expert, each replayed on the bare-MuJoCo floor (default: 3000)")
    parser.add_argument("--reset-samples", type=positive_int, default=50,
                        help="resets timed for the median reset time (default: 50)")
    parser.add_argument("--render-frames", type=positive_int, default=20,
                        help="480x480 rgb_array frames timed per task (default: 20)")
    parser.add_argument("--skip-render", action="store_true",
                        help="do not time rendering (no GL context is created)")
    parser.add_argument("--cold-start-samples", type=positive_int, default=3,
                        help="fresh processes timed for import + make + first reset; the "
                        "median is reported (default: 3)")
    parser.add_argument("--vector-workers", type=positive_int, nargs="*", default=[1, 2],
                        metavar="N", help="AsyncVectorEnv worker counts to measure, random "
                        "actions, --steps env steps in all (default: 1 2; none: skip)")
    parser.add_argument("--memory-envs", type=positive_int, default=10,
                        help="envs made after the first, in a fresh process, to measure the "
                        "resident memory each adds, without and with rendering (default 10)")
    parser.add_argument("--out", type=output_file, default="results.json",
                        help="JSON file for every figure, checked before anything is "
                             "measured (default: results.json)")
    return parser


def run(args: argparse.Namespace) -> int:
    results = {"command": " ".join(["python", "benchmarks/bench.py"] + sys.argv[1:]),
               "machine": machine(), "versions": versions(),
               "settings": {"steps": args.steps, "reset_samples": args.reset_samples,
                            "render_frames": 0 if args.skip_render else args.render_frames},
               "tasks": {}}
    for task in args.tasks:
        result = _measure_in_fresh_process(
            ["--task", task, "--steps", str(args.steps), "--reset-samples",
             str(args.reset_samples), "--render-frames",
             "0" if args.skip_render else str(args.render_frames)])
        result["cold_start"] = cold_start(env_id(task, "sparse"), args.cold_start_samples)
        result["vector_steps_per_s"] = {
            str(workers): _measure_in_fresh_process(
                ["--task", task, "--steps", str(args.steps),
                 "--vector-workers", str(workers)])["steps_per_s"]
            for workers in args.vector_workers}
        result["memory"] = {
            mode: _measure_in_fresh_process(
                ["--task", task, "--steps", "1", "--memory-envs", str(args.memory_envs)]
                + (["--render-mode", mode] if mode != "none" else []))
            for mode in ("none", "rgb_array")}
        result["targets"] = check_targets(result)
        results["tasks"][task] = result
    results["machine"]["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w") as file:
        json.dump(results, file, indent=2)
    print(format_table(results))
    print(f"\nwrote {args.out}")
    return 0


def child_environment(**overrides: str) -> dict:
    """This process's environment with BLAS threads set to 1, for a measuring process."""
    env = dict(os.environ)
    env.update({name: "1" for name in _THREAD_VARIABLES})
    env.update(overrides)
    return env


def _measure_in_fresh_process(arguments: list[str]) -> dict:
    completed = subprocess.run(
        [sys.executable, str(MEASURE), *arguments],
        capture_output=True, text=True, env=child_environment(), check=False)
    if completed.returncode != 0:
        raise RuntimeError(f"benchmark process {arguments} failed:\n{completed.stderr}")
    return json.loads(completed.stdout.strip().splitlines()[-1])


def _cold_process(name: str, **environment: str) -> tuple[float, float, float]:
    """(import + make + first reset seconds, whole process seconds, peak RSS MB)."""
    start = time.perf_counter()
    completed = subprocess.run([sys.executable, "-c", _COLD_START.format(env_id=name)],
                               capture_output=True, text=True,
                               env=child_environment(**environment), check=False)
    whole = time.perf_counter() - start
    if completed.returncode != 0:
        raise RuntimeError(f"cold-start process for {name} failed:\n{completed.stderr}")
    inside, rss = map(float, completed.stdout.strip().splitlines()[-1].split())
    return inside, whole, rss


def cold_start(name: str, samples: int) -> dict:
    """Import + `gym.make` + first reset in fresh processes: the median of `samples` as
    users run it (compiled-model cache warm: the task process has filled it), the whole
    process's wall time (interpreter start included), one run compiling the model
    (cache off), and one with `MUJOCO_GL=disable`, which spares a process that never
    renders dm_control's EGL backend (`headless_gl`)."""
    runs = [_cold_process(name) for _ in range(samples)]
    uncached = _cold_process(name, FRANKA_COMPOSER_CACHE="off")
    no_gl = _cold_process(name, MUJOCO_GL="disable")
    return {"median_s": statistics.median(run[0] for run in runs),
            "process_median_s": statistics.median(run[1] for run in runs),
            "samples_s": [run[0] for run in runs],
            "peak_rss_mb": max(run[2] for run in runs),
            "uncached_s": uncached[0], "uncached_peak_rss_mb": uncached[2],
            "gl_disabled_s": no_gl[0], "gl_disabled_peak_rss_mb": no_gl[2]}


def check_targets(result: dict) -> dict:
    """Each target's value and whether it is met (None where it was not measured)."""
    checks = {}
    for label, (path, comparison, bound) in TARGETS.items():
        value = result
        for key in path:
            value = value.get(key) if isinstance(value, dict) else None
        met = None if value is None else (value >= bound if comparison == ">=" else value <= bound)
        checks[label] = {"value": value, "target": f"{comparison} {bound:g}", "met": met}
    return checks


def machine() -> dict:
    model = "unknown"
    try:
        with open("/proc/cpuinfo") as file:
            model = next(line.split(":", 1)[1].strip() for line in file
                         if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"cpu_model": model, "nproc": os.cpu_count(), "platform": platform.platform(),
            "load_average_before": os.getloadavg()}


def versions() -> dict:
    found = {"python": platform.python_version()}
    for package in ("franka-composer", "mujoco", "dm-control", "gymnasium", "numpy"):
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = None
    return found


def _number(value, digits: int = 0) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def format_table(results: dict) -> str:
    """The stdout report: one row per task, then each target's verdict."""
    workers = next(iter(results["tasks"].values()), {}).get("vector_steps_per_s", {})
    header = ("| task | random steps/s (with / without resets) | floor | ratio "
              "| expert steps/s (with / without) | floor | ratio | reset ms | reward(1024) us "
              "| RSS MB | MB/env (no render / render) | cold s | render ms | vector "
              f"{' / '.join(workers) or '-'} workers |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    for task, result in results["tasks"].items():
        cells = [task]
        for run_name in ("random", "expert"):
            run = result[run_name]
            if "skipped" in run:
                cells += [f"skipped: {run['skipped']}", "-", "-"]
                continue
            cells += [f"{_number(run['steps_per_s_resets_included'])} / "
                      f"{_number(run['steps_per_s_resets_excluded'])}",
                      _number(run["floor_steps_per_s"]), _number(run["overhead_ratio"], 2)]
        render = result.get("render", {}).get("ms_per_frame")
        vector = " / ".join(_number(v) for v in result["vector_steps_per_s"].values()) or "-"
        memory = " / ".join(_number(result["memory"][mode]["per_additional_env_mb"], 1)
                            for mode in ("none", "rgb_array"))
        cells += [_number(result["reset_ms_median"], 2),
                  _number(result["compute_reward_1024_us"], 1),
                  _number(result["peak_rss_mb"]), memory,
                  _number(result["cold_start"]["median_s"], 2),
                  _number(render, 1), vector]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    for task, result in results["tasks"].items():
        missed = [f"{label} ({_number(check['value'], 2)}, target {check['target']})"
                  for label, check in result["targets"].items() if check["met"] is False]
        lines.append(f"{task}: " + ("all measured targets met" if not missed
                                     else "missed: " + "; ".join(missed)))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
