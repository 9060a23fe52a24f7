"""Does the contact fidelity the specification asks of every controller hold under each one?
A full press straight down on the object, x and y following it (the press of
`tests/test_contacts.py`, which runs it under mocap and osc), under `mocap`, `osc` and
`joints`. Under `joints` the press is the joint deltas that move the tool centre point by
the same Cartesian step to first order (the Jacobian's pseudo-inverse, scaled into
[-1, 1]): what a policy pressing straight down in joint space sends.

Each trial: reset with a seed, bring the closed hand 4 cm above the object's top (at most
80 steps), then `--steps` steps of the press. Read after every control step: how far the
object sank below its resting height and rose above it (mm), its top speed (m/s), how far
it moved sideways (mm), the contact force between the robot and the world (N, the sum over
its contacts: the largest, and the median of the last 10 steps), and the fingertips'
deepest penetration of the floor (mm); forces are solved for the state after each step.
The specification's bounds: the object within 2 mm of its resting height and slower than
0.3 m/s, the fingertips at most 2 mm into the floor, the force bounded like a real Panda's
(its joint torques allow 114-136 N straight down).

    python experiments/controller_press.py [--tasks push slide pick_and_place]
        [--controls mocap osc joints] [--seeds 0 1] [--steps 80] [--timing default]
"""

from __future__ import annotations

import argparse

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int

HOVER = 0.04  # m above the object's top, before the press.
STEP = 0.05  # m: a full Cartesian command, the press's depth per step.


def press(task: str, control: str, seed: int, steps: int, timing: str) -> dict:
    """One trial's readings (module docstring)."""
    import mujoco

    import franka_composer

    env = franka_composer.load(task, seed=seed, control=control, terminate_on_success=False,
                               time_limit=None, timing=timing)
    timestep = env.reset()
    physics = env.physics
    model, data = physics.model.ptr, physics.data.ptr
    panda, prop = env.task.panda, env.task.prop
    site = physics.bind(panda.tcp_site).element_id
    dofs = physics.bind(panda.joints).dofadr
    gripper = [-1.0] * (env.action_spec().shape[0] - (7 if control == "joints" else 3))
    name = prop.mjcf_model.model
    jacobian = np.zeros((3, model.nv))

    def action(move: np.ndarray) -> np.ndarray:
        """The action that moves the tool centre point by `move` (m), to first order."""
        if control != "joints":
            return np.array([*np.clip(move / STEP, -1, 1), *gripper], np.float32)
        mujoco.mj_jacSite(model, data, jacobian, None, site)
        arm = jacobian[:, dofs]
        deltas = arm.T @ np.linalg.solve(arm @ arm.T + 1e-6 * np.eye(3), move)
        deltas /= env.task.config.control.max_joint_step
        return np.array([*(deltas / max(1.0, np.abs(deltas).max())), *gripper], np.float32)

    def observed(key: str) -> np.ndarray:
        return np.asarray(timestep.observation[f"{name}/{key}"])

    def tcp() -> np.ndarray:
        return np.asarray(timestep.observation["panda/tcp_position"])

    start = observed("position").copy()
    above = start + [0.0, 0.0, prop.resting_height + HOVER]
    for _ in range(80):
        if np.linalg.norm(above - tcp()) < 0.001:
            break
        timestep = env.step(action(np.clip(above - tcp(), -STEP, STEP)))
    robot = set(physics.bind(panda.mjcf_model.find_all("body")).element_id)
    floor = physics.bind(env.task.root_entity.floor).element_id
    wrench = np.zeros(6)
    # A step leaves the constraint forces of its last substep's contacts: the present
    # contacts are solved again on a copy (their forces read off the step are stale, and
    # uninitialised where the contacts changed).
    solved = mujoco.MjData(model)
    lowest = highest = observed("position")[2]
    fastest, forces, into_floor = 0.0, [], 0.0
    for _ in range(steps):
        position = observed("position")
        timestep = env.step(action(np.clip(
            np.array([position[0] - tcp()[0], position[1] - tcp()[1], -STEP]), -STEP, STEP)))
        height = observed("position")[2]
        lowest, highest = min(lowest, height), max(highest, height)
        fastest = max(fastest, float(np.linalg.norm(observed("linear_velocity"))))
        force = 0.0
        mujoco.mj_copyData(solved, model, data)
        mujoco.mj_forward(model, solved)
        for index in range(solved.ncon):
            contact = solved.contact[index]
            if contact.efc_address < 0:
                continue
            if (model.geom_bodyid[contact.geom1] in robot) != (
                    model.geom_bodyid[contact.geom2] in robot):
                mujoco.mj_contactForce(model, solved, index, wrench)
                force += wrench[0]
                if floor in (contact.geom1, contact.geom2):
                    into_floor = max(into_floor, -contact.dist)
        forces.append(force)
    resting = start[2]
    return {"sank_mm": 1000 * (resting - lowest), "rose_mm": 1000 * (highest - resting),
            "fastest_m_s": fastest,
            "moved_mm": 1000 * float(np.linalg.norm(observed("position")[:2] - start[:2])),
            "peak_force_n": max(forces), "steady_force_n": float(np.median(forces[-10:])),
            "into_floor_mm": 1000 * into_floor}


def main(argv: list[str] | None = None) -> int:
    from franka_composer.controllers import CONTROLS
    from franka_composer.tasks.config import TIMINGS

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=["push", "slide", "pick_and_place"],
                        choices=("push", "slide", "pick_and_place"))
    parser.add_argument("--controls", nargs="+", default=list(CONTROLS), choices=CONTROLS)
    parser.add_argument("--seeds", type=episode_seed, nargs="+", default=[0, 1])
    parser.add_argument("--steps", type=positive_int, default=80,
                        help="steps of the press (default: 80, the contact tests')")
    parser.add_argument("--timing", default="default", choices=tuple(TIMINGS))
    args = parser.parse_args(argv)
    print("| task | control | seed | sank (mm) | rose (mm) | top speed (m/s) | moved (mm) | "
          "peak force (N) | steady force (N) | fingertips into the floor (mm) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for task in args.tasks:
        for control in args.controls:
            for seed in args.seeds:
                r = press(task, control, seed, args.steps, args.timing)
                print(f"| {task} | {control} | {seed} | {r['sank_mm']:.2f} | {r['rose_mm']:.2f}"
                      f" | {r['fastest_m_s']:.3f} | {r['moved_mm']:.1f} | "
                      f"{r['peak_force_n']:,.0f} | {r['steady_force_n']:,.0f} | "
                      f"{r['into_floor_mm']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
