"""End-effector control as the paper does it: a mocap body welded to the tool centre point.

Each control step the action's position part, scaled to at most `max_tcp_step` metres, is
added to the current tool-centre-point position and becomes the mocap target; the weld drags
the hand there during the physics substeps and holds it top-down. The gripper part, when the
gripper is actuated, changes the commanded finger width by at most `max_finger_step` metres.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from dm_env import specs

from franka_composer.entities.panda import MAX_FINGER_WIDTH, Panda

# Weld stiffness (critically damped, time constant in s). MuJoCo's default 0.02 s lets the
# hand lag a full command by ~40 % over a 0.05 s control step. A stiff 0.006 s tracks 99 %
# but covers each step's 5 cm in ~15 ms, a 3 m/s jab that flings and flips a pushed block
# (measured: 20 cm and a 180 deg tumble for an 8 cm push). 0.01 s tracks 95 % of a full
# command within the step, with a peak speed of ~1.8 m/s, and pushes the block flat.
_WELD_SOLREF = (0.01, 1.0)
_WELD_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)


@dataclasses.dataclass(frozen=True)
class ControlSettings:
    """How actions in [-1, 1] map to motion.

    Attributes:
      max_tcp_step: metres the tool centre point is commanded to move per control step for
        an action component of 1.
      max_finger_step: metres the finger width changes per control step for a gripper
        action of 1 (0.2 > 0.08: one full command opens or closes the hand).
      actuated_gripper: whether the action has a 4th, gripper, component; if not, the
        fingers are held at `locked_finger_width`.
      locked_finger_width: finger width (m) held when the gripper is not actuated.
      min_tcp_height: lowest commanded tool-centre-point height (m, world frame).
    """

    max_tcp_step: float = 0.05
    max_finger_step: float = 0.2
    actuated_gripper: bool = False
    locked_finger_width: float = 0.0
    min_tcp_height: float = 0.0

    @property
    def action_size(self) -> int:
        return 4 if self.actuated_gripper else 3


class MocapController:
    """Adds a mocap body and a weld to the arena, and turns actions into mocap targets."""

    def __init__(self, arena, panda: Panda, settings: ControlSettings) -> None:
        self._panda = panda
        self._settings = settings
        root = arena.mjcf_model
        # Mocap bodies must hang from the world body, so the target lives in the arena.
        self._target = root.worldbody.add("body", name="tcp_target", mocap=True)
        target_site = self._target.add("site", name="tcp_target", size=(0.005,),
                                       rgba=(0, 1, 0, 0.5), group=4)
        self._weld = root.equality.add("weld", name="tcp_weld", site1=target_site,
                                       site2=panda.tcp_site, solref=_WELD_SOLREF,
                                       solimp=_WELD_SOLIMP)
        self._action_spec = specs.BoundedArray(
            shape=(settings.action_size,), dtype=np.float32, minimum=-1.0, maximum=1.0,
            name="tcp_delta_and_gripper" if settings.actuated_gripper else "tcp_delta",
        )

    @property
    def settings(self) -> ControlSettings:
        return self._settings

    @property
    def target(self):
        """The mocap body the tool centre point is welded to."""
        return self._target

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def initialize_episode(self, physics) -> None:
        """Puts the mocap target on the tool centre point, so the weld starts slack, and
        takes the views `apply` reads and writes each step.

        Call after the arm is configured and `physics.forward()` has run."""
        tcp = physics.bind(self._panda.tcp_site)
        quat = np.empty(4)
        _mat2quat(tcp.xmat, quat)
        target = physics.bind(self._target)
        target.mocap_pos = tcp.xpos
        target.mocap_quat = quat
        self._views = _StepViews.of(physics, self._panda, self._target)

    def validate(self, action) -> np.ndarray:
        """The action as a float64 vector; a clear error for a wrong shape or a non-finite
        value, before anything reaches MuJoCo."""
        array = np.asarray(action, dtype=np.float64)
        expected = self._action_spec.shape
        if array.shape != expected:
            raise ValueError(
                f"action must have shape {expected} ({_describe(self._settings)}), "
                f"got shape {array.shape}"
            )
        if not np.isfinite(array).all():
            raise ValueError(f"action must be finite, got {array.tolist()}")
        return array

    def apply(self, physics, action) -> None:
        """Sets the mocap target (and gripper command) for the next control step.

        Components are clipped to [-1, 1], as in Fetch. Reads and writes go through the
        views taken at the episode's start (physics.bind costs a few microseconds a call,
        and this runs every step)."""
        action = np.clip(self.validate(action), -1.0, 1.0)
        settings, views = self._settings, self._views
        target = views.tcp_pos + settings.max_tcp_step * action[:3]
        target[2] = max(target[2], settings.min_tcp_height)
        views.mocap_pos[:] = target
        if settings.actuated_gripper:
            width = views.finger_width() + settings.max_finger_step * action[3]
            views.ctrl[views.gripper] = min(max(width, 0.0), MAX_FINGER_WIDTH)


class _StepViews(NamedTuple):
    """NumPy views into one physics' MjData, valid while that physics lives: Composer
    builds a new physics only on recompiling, and then initialises the episode again."""

    tcp_pos: np.ndarray  # The tool centre point's xpos (3,).
    mocap_pos: np.ndarray  # The target's mocap_pos (3,).
    qpos: np.ndarray
    fingers: tuple[int, int]  # qpos addresses of the two finger joints.
    ctrl: np.ndarray
    gripper: int  # The gripper servo's index in ctrl.

    @classmethod
    def of(cls, physics, panda: Panda, target) -> "_StepViews":
        left, right = (int(a) for a in physics.bind(panda.finger_joints).qposadr)
        return cls(tcp_pos=physics.bind(panda.tcp_site).xpos.view(np.ndarray),
                   mocap_pos=physics.bind(target).mocap_pos.view(np.ndarray),
                   qpos=physics.data.qpos, fingers=(left, right), ctrl=physics.data.ctrl,
                   gripper=int(physics.bind(panda.gripper_actuator).element_id))

    def finger_width(self) -> float:
        """Distance between the fingers (m): the sum of the two finger joints' slides."""
        left, right = self.fingers
        return float(self.qpos[left] + self.qpos[right])


def _describe(settings: ControlSettings) -> str:
    return "dx, dy, dz, gripper" if settings.actuated_gripper else "dx, dy, dz"


def _mat2quat(xmat: np.ndarray, out: np.ndarray) -> None:
    import mujoco

    mujoco.mju_mat2Quat(out, np.ascontiguousarray(xmat, dtype=np.float64).ravel())
