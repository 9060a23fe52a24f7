"""What does the 2 ms physics step cost in accuracy? (The paper's open question: "a smaller
timestep has not been tested in MuJoCo considering the computing resources".)

    nice -n 5 python benchmarks/timestep_study.py --episodes 20 --out results/timestep-study

Runs every task's scripted expert, and uniformly random actions, at 2, 1 and 0.5 ms physics
steps from the same seeds (episode i: seed i; random actions drawn from seed i too), the
control period 0.05 s throughout (25, 50, 100 substeps), mocap control, sparse reward. For
each (task, policy, step) it reports the success rate; the object's final position (both
blocks for stack, the tool centre point for reach) against the same episode at 0.5 ms (mean
and largest distance over episodes); the deepest contact penetration and the largest
contact normal force seen at any physics substep (any pair of geoms); and env steps per
CPU second (the process's CPU time inside `env.step`, less the measuring: on a shared
machine wall time measures the neighbours). Writes `timestep-study.csv` and
`timestep-study.md` into `--out`.

Forces are read consistently: after each substep the data is copied and `mj_forward` solves
the contacts of that state (the step itself leaves the constraint forces of the previous
contacts). The random-action episodes are open loop (the same actions at every step size),
so their final-position differences are the integration's alone; the experts close the loop,
so theirs also show how far a small difference grows.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import pathlib
import time

import mujoco
import numpy as np

from franka_composer.cli.options import add_tasks_argument, output_folder

#: Physics steps compared (s); the last is the reference the others are measured against.
TIMESTEPS = (0.002, 0.001, 0.0005)
POLICIES = ("expert", "random")
COLUMNS = ("task", "policy", "timestep_ms", "substeps", "episodes", "success_rate",
           "final_position_diff_mean_mm", "final_position_diff_max_mm",
           "penetration_peak_mm", "penetration_peak_bodies", "contact_force_peak_n",
           "contact_force_peak_bodies", "steps_per_cpu_s")


class ContactPeaks:
    """The deepest penetration (m) and largest contact normal force (N) over every physics
    substep, read through Composer's public `after_substep` hook; `seconds` is the time the
    reading itself took (CPU seconds, taken off the speed)."""

    def __init__(self, composer_env) -> None:
        self._scratch = None
        self.penetration = self.force = self.seconds = 0.0
        #: The bodies in contact at each peak ("body1/body2").
        self.penetration_pair = self.force_pair = ""
        composer_env.add_extra_hook("after_substep", self._read)

    def _read(self, physics, random_state) -> None:
        start = time.process_time()
        model, data = physics.model.ptr, physics.data.ptr
        if self._scratch is None:
            if model.opt.cone != mujoco.mjtCone.mjCONE_ELLIPTIC:
                raise ValueError("the study reads normal forces of elliptic cones only")
            self._scratch = mujoco.MjData(model)
        mujoco.mj_copyData(self._scratch, model, data)
        mujoco.mj_forward(model, self._scratch)
        contacts = self._scratch.contact
        if self._scratch.ncon:
            deepest = int(np.argmin(contacts.dist))
            if -contacts.dist[deepest] > self.penetration:
                self.penetration = float(-contacts.dist[deepest])
                self.penetration_pair = _pair(model, contacts, deepest)
            forces = np.where(contacts.efc_address >= 0,  # An elliptic cone's first row
                              self._scratch.efc_force[contacts.efc_address], 0.0)  # is normal.
            strongest = int(np.argmax(forces))
            if forces[strongest] > self.force:
                self.force = float(forces[strongest])
                self.force_pair = _pair(model, contacts, strongest)
        self.seconds += time.process_time() - start


def _pair(model, contacts, index: int) -> str:
    """The two bodies of contact `index`, "body1/body2"."""
    return "/".join(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY,
                                      model.geom_bodyid[contacts.geom[index][k]])
                    for k in range(2))


def final_positions(task, physics) -> np.ndarray:
    """What the task moves, where it ended (m, world frame): every object's centre, or the
    tool centre point for reach."""
    if task.props:
        return np.concatenate([physics.bind(prop.geom).xpos for prop in task.props])
    return np.array(physics.bind(task.panda.tcp_site).xpos)


def run_cell(task_name: str, policy: str, timestep: float, episodes: int) -> dict:
    """Runs `episodes` seeded episodes; returns the cell's figures and its final positions."""
    import gymnasium as gym

    from franka_composer.adapters.registration import env_id
    from franka_composer.policies import make_expert
    from franka_composer.tasks import TASK_CONFIGS

    physics = dataclasses.replace(TASK_CONFIGS[task_name].physics, timestep=timestep)
    env = gym.make(env_id(task_name, "sparse"), physics=physics)
    unwrapped = env.unwrapped
    peaks = ContactPeaks(unwrapped.composer_env)
    expert = make_expert(env) if policy == "expert" else None
    successes, finals, steps, seconds = [], [], 0, 0.0
    for seed in range(episodes):
        obs, _ = env.reset(seed=seed)
        actions = np.random.default_rng(seed)
        if expert is not None:
            expert.reset()
        done = False
        while not done:
            action = (expert(obs) if expert is not None else
                      actions.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            start = time.process_time()
            obs, _, terminated, truncated, info = env.step(action)
            seconds += time.process_time() - start
            steps += 1
            done = terminated or truncated
        successes.append(bool(info["is_success"]))
        finals.append(final_positions(unwrapped.task, unwrapped.composer_env.physics))
    env.close()
    return {"task": task_name, "policy": policy, "timestep_ms": timestep * 1000,
            "substeps": round(unwrapped.task.config.control_timestep / timestep),
            "episodes": episodes, "success_rate": float(np.mean(successes)),
            "penetration_peak_mm": peaks.penetration * 1000,
            "contact_force_peak_n": peaks.force,
            "penetration_peak_bodies": peaks.penetration_pair,
            "contact_force_peak_bodies": peaks.force_pair,
            "steps_per_cpu_s": steps / (seconds - peaks.seconds), "finals": np.array(finals)}


def final_differences(cells: list[dict]) -> None:
    """Adds to each cell its final positions' distance (mm; the largest over a task's
    objects) from the same episodes at the finest step."""
    finest = {(c["task"], c["policy"]): c["finals"] for c in cells
              if c["timestep_ms"] == min(TIMESTEPS) * 1000}
    for cell in cells:
        difference = cell["finals"] - finest[cell["task"], cell["policy"]]
        per_episode = np.linalg.norm(difference.reshape(len(difference), -1, 3),
                                     axis=2).max(axis=1) * 1000
        cell["final_position_diff_mean_mm"] = float(per_episode.mean())
        cell["final_position_diff_max_mm"] = float(per_episode.max())


def write(cells: list[dict], out: pathlib.Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "timestep-study.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(cells)
    header = ("| task | policy | step (ms) | success | final pos. diff. mean / max (mm) | "
              "penetration peak (mm), bodies | contact force peak (N), bodies | "
              "steps per CPU s |")
    lines = [header, "|---|---|---|---|---|---|---|---|"]
    for c in cells:
        lines.append(
            f"| {c['task']} | {c['policy']} | {c['timestep_ms']:g} | "
            f"{c['success_rate']:.0%} | {c['final_position_diff_mean_mm']:.1f} / "
            f"{c['final_position_diff_max_mm']:.1f} | {c['penetration_peak_mm']:.2f} "
            f"{c['penetration_peak_bodies']} | {c['contact_force_peak_n']:.0f} "
            f"{c['contact_force_peak_bodies']} | {c['steps_per_cpu_s']:.0f} |")
    (out / "timestep-study.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    import franka_composer

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=20,
                        help="seeded episodes per task, policy and step (default: 20)")
    add_tasks_argument(parser, franka_composer.ALL_TASKS, "tasks to study (default: all)")
    parser.add_argument("--out", type=output_folder, default="results/timestep-study",
                        help="folder for timestep-study.csv and .md, checked before the "
                             "study runs (default: results/timestep-study)")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    tasks = args.tasks
    cells = []
    for task in tasks:
        for policy in POLICIES:
            for timestep in TIMESTEPS:
                cells.append(run_cell(task, policy, timestep, args.episodes))
                print(task, policy, timestep, f"{cells[-1]['success_rate']:.0%}", flush=True)
    final_differences(cells)
    write(cells, args.out)
    print((args.out / "timestep-study.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
