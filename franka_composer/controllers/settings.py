"""How actions in [-1, 1] map to motion, for every controller: one record, one place."""

from __future__ import annotations

import dataclasses

import numpy as np

#: Joints of the arm, each with one action component under joint control.
ARM_JOINT_COUNT = 7
#: Each controller's arm action: how many components, what they are, the action spec's
#: name. The gripper, where it is actuated, adds one more, last, under every controller.
ARM_ACTIONS = {
    "mocap": (3, "dx, dy, dz", "tcp_delta"),
    "osc": (3, "dx, dy, dz", "tcp_delta"),
    "joints": (ARM_JOINT_COUNT, "dq1..dq7", "joint_delta"),
}
#: The `control` option's values: the paper's mocap first (the default).
CONTROLS = tuple(ARM_ACTIONS)
#: The controller used where none is named: the paper's mocap. Ids, dataset ids and run
#: labels leave its name out; they name every other.
DEFAULT_CONTROL = "mocap"
#: The controllers whose arm action moves the tool centre point (dx, dy, dz).
TCP_CONTROLS = tuple(kind for kind in CONTROLS if ARM_ACTIONS[kind][2] == "tcp_delta")

# The mocap weld's stiffness (critically damped, time constant in s). MuJoCo's default 0.02 s
# leaves 30 % of a full command from rest undone after a 0.05 s control step. A stiff 0.006 s
# tracks 99 % but covers each step's 5 cm in ~15 ms, a 3 m/s jab that flings and flips a
# pushed block (measured: 20 cm and a 180 deg tumble for an 8 cm push). 0.01 s tracks 95 % of
# a full command within the step, with a peak speed of ~1.9 m/s, and pushes the block flat.
WELD_TIME_CONSTANT = 0.01
# The reference code's weld (MuJoCo's default), which its 0.5 s step leaves time to settle
# (`TIMINGS["reference"]`): a full action's peak hand speed 0.93 m/s against the reference
# code's 0.86-0.90 and this default's 1.91, and a lifted block kept by gripper actions down
# to -0.05 (the reference code's -0.08) where 0.01 s drops it from -0.12 on
# (experiments/grasp_margin.py, docs/experiments/grasp-margin.md).
REFERENCE_WELD_TIME_CONSTANT = 0.02


def has_weld(kind: str) -> bool:
    """Whether controller `kind` drags the hand by a weld (mocap's), so that the weld's time
    constant acts; the others have none and ignore it."""
    return kind == "mocap"


@dataclasses.dataclass(frozen=True)
class ControlSettings:
    """How actions in [-1, 1] map to motion.

    Attributes:
      kind: the controller, one of `CONTROLS`: "mocap" (a weld drags the hand, the paper's),
        "osc" (joint torques from an operational-space law) or "joints" (joint servos).
      max_tcp_step: metres the tool centre point's target moves per control step for an
        action component of 1 (mocap and osc). Under mocap, from 0.4 m on full actions
        let the weld's pull diverge now and then (MuJoCo's instability warning, at 0.05 s
        per step; none up to 0.3 m on push, pick and place and stack).
      max_joint_step: radians a joint's target moves per control step for an action
        component of 1 (joints; panda-gym's 0.05).
      max_finger_step: metres the finger width changes per control step for a gripper
        action of 1 (0.2 > 0.08: one full command opens or closes the hand).
      actuated_gripper: whether the action has a last, gripper, component; if not, the
        fingers are held closed.
      weld_time_constant: seconds, the time constant of the weld that drags the hand to its
        target: how fast a full action moves the hand, hence how hard it jerks a held block
        (`WELD_TIME_CONSTANT`, `REFERENCE_WELD_TIME_CONSTANT`). Mocap only: the other
        controllers have no weld and ignore it, and nothing compares it for them.
      guard_ignores_carried: whether the surface guard takes a block the hand carries (both
        fingers touch it, nothing else does) for part of the hand rather than a surface
        beneath it. Without it, the rays from the fingertips' inner corners meet the
        underside of a block held low in the grip, and a downward command is held up by
        what the hand carries (`docs/guide/physics.md`). Stack's v1 sets it; the paper's
        tasks keep v0's guard, as their ids do.
    """

    kind: str = DEFAULT_CONTROL
    max_tcp_step: float = 0.05
    max_joint_step: float = 0.05
    max_finger_step: float = 0.2
    actuated_gripper: bool = False
    weld_time_constant: float = WELD_TIME_CONSTANT
    guard_ignores_carried: bool = False

    @property
    def arm_action_size(self) -> int:
        return ARM_ACTIONS[self.kind][0]

    @property
    def action_size(self) -> int:
        return self.arm_action_size + int(self.actuated_gripper)

    @property
    def has_weld(self) -> bool:
        """Whether this controller drags the hand by a weld (`has_weld`)."""
        return has_weld(self.kind)

    @property
    def moves_the_tcp(self) -> bool:
        """Whether the arm's action components move the tool centre point (dx, dy, dz)."""
        return self.kind in TCP_CONTROLS

    def describe_action(self) -> str:
        """The action's components in words: "dx, dy, dz, gripper"."""
        arm = ARM_ACTIONS[self.kind][1]
        return f"{arm}, gripper" if self.actuated_gripper else arm

    @property
    def action_name(self) -> str:
        """The action spec's name: "tcp_delta", "joint_delta_and_gripper"..."""
        name = ARM_ACTIONS[self.kind][2]
        return f"{name}_and_gripper" if self.actuated_gripper else name

    def tcp_action(self, tcp, target, max_speed: float = 1.0) -> np.ndarray:
        """The action law inverted: the position part of an action that takes the tool centre
        point from `tcp` to `target` (m) in one step if it is that close, else straight
        towards it at `max_speed` (a fraction of a full step). For scripted policies."""
        step = (np.asarray(target) - tcp) / self.max_tcp_step
        norm = np.linalg.norm(step)
        if norm > max_speed:
            step *= max_speed / norm
        return step
