"""How fast does a hand carrying a block go down, and what does setting it down press? The
scene of `tests/test_contacts.py`'s carried-block test: on stack, block 1 grasped with the
tool centre point 12 mm below the block's centre (the block's lower part between the
fingertips, its top near the palm), lifted 12 cm, then `--steps` full downward commands
(the gripper closed; under joints, the joint deltas of the same Cartesian step), with the
surface guard as stack v0 had it (`guard_ignores_carried=False`: a carried block a surface
beneath the hand) and as v1 has it (part of the hand).

Read per trial: where the block sat in the grip (its centre above the tool centre point,
mm), the hand's descent per step over the first three steps (mm, their median), the tool
centre point's height at the end (mm; the fingertips reach 7.3 mm below it), how far the
block slid up in the grip by the end (mm), and the peak normal force between the block and
the floor (N, solved for the state after each step; the arm's own press is bounded to
114-136 N, docs/guide/physics.md).

    python experiments/carried_descent.py [--controls mocap osc joints] [--seeds 0 1 2]
        [--steps 12]
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

from franka_composer.cli.options import episode_seed, positive_int

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from controller_press import cartesian_action, move_tcp_to, solved_contacts  # noqa: E402

GRASP_BELOW_CENTRE = 0.012  # m: the tool centre point below the block's centre.
LIFT = 0.12  # m above the block's resting place.


def trial(control: str, seed: int, ignores: bool, steps: int) -> dict:
    """One carried descent's readings (module docstring)."""
    import mujoco

    import franka_composer

    env = franka_composer.load("stack", seed=seed, control=control, terminate_on_success=False,
                               time_limit=None, guard_ignores_carried=ignores)
    timestep = env.reset()
    block = np.asarray(timestep.observation["block1/position"]).copy()
    timestep = move_tcp_to(env, timestep, block + [0, 0, 0.08], 1.0, steps=30, tolerance=0.004)
    timestep = move_tcp_to(env, timestep, block - [0, 0, GRASP_BELOW_CENTRE], 1.0, steps=30,
                           tolerance=0.004)
    for _ in range(5):
        timestep = env.step(cartesian_action(env, np.zeros(3), -1.0))
    timestep = move_tcp_to(env, timestep, block + [0, 0, LIFT], -1.0, steps=30,
                           tolerance=0.004)

    def seat(step) -> float:  # The block's centre above the tool centre point (m).
        return float(step.observation["block1/position"][2]
                     - step.observation["panda/tcp_position"][2])

    physics = env.physics
    block_geoms = set(physics.bind(env.task.props[0].mjcf_model.find_all("geom")).element_id)
    floor = int(physics.bind(env.task.root_entity.floor).element_id)
    solved = mujoco.MjData(physics.model.ptr)
    start_seat, heights, forces = seat(timestep), [], []
    heights.append(float(timestep.observation["panda/tcp_position"][2]))
    for _ in range(steps):
        timestep = env.step(cartesian_action(env, np.array([0.0, 0.0, -0.05]), -1.0))
        heights.append(float(timestep.observation["panda/tcp_position"][2]))
        forces.append(sum(normal for contact, normal in solved_contacts(env, solved)
                          if {contact.geom1, contact.geom2} & block_geoms
                          and floor in (contact.geom1, contact.geom2)))
    return {"seat_mm": 1000 * start_seat,
            "descent_mm": 1000 * float(np.median(-np.diff(heights[:4]))),
            "final_tcp_mm": 1000 * heights[-1],
            "slid_mm": 1000 * (seat(timestep) - start_seat),
            "peak_force_n": max(forces)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--controls", nargs="+", default=["mocap", "osc", "joints"],
                        choices=("mocap", "osc", "joints"))
    parser.add_argument("--seeds", nargs="+", type=episode_seed, default=[0, 1, 2])
    parser.add_argument("--steps", type=positive_int, default=12)
    args = parser.parse_args(argv)
    print("| control | seed | guard | block's centre above the TCP (mm) | descent per step "
          "(mm) | TCP height at the end (mm) | block slid up in the grip (mm) | peak "
          "block-floor force (N) |")
    print("|---|---|---|---|---|---|---|---|")
    for control in args.controls:
        for seed in args.seeds:
            for ignores, guard in ((False, "v0"), (True, "v1")):
                r = trial(control, seed, ignores, args.steps)
                print(f"| {control} | {seed} | {guard} | {r['seat_mm']:.1f} | "
                      f"{r['descent_mm']:.1f} | {r['final_tcp_mm']:.1f} | {r['slid_mm']:.1f} | "
                      f"{r['peak_force_n']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
