"""How hard a policy must squeeze to keep a lifted block, in this suite and in the paper's
reference code: a scripted grasp (open above the block, descend, two full closes), then
4 full lifts and 3 full carries toward the square's centre while the gripper action holds a
constant G; the block is held if it ends 10 cm or more above its start. A learner's early
gripper actions are far from -1; a suite that keeps the block at a weaker squeeze rewards
its first grasps sooner.

    python experiments/grasp_margin.py --reference-path DIR [--episodes 20] [--seed 0]

Runs through Gymnasium only, each suite in a process of its own as
`experiments/random_exploration.py` does (`SUITES`: this suite at its default timing, at
0.5 s per step with the default's stiff weld, at the reference timing; the reference code;
DIR as there), episode i from
`reset(seed=SEED + i)`, the block wherever that reset put it. Episodes do not end on
success here (the scripted moves may pass the goal): this suite's env is made with
`terminate_on_success=False`, the reference code's is stepped past its termination
(`env.unwrapped`). Prints a Markdown table: per G, the episodes whose block was held, and
the median slip, how far the block fell in the hand from the end of the close (mm); then
how the hand moves within a step (`hand_motion`), which sets how hard a lift jerks the block;
then how far off the block's centre the open hand may descend, along x and along y (the
fingers' closing axis), and still grasp and keep it at G = -1 (`OFFSETS`), with the median
height above its target at which the hand stopped coming down (on the block's top where a
finger lands there): the wider that reach, the likelier an exploring learner's first grasps.
"""

from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import random_exploration  # noqa: E402  (experiments/, not a package)

#: Those of `random_exploration.SUITES` compared here.
SUITES = ("ours", "stiff_weld", "ours_reference_timing", "reference")
SQUEEZES = (-1.0, -0.5, -0.3, -0.2, -0.15, -0.12, -0.1, -0.08, -0.05, 0.0)
HELD = 0.10  # m above the block's start at the end of the carry.
#: How far (m) off the block's centre the open hand descends, along x and along y.
OFFSETS = (0.0, 0.005, 0.01, 0.015, 0.02, 0.025, 0.03, 0.035)
RESULT_PREFIX = random_exploration.RESULT_PREFIX


def make_env(suite: str, reference_path: pathlib.Path | None):
    """The unwrapped pick-and-place env of `suite`, not ending on success."""
    options = {} if suite == "reference" else {"terminate_on_success": False}
    return random_exploration.make_env(suite, "pick_and_place", reference_path,
                                       **options).unwrapped


class Script:
    """Steps an env with TCP-targeted moves read from its observation (TCP at 0:3, finger
    width at 6, the block as the achieved goal), the same in both suites."""

    def __init__(self, env):
        self.env = env
        self.obs = None

    def reset(self, seed: int) -> None:
        self.obs, _ = self.env.reset(seed=seed)

    @property
    def tcp(self) -> np.ndarray:
        return self.obs["observation"][:3]

    @property
    def block(self) -> np.ndarray:
        return self.obs["achieved_goal"]

    def step(self, move, gripper: float) -> None:
        action = np.append(np.asarray(move, dtype=np.float64), gripper)
        self.obs = self.env.step(action.astype(self.env.action_space.dtype))[0]

    def go(self, target, gripper: float, steps: int = 12) -> None:
        """Full-speed moves toward `target` until the TCP is within 3 mm of it."""
        for _ in range(steps):
            move = (np.asarray(target) - self.tcp) / 0.05
            move /= max(1.0, np.abs(move).max())
            self.step(move, gripper)
            if np.abs(np.asarray(target) - self.tcp).max() < 0.003:
                return


def attempt(script: Script, seed: int, squeeze: float, off_centre=(0.0, 0.0),
            descended=None) -> dict:
    """One grasp, lift and carry holding `squeeze`: whether the block stayed, its slip, how
    far above its target (mm) the open hand stopped coming down `off_centre` (x, y; m) away
    from the block's centre, and how far (mm) its descent shoved the block sideways. Calls
    `descended()`, if given, between the descent and the close."""
    script.reset(seed)
    start = script.block.copy()
    grasp = start + [*off_centre, 0.0]
    script.go(grasp + [0.0, 0.0, 0.06], 1.0)
    script.go(grasp, 1.0)
    stopped_above = 1000.0 * float(script.tcp[2] - grasp[2])
    shoved = 1000.0 * float(np.linalg.norm(script.block[:2] - start[:2]))
    if descended is not None:
        descended()
    for _ in range(2):
        script.step([0.0, 0.0, 0.0], -1.0)
    gap = script.tcp[2] - script.block[2]
    toward_centre = np.array([0.6, 0.0]) - start[:2]
    toward_centre /= max(np.linalg.norm(toward_centre), 1e-9)
    for _ in range(4):
        script.step([0.0, 0.0, 1.0], squeeze)
    for _ in range(3):
        script.step([*toward_centre, 0.0], squeeze)
    return {"held": bool(script.block[2] - start[2] >= HELD),
            "slip_mm": 1000.0 * float(script.tcp[2] - script.block[2] - gap),
            "stopped_above_mm": stopped_above, "shoved_mm": shoved}


def hand_motion(env, suite: str, seed: int, axis: int) -> dict:
    """The TCP over a full action's 5 cm along `axis` from rest, physics step by physics
    step (2 ms), the target set as each suite's action sets it (MuJoCo directly: within a
    step Gymnasium shows nothing): peak speed (m/s), the share of the 5 cm covered after
    0.05 s and after 0.5 s, and how far the hand has tilted from its start by then (deg)."""
    import mujoco

    env.reset(seed=seed)
    if suite == "reference":
        model, data = env.model, env.data
        tcp = lambda: data.site("ee_center_site").xpos.copy()  # noqa: E731
        axis_of_hand = lambda: data.site("ee_center_site").xmat.reshape(3, 3)[:, 2].copy()  # noqa: E731
        env.set_mocap_pose(tcp(), env.grasp_site_pose)
        mujoco.mj_step(model, data, nstep=250)  # At rest: its reset keeps setup's velocities.
        data.qvel[:] = 0.0

        def set_target(target):
            env.set_mocap_pose(target, env.grasp_site_pose)

        step = lambda: mujoco.mj_step(model, data)  # noqa: E731
    else:
        physics, task = env.composer_env.physics, env.task
        tcp = lambda: physics.bind(task.panda.tcp_site).xpos.copy()  # noqa: E731
        axis_of_hand = lambda: physics.bind(task.panda.tcp_site).xmat.reshape(3, 3)[:, 2].copy()  # noqa: E731

        def set_target(target):
            physics.bind(task.controller.target).mocap_pos = target

        step = physics.step
    start, start_axis = tcp(), axis_of_hand()
    set_target(start + 0.05 * np.eye(3)[axis])
    path = [start]
    for _ in range(250):
        step()
        path.append(tcp())
    path = np.array(path)
    moved = (path[:, axis] - start[axis]) / 0.05
    speed = np.linalg.norm(np.diff(path, axis=0), axis=1) / 0.002
    tilt = np.degrees(np.arccos(np.clip(axis_of_hand() @ start_axis, -1.0, 1.0)))
    return {"peak_speed": float(speed.max()), "at_0.05": float(moved[25]),
            "at_0.5": float(moved[250]), "tilt_deg": float(tilt)}


def worker(suite: str, episodes: int, seed: int, reference_path: pathlib.Path | None) -> int:
    answers, sys.stdout = sys.stdout, sys.stderr
    env = make_env(suite, reference_path)
    script = Script(env)
    rows = {str(g): [attempt(script, seed + i, g) for i in range(episodes)] for g in SQUEEZES}
    rows["motion"] = [hand_motion(env, suite, seed, axis) for axis in (0, 2)]
    rows["off_centre"] = [[[attempt(script, seed + i, -1.0, offset * np.eye(2)[axis])
                            for i in range(episodes)] for offset in OFFSETS]
                          for axis in (0, 1)]
    env.close()
    print(RESULT_PREFIX + json.dumps(rows), file=answers, flush=True)
    return 0


def table(results: dict[str, dict[str, list[dict]]], episodes: int) -> str:
    titles = {suite: random_exploration.SUITES[suite][1] for suite in results}
    lines = ["| gripper action held | " + " | ".join(titles[s] for s in results) + " |",
             "|---|" + "---|" * len(results)]
    for g in SQUEEZES:
        cells = []
        for rows in results.values():
            attempts = rows[str(g)]
            held = sum(row["held"] for row in attempts)
            slip = np.median([row["slip_mm"] for row in attempts])
            cells.append(f"{held}/{episodes} held, slip {slip:.0f} mm")
        lines.append(f"| {g:+.2f} | " + " | ".join(cells) + " |")
    lines += ["", "| a full action from rest, along | " + " | ".join(titles[s] for s in results)
              + " |", "|---|" + "---|" * len(results)]
    for index, axis in enumerate("xz"):
        cells = [f"peak {m['peak_speed']:.2f} m/s; {100 * m['at_0.05']:.0f} % of 5 cm at "
                 f"0.05 s, {100 * m['at_0.5']:.1f} % at 0.5 s, tilted {m['tilt_deg']:.1f} deg"
                 for m in (rows["motion"][index] for rows in results.values())]
        lines.append(f"| {axis} | " + " | ".join(cells) + " |")
    lines += ["", "| the open hand descends off the block's centre by | "
              + " | ".join(titles[s] for s in results) + " |", "|---|" + "---|" * len(results)]
    for index, axis in enumerate("xy"):
        for column, offset in enumerate(OFFSETS):
            cells = []
            for rows in results.values():
                attempts = rows["off_centre"][index][column]
                stopped = np.median([row["stopped_above_mm"] for row in attempts])
                cells.append(f"{sum(row['held'] for row in attempts)}/{episodes} held, "
                             f"stopped {int(round(stopped))} mm above")
            lines.append(f"| {1000 * offset:.0f} mm along {axis} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = random_exploration.comparison_parser(__doc__, SUITES, episodes=20)
    args = parser.parse_args(argv)
    random_exploration.check_arguments(parser, args)
    if args.suite:
        return worker(args.suite, args.episodes, args.seed, args.reference_path)
    results = random_exploration.run_suites(
        __file__, SUITES, ["--episodes", str(args.episodes), "--seed", str(args.seed)],
        args.reference_path)
    print(f"pick_and_place, {args.episodes} grasps per gripper action, seed {args.seed}\n")
    print(table(results, args.episodes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
