"""Joint-position control with Menagerie's own servos, panda-gym's `joints` semantics.

The first seven action components, clipped to [-1, 1], move each arm joint's servo target
to the joint's present angle plus `max_joint_step` (0.05 rad) times the component, within
the joint's range; the gripper as under every controller. The servos are Menagerie's (its
stiffness and force limits), with their damping lowered so that a step from rest reaches
83-101 % of its target within the step (held, a moving joint carries on past it: 110-124 %
on joints 1-4; `entities/panda.py`, `SERVO_DERIVATIVE_TIME`), and the links compensate
their own weight, as the real Panda's joint controller does: the servos only move the arm.

The surface guard (`surface_guard.py`) bounds these targets as it does mocap's and osc's.
Where the step could bring the hand onto a surface beneath it (the targets to first order,
with the hand's own descent carried on for `BRAKING_TIME`), two things change: the targets
are raised, by the least change of them weighted by the servos' stiffness, until the tool
centre point's target is no deeper below the touching height than the servos' vertical
spring needs to push with the force the arm can push down with there (the guard's press
depth); and during the step a hand descending onto the surface is braked, critically, by
a vertical force at the tool centre point sent through the servo targets every physics
step (`BRAKE_MARGIN`). Without the brake the underdamped servos carry the hand past its
target into the surface (before the guard a press shoved objects up to 38 cm and lifted
them 13 mm: docs/guide/controllers.md).
"""

from __future__ import annotations

import mujoco
import numpy as np

from franka_composer.controllers.base import ActionLaw, Controller, contiguous

#: How long (s) the hand's present descent is taken to carry on when looking for a surface
#: the step could bring it onto (the brake stops it within ~20 ms).
BRAKING_TIME = 0.05
#: The brake acts once the hand is within 2 v / omega of the surface plus this (m): v its
#: descent, omega the frequency of the servos' vertical spring with the arm's inertia.
BRAKE_MARGIN = 0.005
#: Damping of the lift's solve, relative to the compliance's mean eigenvalue: near a
#: singular pose holding the target's x, y and orientation exactly takes joint motions
#: of radians (condition numbers of 1e7 seen); damped, the target may drift sideways a little.
LIFT_DAMPING = 1e-3
_UP = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


class JointController(Controller):
    """Sets the arm's position servos from joint-angle deltas."""

    ARM_ACTUATION = "position"

    def _bind_law(self, physics) -> "JointLaw":
        panda = self._panda
        low, high = np.array(panda.arm_joint_ranges, dtype=np.float64).T
        return JointLaw(self.settings, physics.model.ptr, physics.data.ptr, dict(
            self._law_ids(physics),
            arm_qpos=contiguous(physics.bind(panda.joints).qposadr, "arm qpos addresses"),
            arm_dofs=contiguous(physics.bind(panda.joints).dofadr, "arm dofs"),
            servos=contiguous(physics.bind(panda.arm_actuators).element_id, "arm servos"),
            low=low, high=high))

    def scale_gains(self, physics, factor: float) -> None:
        """The servos' stiffness times `factor`, their derivative time kept."""
        self._panda.set_servo_gain(physics, factor)


class JointLaw(ActionLaw):
    """Joint-angle deltas to servo targets, on one MjData; guarded near surfaces."""

    def __init__(self, settings, model, data, ids: dict) -> None:
        super().__init__(settings, model, data, ids)
        self._q, self._targets = data.qpos[ids["arm_qpos"]], data.ctrl[ids["servos"]]
        self._qdot = data.qvel[ids["arm_dofs"]]
        self._low, self._high = ids["low"], ids["high"]
        self._arm_size = len(self._low)
        self._arm_dofs = ids["arm_dofs"]
        # A view: domain randomisation scales the servos' stiffness in place.
        self._stiffness = model.actuator_gainprm[ids["servos"], 0]
        self._jacp, self._jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        self._jacobian, self._lever = np.zeros((6, self._arm_size)), np.zeros(model.nv)
        self._guarded, self._target = np.zeros(self._arm_size), np.zeros(3)
        self._per_newton = np.zeros(self._arm_size)
        self._brake = self._frequency = self._touching = 0.0  # Set by each guarded step.
        self.has_substep = False

    def reset(self) -> None:
        """The servos hold the configuration the episode starts in."""
        self._targets[:] = self._q
        self.has_substep = False

    def __call__(self, action: np.ndarray) -> None:
        """Writes the servo targets (and gripper command) for `action` (float64)."""
        action = np.clip(action, -1.0, 1.0)
        step = self._settings.max_joint_step * action[:self._arm_size]
        np.clip(self._q + step, self._low, self._high, out=self._targets)
        self.has_substep = self._guard_targets()
        self.command_gripper(action)

    def _guard_targets(self) -> bool:
        """Raises the targets where they would drive the hand into a surface beneath it
        (the module docstring); returns whether the step needs the brake."""
        model, data, jacp, jacr = self._model, self._data, self._jacp, self._jacr
        mujoco.mj_jacSite(model, data, jacp, jacr, self._ids["tcp_site"])
        jacobian = self._jacobian
        jacobian[:3], jacobian[3:] = jacp[:, self._arm_dofs], jacr[:, self._arm_dofs]
        tcp = self._tcp_pos
        target = np.add(tcp, jacobian[:3] @ (self._targets - self._q), out=self._target)
        descent = jacobian[2] @ self._qdot  # Vertical speed (m/s), up positive.
        reach = target.copy()
        reach[2] = min(target[2], tcp[2]) + min(descent, 0.0) * BRAKING_TIME
        touching = self._guard.touching(tcp, reach)
        if reach[2] >= touching:
            return False
        # The servos' vertical spring at the tool centre point: a vertical force f there
        # deflects them by K^-1 J_z^T f and moves the hand by C_zz f, C_zz = J_z K^-1 J_z^T.
        yielding = jacobian / self._stiffness  # J K^-1
        np.copyto(self._per_newton, yielding[2])
        compliance = float(yielding[2] @ jacobian[2])
        depth = touching - target[2]
        if depth > 0.0:
            # Up to the touching height without moving the target sideways or turning it
            # (the least change of the targets weighted by the servos' stiffness), then as
            # deep as asked, up to the press depth: a press straight down with at most the
            # force the arm can push down with there.
            compliance6 = yielding @ jacobian.T  # C = J K^-1 J^T.
            compliance6[np.diag_indices(6)] += LIFT_DAMPING * np.trace(compliance6) / 6
            lift = yielding.T @ np.linalg.solve(compliance6, _UP)
            lift /= jacobian[2] @ lift  # Straight up by depth, exactly (to first order).
            press = min(depth / compliance, self._guard.max_push_force())
            self._targets += depth * lift - press * self._per_newton
            np.clip(self._targets, self._low, self._high, out=self._targets)
        # Critical damping of that spring, with the arm's inertia seen at the tool centre
        # point straight up: m = 1 / (J_z M^-1 J_z^T).
        lever = self._lever
        mujoco.mj_solveM(model, data, lever.reshape(1, -1), jacp[2:3])
        mass = 1.0 / float(jacp[2] @ lever)
        self._brake = 2.0 * np.sqrt(mass / compliance)
        self._frequency = 1.0 / np.sqrt(mass * compliance)
        self._touching = touching
        self._guarded[:] = self._targets
        return True

    def substep(self) -> None:
        """Brakes a hand descending onto the surface (within `BRAKE_MARGIN`'s reach of it):
        the guarded targets plus the servo deflection that pushes the tool centre point up
        with the force of a critical damper."""
        speed = float(self._jacobian[2] @ self._qdot)
        clearance = self._tcp_pos[2] - self._touching
        if speed < 0.0 and clearance < BRAKE_MARGIN - 2.0 * speed / self._frequency:
            np.add(self._guarded, -self._brake * speed * self._per_newton, out=self._targets)
        else:
            self._targets[:] = self._guarded
