"""Whether a pushed block slides or tips over, here and in the paper's reference code: the
learners trained at the reference timing tip the block in a third of their episodes after
5e4 steps, where the reference code's learner tips it in about 1 % (its pushes slide it;
`training_episodes.py`). A scripted push isolates the physics from the learner: closed
fingers lowered beside the block, then full-speed steps straight through it.

    python experiments/push_tip.py --reference-path DIR [--episodes 20] [--seed 0]

Episode i from `reset(seed=SEED + i)`: the closed hand goes to 5 cm behind the block's
centre along x at a height `HEIGHTS` (its tool centre point's height above the block's
centre), then takes `PUSHES` full steps along +x. The block tipped if its orientation
turned more than 0.3 rad about x or y at the end of a step (its Euler angles in the
observation, both suites); the slide is how far its centre moved. Variants as in
`grasp_reach.py` (one process each, the changes made to that process's env): this suite at
timing="reference", with the reference code's block and floor contacts, with its finger
friction, with both, this suite at its default timing, and the reference code (DIR as
there; left out without it). Prints a Markdown table: per height and variant, the pushes
that tipped the block and the median slide (mm).
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

from franka_composer.tasks.records import REFERENCE_OBJECT_DAMPING

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import grasp_reach  # noqa: E402  (experiments/, not a package)
import hand_on_top  # noqa: E402

grasp_margin, random_exploration = grasp_reach.grasp_margin, grasp_reach.random_exploration
#: The tool centre point's height above the block's centre (m) during the push: the
#: fingertips (7.3 mm below it here) just above the floor, at the block's middle, higher.
HEIGHTS = (-0.012, 0.0, 0.01)
BEHIND = 0.05  # m behind the block's centre, along -x, where the push starts.
PUSHES = 3  # Full steps along +x (5 cm each).


def reference_solver(env) -> None:
    """The reference code's solver options: Euler, pyramidal friction cones, 3 noslip
    iterations (this suite's: implicitfast, elliptic, none)."""
    import mujoco

    option = env.composer_env.physics.model.opt
    option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    option.noslip_iterations = 3


def reference_block_damping(env) -> None:
    """The reference code's block's free-joint damping, set in the compiled model (as the
    task option `object_damping` sets it in the MJCF: the same model)."""
    physics = env.unwrapped.composer_env.physics
    model = physics.model
    geom = int(physics.bind(env.unwrapped.task.prop.mjcf_model.find_all("geom")).element_id[0])
    joint = model.body_jntadr[model.geom_bodyid[geom]]  # The free joint Composer attached.
    if model.jnt_type[joint] != 0:  # mjJNT_FREE
        raise ValueError("the object's body does not hang from a free joint")
    start = model.jnt_dofadr[joint]
    model.dof_damping[start:start + 6] = REFERENCE_OBJECT_DAMPING


def reference_contacts(env) -> None:
    """The reference code's block and floor contacts, finger friction and solver."""
    grasp_reach.reference_block(env)
    grasp_reach.reference_pads(env)
    reference_solver(env)


#: name: (title, the suite it plays, the changes made to its env).
VARIANTS = {
    "as_is": ('timing="reference"', "ours_reference_timing", ()),
    "reference_block": ("the reference code's block and floor contacts",
                        "ours_reference_timing", (grasp_reach.reference_block,)),
    "reference_pads": ("its finger friction", "ours_reference_timing",
                       (grasp_reach.reference_pads,)),
    "reference_solver": ("its solver", "ours_reference_timing", (reference_solver,)),
    "reference_block_damping": ("its block's joint damping", "ours_reference_timing",
                                (reference_block_damping,)),
    "reference_contacts": ("its block contacts, finger friction and solver",
                           "ours_reference_timing", (reference_contacts,)),
    "default_timing": ("this suite's default timing", "ours", ()),
    "reference": ("reference code", "reference", ()),
}


def push(script, watcher, seed: int, height: float) -> dict:
    """One push at `height`: whether the block tipped, how far it slid (mm), and how high
    above the block's bottom (mm) a finger first touched it (`watcher`, a
    `grasp_reach.FingerOnBlock`)."""
    script.reset(seed)
    watcher.clear()
    start = script.block.copy()
    behind = start + [-BEHIND, 0.0, 0.0]
    script.go(behind + [0.0, 0.0, 0.06], -1.0)
    script.go(behind + [0.0, 0.0, height], -1.0)
    tipped = False
    for _ in range(PUSHES):
        script.step([1.0, 0.0, 0.0], -1.0)
        tipped |= bool(hand_on_top.tipped(script.obs["observation"][10:12]))
    touch = watcher.first_touch_z
    return {"tipped": tipped,
            "slide_mm": 1000.0 * float(np.linalg.norm(script.block[:2] - start[:2])),
            "touch_mm": None if touch is None
            else 1000.0 * (touch - (start[2] - hand_on_top.HALF_BLOCK))}


def pushes(variant: str, episodes: int, seed: int, reference_path) -> list[list[dict]]:
    """Per height, the pushes of `variant`."""
    _, suite, changes = VARIANTS[variant]
    env = grasp_margin.make_env(suite, reference_path)
    env.reset(seed=seed)  # Compiles the physics the changes are made to.
    for change in changes:
        change(env)
    script, watcher = grasp_margin.Script(env), grasp_reach.watch(env)
    rows = [[push(script, watcher, seed + i, height) for i in range(episodes)]
            for height in HEIGHTS]
    env.close()
    return rows


def first_touch(rows: list[dict]) -> str:
    """The median height of the first touch above the block's bottom, as a cell."""
    heights = [row["touch_mm"] for row in rows if row["touch_mm"] is not None]
    return f"{np.median(heights):.0f} mm up" if heights else "none"


def table(results: dict[str, list[list[dict]]], episodes: int) -> str:
    lines = ["| the hand's centre above the block's | "
             + " | ".join(VARIANTS[variant][0] for variant in results) + " |",
             "|---|" + "---|" * len(results)]
    for index, height in enumerate(HEIGHTS):
        cells = [f"{sum(row['tipped'] for row in rows[index])}/{episodes} tipped, slid "
                 f"{int(round(np.median([row['slide_mm'] for row in rows[index]])))} mm, "
                 f"first touch {first_touch(rows[index])}"
                 for rows in results.values()]
        lines.append(f"| {1000 * height:+.0f} mm | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(results: dict, episodes: int, seed: int) -> str:
    return (f"pick_and_place, {episodes} pushes per height, seed {seed}, the closed hand "
            f"from {1000 * BEHIND:.0f} mm behind the block, {PUSHES} full steps along x\n\n"
            + table(results, episodes))


def main(argv: list[str] | None = None) -> int:
    return random_exploration.comparison_main(argv, __doc__, __file__, VARIANTS, pushes,
                                              report)


if __name__ == "__main__":
    sys.exit(main())
