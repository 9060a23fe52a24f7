"""Joint-position control with Menagerie's own servos, panda-gym's `joints` semantics.

The first seven action components, clipped to [-1, 1], move each arm joint's servo target
to the joint's present angle plus `max_joint_step` (0.05 rad) times the component, within
the joint's range; the gripper as under every controller. The servos are Menagerie's (its
stiffness and force limits), with their damping lowered so that a step from rest reaches
83-100 % of its target within the step (held, a moving joint carries on past it: 110-124 %
on joints 1-4; `entities/panda.py`, `SERVO_DERIVATIVE_TIME`), and the links compensate
their own weight, as the real Panda's joint controller does: the servos only move the arm.
The surface guard that keeps mocap's and osc's targets out of surfaces does not act on these
targets: a press in joint space is bounded by the servos' force limits alone, and can shove
or lift an object (docs/guide/controllers.md, experiments/controller_press.py).
"""

from __future__ import annotations

import numpy as np

from franka_composer.controllers.base import ActionLaw, Controller, contiguous


class JointController(Controller):
    """Sets the arm's position servos from joint-angle deltas."""

    ARM_ACTUATION = "position"

    def _bind_law(self, physics) -> "JointLaw":
        panda = self._panda
        low, high = np.array(panda.arm_joint_ranges, dtype=np.float64).T
        return JointLaw(self.settings, physics.model.ptr, physics.data.ptr, dict(
            self._law_ids(physics),
            arm_qpos=contiguous(physics.bind(panda.joints).qposadr, "arm qpos addresses"),
            servos=contiguous(physics.bind(panda.arm_actuators).element_id, "arm servos"),
            low=low, high=high))

    def scale_gains(self, physics, factor: float) -> None:
        """The servos' stiffness times `factor`, their derivative time kept."""
        self._panda.set_servo_gain(physics, factor)


class JointLaw(ActionLaw):
    """Joint-angle deltas to servo targets, on one MjData."""

    def __init__(self, settings, model, data, ids: dict) -> None:
        super().__init__(settings, model, data, ids)
        self._q, self._targets = data.qpos[ids["arm_qpos"]], data.ctrl[ids["servos"]]
        self._low, self._high = ids["low"], ids["high"]
        self._arm_size = len(self._low)

    def reset(self) -> None:
        """The servos hold the configuration the episode starts in."""
        self._targets[:] = self._q

    def __call__(self, action: np.ndarray) -> None:
        """Writes the servo targets (and gripper command) for `action` (float64)."""
        action = np.clip(action, -1.0, 1.0)
        step = self._settings.max_joint_step * action[:self._arm_size]
        np.clip(self._q + step, self._low, self._high, out=self._targets)
        self.command_gripper(action)
