"""Does the contact fidelity the specification asks of every controller hold under each one?
A full press straight down on the object, x and y following it (the press of
`tests/test_contacts.py`, which runs it under every controller), under `mocap`, `osc` and
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

With `--held`, what the guard does not bound: on stack, block 1 grasped, carried 10 cm
above block 2 and pressed down onto it the same way; read as above of block 2, with the
force between the blocks, and whether block 1 is still held at the end. The guard keeps the
hand's own points off surfaces, not those of what it holds.

    python experiments/controller_press.py [--tasks push slide pick_and_place]
        [--controls mocap osc joints] [--seeds 0 1] [--steps 80] [--timing default] [--held]
"""

from __future__ import annotations

import argparse

import numpy as np

from franka_composer.cli.options import add_tasks_argument, episode_seed, positive_int

#: The tasks whose block lies on the floor to be pressed.
PRESSED_TASKS = ("push", "slide", "pick_and_place")

HOVER = 0.04  # m above the object's top, before the press.
STEP = 0.05  # m: a full Cartesian command, the press's depth per step.


def cartesian_action(env, move: np.ndarray, gripper: float = -1.0) -> np.ndarray:
    """The action of `env` (a dm_env of this suite, any controller) that moves the tool
    centre point by `move` (m, each axis clipped to a full step) to first order, the gripper
    (where actuated) at `gripper`: under joints the joint deltas of the Jacobian's
    pseudo-inverse, scaled into [-1, 1] (what a policy moving the hand in joint space
    sends). The contact tests use it too (`tests/conftest.py`)."""
    import mujoco

    physics, control = env.physics, env.task.config.control
    move = np.clip(np.asarray(move, np.float64), -control.max_tcp_step, control.max_tcp_step)
    fingers = [gripper] if control.actuated_gripper else []
    if control.kind != "joints":
        return np.array([*(move / control.max_tcp_step), *fingers], np.float32)
    model, data = physics.model.ptr, physics.data.ptr
    jacobian = np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacobian, None,
                      physics.bind(env.task.panda.tcp_site).element_id)
    arm = jacobian[:, physics.bind(env.task.panda.joints).dofadr]
    deltas = arm.T @ np.linalg.solve(arm @ arm.T + 1e-6 * np.eye(3), move)
    deltas /= control.max_joint_step
    return np.array([*(deltas / max(1.0, np.abs(deltas).max())), *fingers], np.float32)


def solved_contacts(env, solved) -> list:
    """(contact, normal force N) of each active contact of the env's present state, solved
    on `solved` (an MjData of its model): a step leaves the constraint forces of its last
    substep's contacts, stale read through the present ones, and uninitialised where the
    contacts changed."""
    import mujoco

    model = env.physics.model.ptr
    mujoco.mj_copyData(solved, model, env.physics.data.ptr)
    mujoco.mj_forward(model, solved)
    wrench, found = np.zeros(6), []
    for index in range(solved.ncon):
        contact = solved.contact[index]
        if contact.efc_address >= 0:
            mujoco.mj_contactForce(model, solved, index, wrench)
            found.append((contact, float(wrench[0])))
    return found


def move_tcp_to(env, timestep, target, gripper: float = -1.0, steps: int = 80,
                tolerance: float = 0.001):
    """Drives the tool centre point to `target` (`cartesian_action`, the gripper at
    `gripper`) for at most `steps` steps, until within `tolerance` (m); returns the last
    timestep. The physical tests use it too (`tests/conftest.py`)."""
    for _ in range(steps):
        offset = np.asarray(target) - timestep.observation["panda/tcp_position"]
        if np.linalg.norm(offset) < tolerance:
            break
        timestep = env.step(cartesian_action(env, offset, gripper))
    return timestep


class _Readings:
    """What a press does to one object (module docstring), step by step."""

    def __init__(self, start: np.ndarray, timestep, name: str) -> None:
        """`start`: where the object rested; `timestep`: the last before the press."""
        self._name, self.start = name, np.array(start)
        self.lowest = self.highest = self._position(timestep)[2]
        self.fastest, self.forces, self.into_floor = 0.0, [], 0.0

    def _position(self, timestep) -> np.ndarray:
        return np.asarray(timestep.observation[f"{self._name}/position"])

    def read(self, timestep, force: float) -> None:
        height = self._position(timestep)[2]
        self.lowest, self.highest = min(self.lowest, height), max(self.highest, height)
        self.fastest = max(self.fastest, float(np.linalg.norm(
            timestep.observation[f"{self._name}/linear_velocity"])))
        self.forces.append(force)

    def summary(self, timestep) -> dict:
        resting = self.start[2]
        moved = np.linalg.norm(self._position(timestep)[:2] - self.start[:2])
        return {"sank_mm": 1000 * (resting - self.lowest),
                "rose_mm": 1000 * (self.highest - resting), "fastest_m_s": self.fastest,
                "moved_mm": 1000 * float(moved), "peak_force_n": max(self.forces),
                "steady_force_n": float(np.median(self.forces[-10:])),
                "into_floor_mm": 1000 * self.into_floor}


def press(task: str, control: str, seed: int, steps: int, timing: str) -> dict:
    """One trial's readings (module docstring): the force is the robot's on the world."""
    import mujoco

    import franka_composer

    env = franka_composer.load(task, seed=seed, control=control, terminate_on_success=False,
                               time_limit=None, timing=timing)
    timestep = env.reset()
    physics, panda, prop = env.physics, env.task.panda, env.task.prop
    model = physics.model.ptr
    name = prop.mjcf_model.model
    start = np.array(timestep.observation[f"{name}/position"])
    timestep = move_tcp_to(env, timestep, start + [0.0, 0.0, prop.resting_height + HOVER], -1.0)
    robot = set(physics.bind(panda.mjcf_model.find_all("body")).element_id)
    floor = physics.bind(env.task.root_entity.floor).element_id
    solved = mujoco.MjData(model)
    readings = _Readings(start, timestep, name)
    for _ in range(steps):
        offset = (np.asarray(timestep.observation[f"{name}/position"])
                  - timestep.observation["panda/tcp_position"])
        timestep = env.step(cartesian_action(env, np.array([*offset[:2], -STEP])))
        force = 0.0
        for contact, normal in solved_contacts(env, solved):
            if (model.geom_bodyid[contact.geom1] in robot) != (
                    model.geom_bodyid[contact.geom2] in robot):
                force += normal
                if floor in (contact.geom1, contact.geom2):
                    readings.into_floor = max(readings.into_floor, -contact.dist)
        readings.read(timestep, force)
    return readings.summary(timestep)


def held_press(control: str, seed: int, steps: int, timing: str) -> dict:
    """Stack: block 1 grasped and carried 10 cm above block 2, then pressed down onto it
    (full -z, x and y following block 2) for `steps` steps; block 2's readings as `press`
    reads its object's, the force the one between the blocks, and whether block 1 is still
    held (its height within 2 cm of the tool centre point's) at the end."""
    import mujoco

    import franka_composer

    env = franka_composer.load("stack", seed=seed, control=control, terminate_on_success=False,
                               time_limit=None, timing=timing)
    timestep = env.reset()
    upper, lower = env.task.props
    first = np.asarray(timestep.observation["block1/position"]).copy()
    second = np.asarray(timestep.observation["block2/position"]).copy()
    timestep = move_tcp_to(env, timestep, first + [0, 0, 0.08], 1.0, tolerance=0.002)
    timestep = move_tcp_to(env, timestep, first, 1.0, tolerance=0.002)
    for _ in range(6):
        timestep = env.step(cartesian_action(env, np.zeros(3), -1.0))
    timestep = move_tcp_to(env, timestep, first + [0, 0, 0.10], -1.0, tolerance=0.002)
    timestep = move_tcp_to(env, timestep, second + [0, 0, 0.10], -1.0, tolerance=0.002)
    physics = env.physics
    upper_geoms = set(physics.bind(upper.mjcf_model.find_all("geom")).element_id)
    lower_geoms = set(physics.bind(lower.mjcf_model.find_all("geom")).element_id)
    solved = mujoco.MjData(physics.model.ptr)
    readings = _Readings(second, timestep, "block2")
    for _ in range(steps):
        offset = second - timestep.observation["panda/tcp_position"]
        timestep = env.step(cartesian_action(env, np.array([*offset[:2], -STEP]), -1.0))
        readings.read(timestep, sum(
            normal for contact, normal in solved_contacts(env, solved)
            if {contact.geom1, contact.geom2} & upper_geoms
            and {contact.geom1, contact.geom2} & lower_geoms))
    held = abs(timestep.observation["block1/position"][2]
               - timestep.observation["panda/tcp_position"][2]) < 0.02
    return dict(readings.summary(timestep), held=bool(held))


def main(argv: list[str] | None = None) -> int:
    from franka_composer.controllers import CONTROLS
    from franka_composer.tasks.options import TIMINGS

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_tasks_argument(parser, PRESSED_TASKS, f"tasks to press (of {', '.join(PRESSED_TASKS)})")
    parser.add_argument("--controls", nargs="+", default=list(CONTROLS), choices=CONTROLS)
    parser.add_argument("--seeds", type=episode_seed, nargs="+", default=[0, 1])
    parser.add_argument("--steps", type=positive_int, default=80,
                        help="steps of the press (default: 80, the contact tests')")
    parser.add_argument("--timing", default="default", choices=tuple(TIMINGS))
    parser.add_argument("--held", action="store_true",
                        help="press a held block onto another instead (stack; --tasks unread)")
    args = parser.parse_args(argv)
    others = [task for task in args.tasks if task not in PRESSED_TASKS]
    if others:
        parser.error(f"--tasks: {', '.join(others)} not pressed here; tasks pressed: "
                     f"{', '.join(PRESSED_TASKS)}")
    if args.held:
        return _print_held(args)
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


def _print_held(args) -> int:
    print("| control | seed | lower block sank (mm) | rose (mm) | top speed (m/s) | moved (mm) "
          "| peak force between the blocks (N) | steady (N) | still held |")
    print("|---|---|---|---|---|---|---|---|---|")
    for control in args.controls:
        for seed in args.seeds:
            r = held_press(control, seed, args.steps, args.timing)
            print(f"| {control} | {seed} | {r['sank_mm']:.2f} | {r['rose_mm']:.2f} | "
                  f"{r['fastest_m_s']:.3f} | {r['moved_mm']:.1f} | {r['peak_force_n']:,.0f} | "
                  f"{r['steady_force_n']:,.0f} | {'yes' if r['held'] else 'no'} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
