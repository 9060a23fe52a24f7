"""What every controller shares: the action spec, action checks, the gripper, the surface
guard, binding.

A controller is built with the task (it may add elements to the arena, as the mocap body)
and owns the action law. The law itself (`ActionLaw`) works on one MjModel / MjData through
NumPy views of the data's arrays, because it runs every step (a dm_control binding costs
microseconds per call), and can be moved onto a copy of the model (`on`) so the benchmark's
bare-MuJoCo floor drives its copy with the env's own law.
"""

from __future__ import annotations

import numpy as np
from dm_env import specs

from franka_composer.controllers.settings import ControlSettings
from franka_composer.entities.panda import MAX_FINGER_WIDTH, Panda
from franka_composer.surface_guard import BoundSurfaceGuard, SurfaceGuard


class ActionLaw:
    """An action law on one MjData: `__call__(action)` once per control step, `substep()`
    before every physics step where the law has one (`has_substep`), `reset()` at each
    episode start, after the arm is configured and `mj_forward` has run."""

    #: Whether `substep` must run before every physics step (a torque law does).
    has_substep = False

    def __init__(self, settings: ControlSettings, model, data, ids: dict) -> None:
        self._settings, self._model, self._data, self._ids = settings, model, data, ids
        self._qpos, self._ctrl = data.qpos, data.ctrl
        self._fingers, self._gripper = ids["fingers"], ids["gripper"]
        self._tcp_pos = data.site_xpos[ids["tcp_site"]]
        self._guard = ids["guard"]

    def on(self, model, data) -> "ActionLaw":
        """The same law on another MjData of the same model (e.g. a copy)."""
        return type(self)(self._settings, model, data,
                          dict(self._ids, guard=self._guard.on(model, data)))

    @property
    def guard(self) -> BoundSurfaceGuard:
        """What keeps the hand from being driven into the surface beneath it."""
        return self._guard

    def finger_width(self) -> float:
        """Distance between the fingers (m): the sum of the two finger joints' slides."""
        left, right = self._fingers
        return float(self._qpos[left] + self._qpos[right])

    def command_gripper(self, action: np.ndarray) -> None:
        """The gripper servo gets the finger width plus `max_finger_step` times the last
        component, within [0, MAX_FINGER_WIDTH], where the gripper is actuated."""
        if self._settings.actuated_gripper:
            width = self.finger_width() + self._settings.max_finger_step * action[-1]
            self._ctrl[self._gripper] = min(max(width, 0.0), MAX_FINGER_WIDTH)

    def reset(self) -> None:
        """Starts an episode from the configured state (nothing to do by default)."""

    def substep(self) -> None:
        """Runs before every physics step where `has_substep`."""

    def __call__(self, action: np.ndarray) -> None:
        raise NotImplementedError


class TcpTargetLaw(ActionLaw):
    """A law that sends the tool centre point towards a target each control step (mocap's
    weld, osc's torques): the target, kept from running into the surface beneath the hand
    (`SurfaceGuard`), is worked out here for both."""

    def __init__(self, settings, model, data, ids: dict) -> None:
        super().__init__(settings, model, data, ids)
        self._target = np.zeros(3)

    def _set_target(self, action: np.ndarray, stiffness: float) -> bool:
        """Sets the target to the tool centre point plus `max_tcp_step` times the first three
        components of `action` (clipped), no deeper than the guard allows for a spring of
        `stiffness` (N/m); returns whether the guard raised it (the hand presses)."""
        tcp, target = self._tcp_pos, self._target
        np.add(tcp, self._settings.max_tcp_step * action[:3], out=target)
        wanted = target[2]
        target[2] = self._guard.guard(tcp, target, stiffness)
        return target[2] > wanted


class Controller:
    """Turns actions into commands for one Panda; subclasses say how (`_bind_law`) and
    how the arm must be actuated for it (`ARM_ACTUATION`, read by the task builder)."""

    #: `Panda(arm_actuation=...)` this controller drives.
    ARM_ACTUATION = "none"

    def __init__(self, arena, panda: Panda, settings: ControlSettings) -> None:
        if panda.arm_actuation != self.ARM_ACTUATION:
            raise ValueError(f"the {settings.kind} controller drives a Panda built with "
                             f"arm_actuation={self.ARM_ACTUATION!r}, got "
                             f"{panda.arm_actuation!r}")
        self._panda, self._settings = panda, settings
        self._surface_guard = SurfaceGuard(panda, settings.guard_ignores_carried)
        # Bounds of the action's own shape, as dm_control's suites give them: an agent may
        # take spec.minimum as an action (scalar bounds are dm_env-legal but are no action).
        shape = (settings.action_size,)
        self._action_spec = specs.BoundedArray(
            shape=shape, dtype=np.float32, minimum=np.full(shape, -1.0, np.float32),
            maximum=np.full(shape, 1.0, np.float32), name=settings.action_name)
        self._law: ActionLaw | None = None
        self._law_physics = None

    @property
    def settings(self) -> ControlSettings:
        return self._settings

    def action_spec(self) -> specs.BoundedArray:
        return self._action_spec

    def initialize_episode(self, physics) -> None:
        """Binds the action law to this physics (once per compiled model) and resets it.

        Call after the arm is configured and `physics.forward()` has run."""
        if self._law is None or self._law_physics is not physics:
            self._law = self._bind_law(physics)
            self._law_physics = physics
        self._law.reset()

    def _bind_law(self, physics) -> ActionLaw:
        raise NotImplementedError

    def scale_gains(self, physics, factor: float) -> None:
        """Scales the controller's stiffness by `factor` from the next step on, each
        controller keeping its damping rule (domain randomisation; no recompilation)."""
        raise NotImplementedError

    def _law_ids(self, physics) -> dict:
        """What every law needs: the finger joints' qpos addresses, the gripper servo, the
        tool centre point's site and the surface guard bound to the physics."""
        left, right = (int(a) for a in physics.bind(self._panda.finger_joints).qposadr)
        return dict(fingers=(left, right),
                    gripper=int(physics.bind(self._panda.gripper_actuator).element_id),
                    tcp_site=int(physics.bind(self._panda.tcp_site).element_id),
                    guard=self._surface_guard.bind(physics))

    @property
    def law(self) -> ActionLaw:
        """The action law bound to the current physics (bound at the first reset)."""
        if self._law is None:
            raise RuntimeError("the controller's action law is bound at the first reset: "
                               "reset the environment first")
        return self._law

    @property
    def substep_law(self):
        """What must run before every physics step (the law's `substep`), or None."""
        law = self._law
        return law.substep if law is not None and law.has_substep else None

    def validate(self, action) -> np.ndarray:
        """The action as a float64 vector; a clear error for anything but real numbers
        (strings, objects, complex, bools), a wrong shape or a non-finite value, before
        anything reaches MuJoCo."""
        raw = np.asarray(action)
        described = self._settings.describe_action()
        if raw.dtype.kind not in "iuf":
            raise ValueError(f"action must be an array of real numbers ({described}), got "
                             f"dtype {raw.dtype}")
        array = raw.astype(np.float64, copy=False)
        expected = self._action_spec.shape
        if array.shape != expected:
            raise ValueError(f"action must have shape {expected} ({described}), got shape "
                             f"{array.shape}")
        if not np.isfinite(array).all():
            raise ValueError(f"action must be finite, got {array.tolist()}")
        return array

    def apply(self, physics, action, perturb=None) -> None:
        """Sets the commands for the next control step; `perturb` (e.g. action noise) acts
        on the checked action."""
        action = self.validate(action)
        self.law(action if perturb is None else perturb(action))


def contiguous(indices, what: str) -> slice:
    """`indices` (consecutive ints) as a slice, for views rather than copies."""
    indices = [int(i) for i in indices]
    if indices != list(range(indices[0], indices[0] + len(indices))):
        raise ValueError(f"{what} are not consecutive: {indices}")
    return slice(indices[0], indices[0] + len(indices))
