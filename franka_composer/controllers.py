"""End-effector control as the paper does it: a mocap body welded to the tool centre point.

Each control step the action's position part, scaled to at most `max_tcp_step` metres, is
added to the current tool-centre-point position and becomes the mocap target; the weld drags
the hand there during the physics substeps and holds it top-down. The gripper part, when the
gripper is actuated, changes the commanded finger width by at most `max_finger_step` metres.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from dm_env import specs

from franka_composer.entities.panda import MAX_FINGER_WIDTH, Panda
from franka_composer.surface_guard import BoundSurfaceGuard, SurfaceGuard

# Weld stiffness (critically damped, time constant in s). MuJoCo's default 0.02 s lets the
# hand lag a full command by ~40 % over a 0.05 s control step. A stiff 0.006 s tracks 99 %
# but covers each step's 5 cm in ~15 ms, a 3 m/s jab that flings and flips a pushed block
# (measured: 20 cm and a 180 deg tumble for an 8 cm push). 0.01 s tracks 95 % of a full
# command within the step, with a peak speed of ~1.8 m/s, and pushes the block flat.
WELD_TIMECONST = 0.01
_WELD_SOLREF = (WELD_TIMECONST, 1.0)
# Weld impedance d. Held still by a surface, MuJoCo makes a weld 1 / (1 - d) times stiffer
# than the spring of time constant WELD_TIMECONST it is in free space. At d = 0.99 (before)
# a hand pressing an object onto the floor was 100x stiffer than MuJoCo's default contacts
# and crushed them (objects 3-5 cm into the floor, then launched). In free space, though, a
# fraction 1 - d of the arm's own passive acceleration leaks past the weld: measured tilt of
# the hand after one full step 5.2 deg at d = 0.1, 3.3 at 0.5, 0.6 at 0.9, 0.14 at 0.99.
# 0.9 keeps the hand top-down and tracking (94 % of a full step), and makes a blocked weld
# 10x softer than before, while the contacts (`contacts.py`) are stiffer still; how deep the
# target may go into a surface, hence the force, is bounded by `SurfaceGuard`.
WELD_IMPEDANCE = 0.9
_WELD_SOLIMP = (WELD_IMPEDANCE, WELD_IMPEDANCE, 0.001, 0.5, 2.0)


@dataclasses.dataclass(frozen=True)
class ControlSettings:
    """How actions in [-1, 1] map to motion.

    Attributes:
      max_tcp_step: metres the tool centre point is commanded to move per control step for
        an action component of 1.
      max_finger_step: metres the finger width changes per control step for a gripper
        action of 1 (0.2 > 0.08: one full command opens or closes the hand).
      actuated_gripper: whether the action has a 4th, gripper, component; if not, the
        fingers are held closed.
    """

    max_tcp_step: float = 0.05
    max_finger_step: float = 0.2
    actuated_gripper: bool = False

    @property
    def action_size(self) -> int:
        return 4 if self.actuated_gripper else 3

    def tcp_action(self, tcp, target, max_speed: float = 1.0) -> np.ndarray:
        """The action law inverted: the position part of an action that takes the tool centre
        point from `tcp` to `target` (m) in one step if it is that close, else straight
        towards it at `max_speed` (a fraction of a full step). For scripted policies."""
        step = (np.asarray(target) - tcp) / self.max_tcp_step
        norm = np.linalg.norm(step)
        if norm > max_speed:
            step *= max_speed / norm
        return step


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
        self._surface_guard = SurfaceGuard(panda, self._weld, WELD_TIMECONST, WELD_IMPEDANCE)
        self._law = self._law_physics = None

    @property
    def settings(self) -> ControlSettings:
        return self._settings

    @property
    def surface_guard(self) -> SurfaceGuard:
        """What keeps the target from running into the surface beneath the hand."""
        return self._surface_guard

    @property
    def target(self):
        """The mocap body the tool centre point is welded to."""
        return self._target

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def initialize_episode(self, physics) -> None:
        """Puts the mocap target on the tool centre point, so the weld starts slack, and
        binds the action law to this physics (once per compiled model).

        Call after the arm is configured and `physics.forward()` has run."""
        tcp = physics.bind(self._panda.tcp_site)
        quat = np.empty(4)
        _mat2quat(tcp.xmat, quat)
        target = physics.bind(self._target)
        target.mocap_pos = tcp.xpos
        target.mocap_quat = quat
        if self._law is None or self._law_physics is not physics:
            self._law = MocapLaw.bind(self, physics)
            self._law_physics = physics

    @property
    def law(self) -> "MocapLaw":
        """The action law bound to the current physics (bound at the first reset)."""
        if self._law is None:
            raise RuntimeError("the controller's action law is bound at the first reset: "
                               "reset the environment first")
        return self._law

    def validate(self, action) -> np.ndarray:
        """The action as a float64 vector; a clear error for anything but real numbers
        (strings, objects, complex, bools), a wrong shape or a non-finite value, before
        anything reaches MuJoCo."""
        raw = np.asarray(action)
        if raw.dtype.kind not in "iuf":
            raise ValueError(f"action must be an array of real numbers "
                             f"({_describe(self._settings)}), got dtype {raw.dtype}")
        array = raw.astype(np.float64, copy=False)
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
        """Sets the mocap target (and gripper command) for the next control step."""
        self._law(self.validate(action))


class MocapLaw:
    """The action law, on one MjModel / MjData: what an action does to the mocap target and
    the gripper servo. The controller calls it each step; the benchmark's bare-MuJoCo floor
    calls the same law on its own copy of the model (`on`).

    Components are clipped to [-1, 1], as in Fetch. The target is the tool centre point plus
    `max_tcp_step` times the first three, kept from running into the surface beneath the hand
    (`SurfaceGuard`); the gripper servo gets the finger width plus `max_finger_step` times
    the fourth, within [0, MAX_FINGER_WIDTH]. Reads and writes go through NumPy views of the
    data's arrays (a dm_control binding costs microseconds per call; this runs every step).
    """

    def __init__(self, settings: ControlSettings, model, data, *, tcp_site: int, mocap: int,
                 fingers: tuple[int, int], gripper: int, guard: BoundSurfaceGuard) -> None:
        self._settings = settings
        self._ids = dict(tcp_site=tcp_site, mocap=mocap, fingers=fingers, gripper=gripper)
        self._tcp_pos = data.site_xpos[tcp_site]
        self._mocap_pos = data.mocap_pos[mocap]
        self._qpos, self._ctrl = data.qpos, data.ctrl
        self._fingers, self._gripper = fingers, gripper
        self._guard = guard

    @classmethod
    def bind(cls, controller: MocapController, physics) -> "MocapLaw":
        panda = controller._panda  # pylint: disable=protected-access
        left, right = (int(a) for a in physics.bind(panda.finger_joints).qposadr)
        model = physics.model.ptr
        return cls(controller.settings, model, physics.data.ptr,
                   tcp_site=int(physics.bind(panda.tcp_site).element_id),
                   mocap=int(model.body(controller.target.full_identifier).mocapid[0]),
                   fingers=(left, right),
                   gripper=int(physics.bind(panda.gripper_actuator).element_id),
                   guard=controller.surface_guard.bind(physics))

    def on(self, model, data) -> "MocapLaw":
        """The same law on another MjData of the same model (e.g. a copy)."""
        return MocapLaw(self._settings, model, data, guard=self._guard.on(model, data),
                        **self._ids)

    @property
    def guard(self) -> BoundSurfaceGuard:
        """What keeps the target from running into the surface beneath the hand."""
        return self._guard

    def finger_width(self) -> float:
        """Distance between the fingers (m): the sum of the two finger joints' slides."""
        left, right = self._fingers
        return float(self._qpos[left] + self._qpos[right])

    def __call__(self, action: np.ndarray) -> None:
        """Writes the mocap target (and gripper command) for `action` (float64)."""
        action = np.clip(action, -1.0, 1.0)
        settings, tcp = self._settings, self._tcp_pos
        target = tcp + settings.max_tcp_step * action[:3]
        target[2] = self._guard.guard(tcp, target)
        self._mocap_pos[:] = target
        if settings.actuated_gripper:
            width = self.finger_width() + settings.max_finger_step * action[3]
            self._ctrl[self._gripper] = min(max(width, 0.0), MAX_FINGER_WIDTH)


def _describe(settings: ControlSettings) -> str:
    return "dx, dy, dz, gripper" if settings.actuated_gripper else "dx, dy, dz"


def _mat2quat(xmat: np.ndarray, out: np.ndarray) -> None:
    import mujoco

    mujoco.mju_mat2Quat(out, np.ascontiguousarray(xmat, dtype=np.float64).ravel())
