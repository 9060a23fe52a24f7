"""Can the hand flick a block away by sweeping its top edge? The contact tests press straight
down (`tests/test_contacts.py`: neither sinks nor launches); a stack learner found another
way: a finger resting on a block's top edge, then a full sideways command
(`training_episodes.py` counts the flights in a learner's buffer).

On pick-and-place (its block, and the fingers under command; push holds them closed). Each
trial: reset with a seed, bring the open hand (or narrowed by one width command) 6 cm above
a point beside the block, lower it with full -z for 10 steps (it comes to rest on the
block's top where a finger overlaps it, on the floor where none does), then two steps of a
full sideways command (x, y each -1, 0 or +1, not both 0) with -z (or `--move-z`) and the
fingers closing or opening, and two steps still. Prints the hand's top speed in free space
and how much of a full command it covers in a step, the trials whose block flew fastest
(its peak speed, m/s, read after every physics step, and its rise, cm) and counts over all.

    python experiments/edge_flick.py [--timing default|reference]
        [--seeds 0 1] [--weld-time-constant SECONDS] [--move-z Z] [--stiff-hand-contacts]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from franka_composer.cli.options import episode_seed, positive_number

#: Where the hand comes down, from the block's centre (m): beside it, or with a finger over
#: its edge.
OFFSETS = [(x, y) for x in (-0.035, -0.03, -0.025, -0.02, 0.0) for y in (-0.03, 0.0, 0.03)
           if (x, y) != (0.0, 0.0)]
#: The finger command of the last lowering step: none (open, 8 cm), or narrowing the hand.
WIDTH_COMMANDS = (0.0, -0.2, -0.3)


class Peaks:
    """The block's and the hand's (tool centre point's) highest speeds (m/s), and the block's
    greatest height (m), since each was last set to zero, read after every physics step: a
    control step's ends would miss them (a block flung 20 cm up lands within 0.5 s, the
    reference timing's step)."""

    def __init__(self, physics) -> None:
        import mujoco

        free = np.flatnonzero(physics.model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
        if len(free) != 1:
            raise SystemExit(f"{len(free)} free joints: this reads a task with one block")
        self._velocity = slice(physics.model.jnt_dofadr[free[0]],
                               physics.model.jnt_dofadr[free[0]] + 3)
        self._height = physics.model.jnt_qposadr[free[0]] + 2
        self._tcp = physics.model.name2id("panda/tcp", "site")
        self._physics, self._step = physics, physics.step
        self.block, self.hand, self.height = 0.0, 0.0, 0.0
        physics.step = self._stepped

    @classmethod
    def of(cls, env) -> "Peaks":
        """The one reading `env`'s physics (made on its first use)."""
        physics = env.unwrapped._env.physics
        reading = getattr(physics.step, "__self__", None)
        return reading if isinstance(reading, cls) else cls(physics)

    def _stepped(self, nstep: int = 1) -> None:
        data, timestep = self._physics.data, self._physics.model.opt.timestep
        for _ in range(nstep):
            before = data.site_xpos[self._tcp].copy()
            self._step()
            self.block = max(self.block, float(np.linalg.norm(data.qvel[self._velocity])))
            self.height = max(self.height, float(data.qpos[self._height]))
            self.hand = max(self.hand,
                            float(np.linalg.norm(data.site_xpos[self._tcp] - before)) / timestep)


def hand_top_speed(env) -> float:
    """The hand's peak speed (m/s) over two full diagonal commands from rest, in free space."""
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([0.0, 0.0, 0.0, 0.0], np.float32))
    peaks = Peaks.of(env)
    peaks.hand = 0.0
    for _ in range(2):
        env.step(np.array([1.0, 1.0, 0.0, 0.0], np.float32))
    return peaks.hand


def stiffen_hand_contacts(env) -> None:
    """Gives the block's stiff contact parameters the win in its contacts with the hand too:
    MuJoCo mixes a contact's parameters by the geoms' `solmix` weights, and the block's
    weight 0 leaves them to the hand (contacts.py); a weight far above the hand's 1 takes
    them. The model is built once, so this holds over resets."""
    env.reset(seed=0)
    physics = env.unwrapped._env.physics
    block = physics.model.name2id("block/geom", "geom")
    physics.model.geom_solmix[block] = 1e6


def tracking(env) -> float:
    """The share of a full x command's 5 cm the hand covers in one step from rest: what a
    softer weld costs in motion."""
    obs, _ = env.reset(seed=0)
    for _ in range(10):
        obs, *_ = env.step(np.array([0.0, 0.0, 0.0, 0.0], np.float32))
    start = obs["observation"][0]
    obs, *_ = env.step(np.array([1.0, 0.0, 0.0, 0.0], np.float32))
    return float(obs["observation"][0] - start) / 0.05


def trial(env, seed: int, offset, width_command: float, move,
          move_z: float = -1.0) -> tuple[float, float]:
    """(the block's peak speed, m/s; its highest rise, m) for one trial; `move_z`: the z
    command of the sideways steps (-1 goes on pressing, 0 stops)."""
    obs, _ = env.reset(seed=seed)
    peaks = Peaks.of(env)

    def tcp(observation):
        return observation["observation"][:3]

    block = obs["achieved_goal"][:3].copy()
    target = np.array([block[0] + offset[0], block[1] + offset[1], 0.06])
    for _ in range(25):
        step = np.clip((target - tcp(obs)) / 0.05, -1, 1)
        obs, *_ = env.step(np.r_[step, 1.0].astype(np.float32))
    for i in range(10):
        step = np.clip((target - tcp(obs)) / 0.05, -1, 1)
        step[2] = -1.0
        obs, *_ = env.step(np.r_[step, width_command if i == 9 else 0.0].astype(np.float32))
    resting, peaks.block, peaks.height = float(obs["achieved_goal"][2]), 0.0, 0.0
    for action in [(*move[:2], move_z, move[2])] * 2 + [(0.0, 0.0, 0.0, 0.0)] * 2:
        _, _, terminated, truncated, _ = env.step(np.array(action, np.float32))
        if terminated or truncated:
            break
    return peaks.block, peaks.height - resting


def main(argv: list[str] | None = None) -> int:
    import gymnasium as gym

    import franka_composer  # noqa: F401  (registers the ids)
    from franka_composer.tasks.options import TIMINGS, expand_timing

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--timing", default="default", choices=tuple(TIMINGS))
    parser.add_argument("--seeds", type=episode_seed, nargs="+", default=[0, 1])
    parser.add_argument("--weld-time-constant", type=positive_number, metavar="SECONDS",
                        help="the mocap weld's (default: the timing's, 0.01 s or 0.02 s): "
                             "how fast the hand follows a full command")
    parser.add_argument("--move-z", type=float, default=-1.0, metavar="Z",
                        help="the z command of the sideways steps: -1 (default) goes on "
                             "pressing, 0 lets the press go")
    parser.add_argument("--stiff-hand-contacts", action="store_true",
                        help="the block's stiff contact parameters (contacts.py) in its "
                             "contacts with the hand too, in place of Menagerie's softer ones")
    args = parser.parse_args(argv)
    if not -1.0 <= args.move_z <= 1.0:
        parser.error(f"--move-z must be an action in [-1, 1], got {args.move_z:g}")
    options = {"timing": args.timing}
    if args.weld_time_constant:
        options = {**expand_timing(options), "weld_time_constant": args.weld_time_constant}
    env = gym.make("FrankaPickAndPlaceSparse-v0", max_episode_steps=400,
                   terminate_on_success=False, **options)
    if args.stiff_hand_contacts:
        stiffen_hand_contacts(env)
    moves = [(dx, dy, fingers) for dx, dy, fingers in itertools.product((1, 0, -1), (1, 0, -1),
                                                                          (-1, 1))
             if (dx, dy) != (0, 0)]
    trials = []
    for seed, offset, width, move in itertools.product(args.seeds, OFFSETS, WIDTH_COMMANDS,
                                                        moves):
        trials.append((*trial(env, seed, offset, width, move, args.move_z), seed, offset, width,
                       move))
    trials.sort(key=lambda row: -row[0])
    setting = (f", weld time constant {args.weld_time_constant:g} s"
               if args.weld_time_constant else "")
    setting += f", sideways steps with z {args.move_z:g}" if args.move_z != -1.0 else ""
    setting += ", stiff hand contacts" if args.stiff_hand_contacts else ""
    print(f"pick_and_place, timing {args.timing}{setting}, seeds {args.seeds}: "
          f"{len(trials)} trials; the hand's top speed (two full diagonal commands from rest): "
          f"{hand_top_speed(env):.2f} m/s; one full x command from rest moves it "
          f"{100 * tracking(env):.0f} % of its 5 cm\n")
    print("| block's peak speed | its rise | seed | hand down at (from the block) | "
          "finger command | move (x, y, fingers) |")
    print("|---|---|---|---|---|---|")
    for peak, rise, seed, offset, width, move in trials[:8]:
        print(f"| {peak:.2f} m/s | {100 * rise:.1f} cm | {seed} | {offset} | {width} | {move} |")
    speeds = np.array([row[0] for row in trials])
    rises = np.array([row[1] for row in trials])
    print(f"\nfaster than 1.5 m/s: {(speeds > 1.5).sum()}; faster than 2.5 m/s: "
          f"{(speeds > 2.5).sum()}; risen more than 5 cm: {(rises > 0.05).sum()}; more than "
          f"10 cm: {(rises > 0.10).sum()}; the highest: {100 * rises.max():.1f} cm")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
