"""Operational-space torque control: the arm driven through its joint torques, as a real Panda
under its torque interface.

The arm's position servos are replaced by torque motors with the real Panda's limits (87 N m
on joints 1-4, 12 N m on joints 5-7: Menagerie's force ranges). Each control step sets the
same target as mocap: the tool centre point plus `max_tcp_step` times the action, kept from
running into the surface beneath the hand (`surface_guard.py`). Every `UPDATE_PERIOD`
seconds the law computes the joint torques

    tau = g(q) + c(q, qdot) + s_rot J^T W(a_rot) + s (J^T W(a_pos) + N M a_null)

with J the tool centre point's 6 x 7 Jacobian, M the mass matrix and

    a_pos = [K (target - x) - D v ; 0],    a_rot = [0 ; K_rot e_rot - D_rot w]

critically damped springs on the position and on the hand's orientation (held top-down at
the yaw it starts the episode with: e_rot is the rotation vector from the present
orientation to that one). W(a) = Lambda a, with Lambda = (J M^-1 J^T)^-1 the hand's
operational-space inertia, so that in free space the hand accelerates as asked, decoupled;
while the target is held at a surface (the hand presses into it), W(a) = diag(Lambda) a, a
Cartesian impedance, because there the hand cannot accelerate into the surface and Lambda's
cross terms would push it sideways off what it presses (measured: ~50 N sideways with a 136 N
press, the hand sliding off a block). a_null = k_n (q_0 - q) - d_n qdot pulls the elbow
towards the episode's starting configuration through N = I - J^T Lambda J M^-1, which
removes what would move the hand. g + c are MuJoCo's bias forces (gravity, Coriolis,
centrifugal): the links have no gravity compensation of their own, so the motors carry the
arm's weight within their limits. The factors s_rot, s <= 1 are the largest that keep every
joint within its limit, orientation first: where the command saturates, the hand keeps its
orientation and still accelerates straight towards the target, rather than being bent off
course by whichever joint clipped first.

What the limits allow. From the neutral pose the torques can accelerate the hand (no tilt,
no sideways motion) by at most 50 m/s^2 along +x, 32 along -y, 31 down and 11 up (gravity
takes 41 of joint 2's 87 N m): a linear programme over the torque box,
`experiments/torque_reach.py`. Even flat out for a whole 0.05 s control step that is 6.3,
4.0, 3.9 and 1.4 cm from rest, so unlike the mocap weld (unbounded force) one step from rest
cannot cover a full 5 cm command; sustained commands come close from the second step
(`tests/test_controllers.py`).
"""

from __future__ import annotations

from typing import cast

import mujoco
import numpy as np

from franka_composer.controllers.base import Controller, TcpTargetLaw, contiguous

#: Seconds between torque updates (250 Hz: every other 2 ms physics step), the torques held
#: in between. The real Panda's torque loop runs at 1 kHz; at 500 Hz (every physics step)
#: the measured tracking differs by at most 4 % of a step, and an env step costs 1.5x as
#: much (791 against 1169 random steps/s), so the law runs at 250 Hz.
UPDATE_PERIOD = 0.004
#: Cartesian stiffness (1/s^2, per unit of operational-space inertia: the hand's natural
#: frequency is its square root, 70 rad/s) and damping ratio, for position and orientation.
#: Stiff enough that a sustained full command moves the hand 5 cm per 0.05 s step (~1 m/s);
#: critically damped, so it does not ring about the target.
STIFFNESS = 4900.0
ROTATION_STIFFNESS = 4900.0
DAMPING_RATIO = 1.0
#: Null-space stiffness (1/s^2) and damping (1/s), per unit of joint inertia: keeps the elbow
#: near its starting configuration; soft, as it only resolves the arm's redundancy.
NULL_STIFFNESS = 25.0
NULL_DAMPING = 10.0

_VERTICAL = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def _gains(factor: float) -> tuple[float, float, float, float]:
    """Position stiffness and damping, orientation stiffness and damping, for stiffness
    `factor` times the nominal, critically damped (`DAMPING_RATIO`)."""
    stiffness, rotation_stiffness = STIFFNESS * factor, ROTATION_STIFFNESS * factor
    return (stiffness, 2 * DAMPING_RATIO * np.sqrt(stiffness),
            rotation_stiffness, 2 * DAMPING_RATIO * np.sqrt(rotation_stiffness))


class OscController(Controller):
    """Drives the Panda's torque motors with the operational-space law."""

    ARM_ACTUATION = "torque"

    def __init__(self, arena, panda, settings) -> None:
        super().__init__(arena, panda, settings)
        self._gain_scale = 1.0

    def scale_gains(self, physics, factor: float) -> None:
        """The law's stiffness times `factor`, set on the law as the episode starts."""
        self._gain_scale = float(factor)

    def initialize_episode(self, physics) -> None:
        super().initialize_episode(physics)
        cast(OscLaw, self.law).set_gain_scale(self._gain_scale)

    def _bind_law(self, physics) -> "OscLaw":
        panda = self._panda
        timestep = float(physics.model.opt.timestep)
        return OscLaw(self.settings, physics.model.ptr, physics.data.ptr, dict(
            self._law_ids(physics),
            arm_dofs=contiguous(physics.bind(panda.joints).dofadr, "arm dofs"),
            arm_qpos=contiguous(physics.bind(panda.joints).qposadr, "arm qpos addresses"),
            motors=contiguous(physics.bind(panda.arm_actuators).element_id, "arm motors"),
            torque_limits=np.asarray(panda.arm_torque_limits, dtype=np.float64),
            substeps_per_update=max(1, int(round(UPDATE_PERIOD / timestep)))))


class OscLaw(TcpTargetLaw):
    """The operational-space law on one MjData (see the module docstring). It works with
    MuJoCo's own routines on the data's factorised mass matrix (`mj_solveM`, `mj_mulM`),
    which the physics step has brought up to date, and preallocated arrays: it runs 250
    times per simulated second."""

    has_substep = True

    def __init__(self, settings, model, data, ids: dict) -> None:
        super().__init__(settings, model, data, ids)
        nv = model.nv
        self._site, self._every = ids["tcp_site"], ids["substeps_per_update"]
        arm = ids["arm_dofs"]
        self._limits = ids["torque_limits"]
        self._tcp_mat = data.site_xmat[self._site]
        self._q, self._qdot = data.qpos[ids["arm_qpos"]], data.qvel[arm]
        self._bias, self._torques = data.qfrc_bias[arm], data.ctrl[ids["motors"]]
        self._jacobian = np.zeros((6, nv))  # Position rows, then rotation rows.
        self._arm_jacobian_t = self._jacobian[:, arm].T
        self._jacobian_inverse_mass = np.zeros((6, nv))  # J M^-1
        self._inverse_inertia = np.zeros((6, 6))  # Lambda^-1 = J M^-1 J^T, then its Cholesky
        self._null_acceleration = np.zeros(nv)  # Zero outside the arm.
        self._arm_null_acceleration = self._null_acceleration[arm]
        self._null_force = np.zeros(nv)
        self._outside_arm = np.ones(nv, dtype=bool)
        self._outside_arm[arm] = False
        self._arm_null_force = self._null_force[arm]
        self._turning, self._moving = np.zeros(6), np.zeros(6)
        self._force, self._column = np.zeros(6), np.zeros(6)
        self._pressing = False  # Whether the target was kept from going into a surface.
        self._apparent_inertia = np.zeros(6)  # diag(Lambda), while pressing.
        self._rest = np.zeros(len(self._limits))
        self._orientation = np.zeros(4)  # The hand's wanted orientation (w, x, y, z).
        self._quat, self._inverse, self._turn = np.zeros(4), np.zeros(4), np.zeros(4)
        self._rotation_error = np.zeros(3)
        self._gains = _gains(1.0)
        self._phase = 0

    def set_gain_scale(self, factor: float) -> None:
        """Stiffness (position and orientation) times `factor`, still critically damped."""
        self._gains = _gains(factor)

    def reset(self) -> None:
        """Holds the hand where it starts, top-down at its starting yaw, the elbow at the
        starting configuration; the torque clock starts with the first physics step."""
        self._target[:] = self._tcp_pos
        self._rest[:] = self._q
        mujoco.mju_mat2Quat(self._orientation, self._tcp_mat)
        self._pressing = False
        self._factor_inertia()
        self._phase = 0

    def __call__(self, action: np.ndarray) -> None:
        """Sets this control step's target (and gripper command) for `action` (float64):
        the tool centre point plus `max_tcp_step` times the first three components, kept
        from running into the surface beneath the hand (`SurfaceGuard`)."""
        action = np.clip(action, -1.0, 1.0)
        self._pressing = self._set_target(action, self.vertical_stiffness())
        self.command_gripper(action)

    def substep(self) -> None:
        """New torques every `substeps_per_update` physics steps; held in between."""
        if self._phase % self._every == 0:
            self._update_torques()
        self._phase += 1

    def vertical_stiffness(self) -> float:
        """Newtons per metre the law pushes down with per metre its target lies below the
        hand, the hand held still: STIFFNESS times the hand's operational-space inertia
        along z, Lambda_zz (from the last torque update)."""
        mujoco.mju_cholSolve(self._column, self._inverse_inertia, _VERTICAL)
        return self._gains[0] * float(self._column[2])

    def _factor_inertia(self) -> None:
        """The Jacobian, J M^-1 and the Cholesky factor of Lambda^-1 = J M^-1 J^T, from the
        data's factorised mass matrix (brought up to date by the last physics step)."""
        model, data = self._model, self._data
        jacobian = self._jacobian
        mujoco.mj_jacSite(model, data, jacobian[:3], jacobian[3:], self._site)
        mujoco.mj_solveM(model, data, self._jacobian_inverse_mass, jacobian)
        np.matmul(jacobian, self._jacobian_inverse_mass.T, out=self._inverse_inertia)
        if self._pressing:
            self._apparent_inertia[:] = np.linalg.inv(self._inverse_inertia).diagonal()
        mujoco.mju_cholFactor(self._inverse_inertia, 0.0)

    def _update_torques(self) -> None:
        self._factor_inertia()
        stiffness, damping, rotation_stiffness, rotation_damping = self._gains
        velocity = self._qdot @ self._arm_jacobian_t
        # Orientation error: the rotation vector (world frame) from now to the wanted one.
        mujoco.mju_mat2Quat(self._quat, self._tcp_mat)
        mujoco.mju_negQuat(self._inverse, self._quat)
        mujoco.mju_mulQuat(self._turn, self._orientation, self._inverse)
        mujoco.mju_quat2Vel(self._rotation_error, self._turn, 1.0)
        turning, moving = self._turning, self._moving  # Rotational, translational parts.
        turning[3:] = rotation_stiffness * self._rotation_error - rotation_damping * velocity[3:]
        moving[:3] = stiffness * (self._target - self._tcp_pos) - damping * velocity[:3]
        # The null-space force M a_null, less what of it would move the hand:
        # J^T Lambda J M^-1 M a_null.
        self._arm_null_acceleration[:] = (NULL_STIFFNESS * (self._rest - self._q)
                                          - NULL_DAMPING * self._qdot)
        mujoco.mj_mulM(self._model, self._data, self._null_force, self._null_acceleration)
        null_force = self._null_force
        null_force[self._outside_arm] = 0.0  # Only the arm's motors apply it.
        mujoco.mju_cholSolve(self._force, self._inverse_inertia,
                             self._jacobian_inverse_mass @ null_force)
        null = self._arm_null_force - self._arm_jacobian_t @ self._force
        holding = self._arm_jacobian_t @ self._wrench(turning)
        moving = self._arm_jacobian_t @ self._wrench(moving) + null
        # Holding the hand's orientation comes first: its torques are scaled only if they
        # alone exceed a limit; the rest is scaled into what is left.
        limits, total = self._limits, self._bias.copy()
        total += _largest_scale(total, holding, limits) * holding
        total += _largest_scale(total, moving, limits) * moving
        np.clip(total, -limits, limits, out=self._torques)

    def _wrench(self, acceleration: np.ndarray) -> np.ndarray:
        """The hand's wrench for a wanted acceleration: Lambda a in free space. Pressing into
        a surface, the hand cannot accelerate into it, and Lambda's cross terms (a 136 N
        press comes with ~50 N sideways) would push it off what it presses, so there the
        law is a Cartesian impedance: each axis's spring alone, diag(Lambda) a."""
        if self._pressing:
            return self._apparent_inertia * acceleration
        mujoco.mju_cholSolve(self._force, self._inverse_inertia, acceleration)
        return self._force.copy()


def _largest_scale(base: np.ndarray, torques: np.ndarray, limits: np.ndarray) -> float:
    """The largest s in [0, 1] for which base + s * torques stays within +-limits."""
    total = base + torques
    if (np.abs(total) <= limits).all():
        return 1.0
    room = limits - base * np.sign(torques)  # Left by `base` in each torque's direction.
    scale = np.min(room / np.maximum(np.abs(torques), 1e-300))
    return min(max(float(scale), 0.0), 1.0)
