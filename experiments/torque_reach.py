"""How fast the torque-driven Panda can accelerate its hand: the bound behind osc's tracking.

    python experiments/torque_reach.py [TASK]

At the task's starting pose (control="osc"), a linear programme over the joint-torque box
|tau_i| <= limit_i finds, for each direction, the largest acceleration of the tool centre
point along it with no sideways and no rotational acceleration: a = J M^-1 (tau - bias),
bias = gravity + Coriolis (zero at rest). Held for a whole control step from rest, that
acceleration moves the hand a t^2 / 2, the most one step can cover (`controllers/osc.py`).
Needs SciPy (installed with the test extra).
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
from scipy.optimize import linprog

import franka_composer

DIRECTIONS = {"+x": (1, 0, 0), "-y": (0, -1, 0), "-z": (0, 0, -1), "+z": (0, 0, 1)}


def reach(task: str = "push") -> dict[str, tuple[float, float]]:
    """Per direction: (largest acceleration m/s^2, metres covered in one step from rest)."""
    env = franka_composer.load(task, seed=0, control="osc")
    env.reset()
    physics, panda = env.physics, env.task.panda
    model, data = physics.model.ptr, physics.data.ptr
    dofs = np.array(physics.bind(panda.joints).dofadr)
    limits = np.asarray(panda.arm_torque_limits)
    jacobian = np.zeros((6, model.nv))
    site = physics.bind(panda.tcp_site).element_id
    mujoco.mj_jacSite(model, data, jacobian[:3], jacobian[3:], site)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    # Accelerations of the hand per unit torque (the fingers and objects do not move).
    gain = jacobian[:, dofs] @ np.linalg.inv(mass[np.ix_(dofs, dofs)])
    bias = data.qfrc_bias[dofs]
    step = env.control_timestep()
    result = {}
    for name, direction in DIRECTIONS.items():
        axis = np.asarray(direction, dtype=float)
        others = [row for row in np.eye(3) if abs(row @ axis) < 0.5]
        equal = np.vstack([row @ gain[:3] for row in others] + [gain[3:]])
        solution = linprog(-(axis @ gain[:3]), A_eq=equal, b_eq=equal @ bias,
                           bounds=list(zip(-limits, limits)))
        acceleration = float(axis @ gain[:3] @ (solution.x - bias))
        result[name] = (acceleration, acceleration * step ** 2 / 2)
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", nargs="?", default="push", choices=franka_composer.ALL_TASKS,
                        metavar="TASK", help="the task whose starting pose is measured (default: push)")
    task = parser.parse_args(argv).task
    print(f"{task}, osc, starting pose: largest hand acceleration within the torque limits")
    print("| direction | m/s^2 | cm in one 0.05 s step from rest |")
    print("|---|---|---|")
    for name, (acceleration, distance) in reach(task).items():
        print(f"| {name} | {acceleration:.1f} | {distance * 100:.1f} |")


if __name__ == "__main__":
    main()
