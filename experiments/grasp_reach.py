"""Which of this suite's contact choices narrows the off-centre grasp: at the reference timing
an open hand coming down 20 mm or more off the block's centre along the fingers' closing
axis stops with a finger on the block's top, where the reference code's hand grasps up to
25 mm off (`grasp_margin.py`). Each column undoes one of this suite's deliberate
differences from the reference code, or two together, and repeats that reach; the last is
the reference code itself:

    python experiments/grasp_reach.py --reference-path DIR [--episodes 20] [--seed 0]

`VARIANTS`: this suite at timing="reference"; with the surface guard let go (the hand's
target goes as deep as the action sends it, down to z = 0, as in the reference code); with
the reference code's block and floor contacts (MuJoCo's default softness, the block's
condim 6); with the reference code's finger friction (0.8 in all three coefficients,
condim 6); with the guard let go and the reference code's block; the
reference code (DIR as in `random_exploration.py`; left out without it). The same scripted
grasp and episodes as `grasp_margin.py` (`attempt`: open hand above the point, down, two
full closes, lift and carry at G = -1), episode i from `reset(seed=SEED + i)`; each variant
in a process of its own, its changes made to that process's compiled model and guard,
never to the package. Prints a Markdown table: per offset and variant, the grasps that kept
the block, the median height above its target (mm) at which the hand stopped coming down,
how far (mm) the descent shoved the block sideways, and over the descent, physics step by
physics step, the largest force (N) with which a finger pressed on the block's top (a
contact normal within 45 deg of vertical) and how deep (mm) a finger sank into the block.
"""

from __future__ import annotations

import pathlib
import sys

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import grasp_margin  # noqa: E402  (experiments/, not a package)
from env_differences import DEFAULT_SOLIMP, DEFAULT_SOLREF  # noqa: E402

random_exploration = grasp_margin.random_exploration
#: Offsets (m) off the block's centre, (x, y); y is the fingers' closing axis.
OFFSETS = ((0.0, 0.0), (0.0, 0.015), (0.0, 0.02), (0.0, 0.025), (0.0, 0.03), (0.02, 0.0),
           (0.025, 0.0))


def let_guard_go(env) -> None:
    """The hand's target as deep as the action sends it (`random_exploration.let_guard_go`)."""
    del env  # The guard's class changes: one variant per process.
    random_exploration.let_guard_go()


def reference_block(env) -> None:
    """The block and the floor with MuJoCo's default softness, the block with condim 6."""
    physics = env.composer_env.physics
    model = physics.model
    block = np.array(physics.bind(env.task.prop.mjcf_model.find_all("geom")).element_id)
    for geom in (0, *block):  # The floor is geom 0.
        model.geom_solref[geom] = DEFAULT_SOLREF
        model.geom_solimp[geom] = DEFAULT_SOLIMP
        model.geom_solmix[geom] = 1.0
    model.geom_condim[block] = 6
    # The block's contact with the floor is a contact pair, with parameters of its own
    # (`contacts.add_surface_pair`).
    on_floor = model.name2id("block_floor", "pair")
    model.pair_solref[on_floor], model.pair_solimp[on_floor] = DEFAULT_SOLREF, DEFAULT_SOLIMP
    model.pair_dim[on_floor] = 6


def reference_pads(env) -> None:
    """The fingers' geoms with the reference code's friction (0.8 sliding, torsional and
    rolling) and condim 6."""
    model, fingers = env.composer_env.physics.model, finger_geoms(env)
    model.geom_friction[fingers] = (0.8, 0.8, 0.8)
    model.geom_condim[fingers] = 6


#: name: (title, the changes made to this suite's env; None: the reference code).
VARIANTS = {
    "as_is": ('timing="reference"', ()),
    "no_guard": ("the guard let go", (let_guard_go,)),
    "reference_block": ("the reference code's block and floor contacts", (reference_block,)),
    "reference_pads": ("the reference code's finger friction", (reference_pads,)),
    "no_guard_reference_block": ("the guard let go and the reference code's block",
                                 (let_guard_go, reference_block)),
    "reference": ("reference code", None),
}


def finger_geoms(env) -> list[int]:
    """The colliding geoms of the fingers of `env` (this suite's or the reference code's)."""
    if is_reference(env):
        model = env.model
        fingers = {model.body(name).id for name in ("left_finger", "right_finger")}
    else:
        physics = env.composer_env.physics
        model = physics.model.ptr
        fingers = set(np.array(physics.bind(env.task.panda.colliding_bodies).element_id)[1:])
    return [geom for geom in range(model.ngeom) if model.geom_bodyid[geom] in fingers
            and (model.geom_contype[geom] or model.geom_conaffinity[geom])]


def is_reference(env) -> bool:
    """Whether `env` is the reference code's (this suite's have a Composer env inside)."""
    return not hasattr(env, "composer_env")


class FingerOnBlock:
    """Physics step by physics step, since the last `clear`: the largest normal force (N) of
    a finger-block contact whose normal is within 45 deg of vertical (a finger pressing on
    the block's top, not squeezing its sides), the deepest (m) any finger-block contact
    went, and the height (m) of the first finger-block contact. After a physics step the
    contact forces are not yet solved for the new state: each step with a finger-block
    contact is solved again on a scratch copy (`mj_forward`), so the env's own data is
    never touched."""

    def __init__(self, model, data, fingers, block) -> None:
        self._model, self._data = model, data
        self._scratch = mujoco.MjData(model)
        self._pairs = {pair for a in fingers for b in block for pair in ((a, b), (b, a))}
        self._force = np.zeros(6)
        self.clear()

    def clear(self) -> None:
        self.press, self.depth = 0.0, 0.0
        self.first_touch_z = None  # m: the height of the first finger-block contact.

    def _touching(self, data) -> list[int]:
        return [index for index in range(data.ncon)
                if (int(data.contact[index].geom1), int(data.contact[index].geom2))
                in self._pairs]

    def measure(self) -> None:
        if not self._touching(self._data):
            return
        scratch = self._scratch
        mujoco.mj_copyData(scratch, self._model, self._data)
        mujoco.mj_forward(self._model, scratch)
        for index in self._touching(scratch):
            contact = scratch.contact[index]
            if self.first_touch_z is None:
                self.first_touch_z = float(contact.pos[2])
            self.depth = max(self.depth, -float(contact.dist))
            if abs(contact.frame[2]) > np.sqrt(0.5):
                mujoco.mj_contactForce(self._model, scratch, index, self._force)
                self.press = max(self.press, float(self._force[0]))


def watch(env) -> FingerOnBlock:
    """A `FingerOnBlock` measuring after every physics step of `env` (this suite's: from its
    next reset on, when Composer gathers the task's hooks again)."""
    if is_reference(env):
        model, data = env.model, env.data
        block = [model.geom("obj_geom").id]
        watcher = FingerOnBlock(model, data, finger_geoms(env), block)

        class SteppedOneByOne:  # The reference code steps through `env._mujoco`.
            def __getattr__(self, name):
                return getattr(mujoco, name)

            @staticmethod
            def mj_step(model, data, nstep=1):
                for _ in range(nstep):
                    mujoco.mj_step(model, data)
                    watcher.measure()

        env._mujoco = SteppedOneByOne()
        return watcher
    physics = env.composer_env.physics
    block = [int(geom) for geom in
             physics.bind(env.task.prop.mjcf_model.find_all("geom")).element_id]
    watcher = FingerOnBlock(physics.model.ptr, physics.data.ptr, finger_geoms(env), block)
    task, after = env.task, env.task.after_substep

    def after_substep(physics, random_state):
        after(physics, random_state)
        watcher.measure()

    task.after_substep = after_substep
    return watcher


def reach(variant: str, episodes: int, seed: int, reference_path) -> list[list[dict]]:
    """Per offset, the attempts of `variant`, each with its finger-on-block measures over
    the descent."""
    changes = VARIANTS[variant][1]
    env = grasp_margin.make_env("reference" if changes is None else "ours_reference_timing",
                                reference_path)
    env.reset(seed=seed)  # Compiles the physics the changes are made to.
    for change in changes or ():
        change(env)
    script, watcher = grasp_margin.Script(env), watch(env)
    rows = []
    for offset in OFFSETS:
        attempts = []
        for i in range(episodes):
            descent = {}
            watcher.clear()
            row = grasp_margin.attempt(script, seed + i, -1.0, offset, descended=lambda: (
                descent.update(press_n=watcher.press, depth_mm=1000.0 * watcher.depth)))
            attempts.append({**row, **descent})
        rows.append(attempts)
    env.close()
    return rows


def table(results: dict[str, list[list[dict]]], episodes: int) -> str:
    lines = ["| the open hand descends off the block's centre by | "
             + " | ".join(VARIANTS[variant][0] for variant in results) + " |",
             "|---|" + "---|" * len(results)]
    for column, (x, y) in enumerate(OFFSETS):
        cells = []
        for rows in results.values():
            attempts = rows[column]
            median = {key: np.median([row[key] for row in attempts])
                      for key in ("stopped_above_mm", "shoved_mm", "press_n", "depth_mm")}
            cells.append(f"{sum(row['held'] for row in attempts)}/{episodes} held; stopped "
                         f"{int(round(median['stopped_above_mm']))} mm above, shoved "
                         f"{int(round(median['shoved_mm']))} mm; pressed "
                         f"{int(round(median['press_n']))} N, "
                         f"{abs(median['depth_mm']):.1f} mm deep")
        along = f"{1000 * y:.0f} mm along y" if y else f"{1000 * x:.0f} mm along x"
        lines.append(f"| {along if x or y else 'on the centre'} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(results: dict, episodes: int, seed: int) -> str:
    return (f"pick_and_place at the reference timing, {episodes} grasps per offset, seed "
            f"{seed}, the gripper action held at -1\n\n" + table(results, episodes))


def main(argv: list[str] | None = None) -> int:
    return random_exploration.comparison_main(argv, __doc__, __file__, VARIANTS, reach,
                                              report)


if __name__ == "__main__":
    sys.exit(main())
