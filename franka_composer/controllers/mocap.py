"""End-effector control as the paper does it: a mocap body welded to the tool centre point.

Each control step the action's position part, scaled to at most `max_tcp_step` metres, is
added to the current tool-centre-point position and becomes the mocap target; the weld drags
the hand there during the physics substeps and holds it top-down. The gripper part, when the
gripper is actuated, changes the commanded finger width by at most `max_finger_step` metres.
"""

from __future__ import annotations

import mujoco
import numpy as np

from franka_composer.controllers.base import Controller, TcpTargetLaw

# The weld's stiffness is the settings' (`ControlSettings.weld_time_constant`, the reasons
# beside it). Weld impedance d: held still by a surface, MuJoCo makes a weld 1 / (1 - d) times
# stiffer than the spring of its time constant it is in free space. At d = 0.99 (before) a
# hand pressing an object onto the floor was 100x stiffer than MuJoCo's default contacts
# and crushed them (objects 3-5 cm into the floor, then launched). In free space, though, a
# fraction 1 - d of the arm's own passive acceleration leaks past the weld: measured tilt of
# the hand after one full step along x 5.2 deg at d = 0.1, 3.3 at 0.5, 0.6 at 0.9, 0.14 at 0.99.
# 0.9 keeps the hand top-down and tracking (94 % of a full step), and makes a blocked weld
# 10x softer than before, while the contacts (`contacts.py`) are stiffer still; how deep the
# target may go into a surface, hence the force, is bounded by `SurfaceGuard`.
WELD_IMPEDANCE = 0.9
_WELD_SOLIMP = (WELD_IMPEDANCE, WELD_IMPEDANCE, 0.001, 0.5, 2.0)
_EQUALITY = mujoco.mjtConstraint.mjCNSTR_EQUALITY



class MocapController(Controller):
    """Adds a mocap body and a weld to the arena, and turns actions into mocap targets."""

    ARM_ACTUATION = "none"

    def __init__(self, arena, panda, settings) -> None:
        super().__init__(arena, panda, settings)
        root = arena.mjcf_model
        # Mocap bodies must hang from the world body, so the target lives in the arena.
        self._target = root.worldbody.add("body", name="tcp_target", mocap=True)
        target_site = self._target.add("site", name="tcp_target", size=(0.005,),
                                       rgba=(0, 1, 0, 0.5), group=4)
        self._weld = root.equality.add("weld", name="tcp_weld", site1=target_site,
                                       site2=panda.tcp_site,
                                       solref=(settings.weld_time_constant, 1.0),
                                       solimp=_WELD_SOLIMP)

    @property
    def target(self):
        """The mocap body the tool centre point is welded to."""
        return self._target

    def initialize_episode(self, physics) -> None:
        """Binds the law, and puts the mocap target on the tool centre point so the weld
        starts slack. Written through bindings: dm_control then brings the constraint up
        to date (`mj_forward`) before the next read."""
        super().initialize_episode(physics)
        tcp = physics.bind(self._panda.tcp_site)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(tcp.xmat, dtype=np.float64).ravel())
        target = physics.bind(self._target)
        target.mocap_pos = tcp.xpos
        target.mocap_quat = quat

    def scale_gains(self, physics, factor: float) -> None:
        """The weld's stiffness times `factor`: its time constant over sqrt(factor), still
        critically damped."""
        physics.bind(self._weld).solref = (self.settings.weld_time_constant / np.sqrt(factor),
                                           1.0)

    def _bind_law(self, physics) -> "MocapLaw":
        model = physics.model.ptr
        return MocapLaw(self.settings, model, physics.data.ptr, dict(
            self._law_ids(physics),
            mocap=int(model.body(self._target.full_identifier).mocapid[0]),
            weld=int(physics.bind(self._weld).element_id)))


class MocapLaw(TcpTargetLaw):
    """The mocap action law. Components are clipped to [-1, 1], as in Fetch. The target is
    the tool centre point plus `max_tcp_step` times the first three, kept from running into
    the surface beneath the hand (`SurfaceGuard`); the gripper as every controller's."""

    def __init__(self, settings, model, data, ids: dict) -> None:
        super().__init__(settings, model, data, ids)
        self._mocap_pos = data.mocap_pos[ids["mocap"]]
        self._weld = ids["weld"]
        self._solref, self._solimp = model.eq_solref[self._weld], model.eq_solimp[self._weld]

    def press_stiffness(self) -> float:
        """Newtons per metre the weld pushes with when held still below its target: MuJoCo
        holds a weld row of regulariser R = 1 / D, impedance d and time constant tc,
        blocked at depth r, with the force r D / (d tc^2); read from its vertical row (a
        weld's first three rows are x, y, z; equality rows come first)."""
        data = self._data
        rows = np.flatnonzero((data.efc_type[:data.ne] == _EQUALITY)
                              & (data.efc_id[:data.ne] == self._weld))
        compliance = self._solimp[0] * self._solref[0] ** 2  # s^2: d tc^2
        return float(data.efc_D[rows[2]]) / compliance

    def __call__(self, action: np.ndarray) -> None:
        """Writes the mocap target (and gripper command) for `action` (float64)."""
        action = np.clip(action, -1.0, 1.0)
        self._set_target(action, self.press_stiffness())
        self._mocap_pos[:] = self._target
        self.command_gripper(action)
