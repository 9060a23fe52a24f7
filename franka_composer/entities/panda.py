"""The Franka Emika Panda (arm and parallel gripper) from MuJoCo Menagerie.

Menagerie's `panda.xml` is loaded as it is and changed here, in code, for what the tasks
need: the keyframe goes (it breaks once props add free joints), the arm is actuated as its
controller needs (`ARM_ACTUATIONS`), a tool-centre-point site is added between the
fingertips, the gripper servo takes a finger width in metres, and only the hand and fingers
collide, with the objects and the floor.
"""

from __future__ import annotations

import pathlib

import numpy as np
from dm_control import composer, mjcf
from dm_control.composer import define

from franka_composer import assets
from franka_composer.entities.features import ArrayFeature
from franka_composer.validation import check_choice

#: Neutral arm configuration (rad), hand pointing straight down above the workspace.
NEUTRAL_ARM_QPOS = (0.00, 0.41, 0.00, -1.85, 0.00, 2.26, 0.79)

#: Largest opening between the fingers (m): each finger slides 0.04.
MAX_FINGER_WIDTH = 0.08

#: Menagerie's geom groups for the Panda: visual meshes, and collision hulls.
VISUAL_GROUP, COLLISION_GROUP = 2, 3

#: Tool centre point: between the fingertips, this far from the hand body along its z axis
#: (panda-gym's grasp target).
TCP_OFFSET = 0.105

#: The wrist camera, in the hand's frame: 6 cm to the side of the hand's axis (clear of the
#: fingers, which open along y) and 2 cm below the flange, looking at a point 5.5 cm past
#: the tool centre point, image rows along the fingers' opening, as cameras mounted on real
#: Panda hands see the grasp. MuJoCo cameras look along their -z axis.
WRIST_CAMERA = dict(pos=(0.06, 0.0, 0.02), xyaxes=(0, 1, 0, 0.919, 0, 0.394), fovy=60)

_ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
_FINGER_JOINTS = ("finger_joint1", "finger_joint2")
_ARM_ACTUATORS = tuple(f"actuator{i}" for i in range(1, 8))
_GRIPPER_ACTUATOR = "actuator8"
_MOVING_BODIES = tuple(f"link{i}" for i in range(1, 8)) + ("hand", "left_finger", "right_finger")
_FINGER_BODIES = ("left_finger", "right_finger")
_COLLIDING_BODIES = ("hand",) + _FINGER_BODIES

# Gripper servo on the finger tendon (tendon length = half the finger width). Menagerie's
# gain of 100 N/m squeezes a 4 cm block with only 1 N per finger, which lets a 0.1 kg block
# slip out when lifted; 1000 N/m gives 10 N per finger, about 20 N of friction against 1 N of
# weight, still well inside Menagerie's +-100 N force range and the real hand's 70 N.
_GRIPPER_STIFFNESS = 1000.0
_GRIPPER_DAMPING = 30.0

# Finger contacts: rubber-like sliding friction of 2 (MuJoCo uses the larger of the two
# geoms' values) keeps a squeezed block from creeping down while it is lifted (measured: 3 mm
# of creep over a 0.15 m lift and 0.1 m carry, against 8 mm at friction 1); torsional friction
# (condim 4) stops it pivoting about the pad normal, which Menagerie's condim 3 allows.
_FINGER_CONDIM = 4
_FINGER_FRICTION = (2.0, 0.005, 0.0001)

#: How the arm can be driven, one per controller: "none" (no arm actuators: a mocap weld
#: moves the hand, and servos would fight it), "torque" (a motor per joint, within the real
#: Panda's torque limits) or "position" (Menagerie's servos). Under "none" and "position"
#: the links compensate their own weight (MuJoCo's gravcomp), as the real Panda's joint
#: controller does, so the weld or the servos only move the arm; under "torque" the control
#: law must hold the arm up itself, within the limits.
ARM_ACTUATIONS = ("none", "torque", "position")

#: Derivative time (s) of the arm's position servos: damping = stiffness x this. Menagerie's
#: 0.1 s (damping 450 N m s on joint 1) overdamps the servos 2-7x, so a 0.05 rad target step
#: moves a joint only 37 % of the way within a 0.05 s control step, and zero actions leave
#: it there. At 0.015 s a first step from rest moves a joint 83-101 % of the way within
#: the control step (from the neutral pose, joint by joint); a joint already moving carries
#: on past its target, 110-124 % of it on joints 1-4 (experiments/joint_tracking.py).
SERVO_DERIVATIVE_TIME = 0.015

#: Collision bits: robot geoms collide with everything but each other.
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 1, 0


def _parsed(xml: pathlib.Path) -> mjcf.RootElement:
    """Menagerie's Panda as dm_control's MJCF tree; one that is not XML (a truncated or
    edited copy under MENAGERIE_ROOT) a `MenagerieUnavailableError` naming the file, where
    lxml's syntax error came as a traceback."""
    try:
        return mjcf.from_path(str(xml))
    except SyntaxError as error:  # lxml.etree.XMLSyntaxError is one.
        raise assets.MenagerieUnavailableError(
            f"{xml} is not Menagerie's Panda: it is not well-formed XML ({error.msg}); a damaged "
            "or edited copy? Point MENAGERIE_ROOT at a whole one") from None


class Panda(composer.Robot):
    """Menagerie's Panda with a tool-centre-point site and a width-controlled gripper."""

    def _build(self, name: str = "panda", visual_meshes: bool = True,
               arm_actuation: str = "none") -> None:
        """`visual_meshes=False` leaves out the visual geoms and the meshes only they use
        (34 MB of mesh files and 35 MB compiled, per env): for envs that never render. The
        visual geoms have no mass (every body has its own inertial) and no contacts, so
        the simulation is the same. `arm_actuation` is one of `ARM_ACTUATIONS`."""
        check_choice("arm_actuation", arm_actuation, ARM_ACTUATIONS)
        self._arm_actuation = arm_actuation
        self._has_visual_meshes = bool(visual_meshes)
        self._mjcf_root = _parsed(assets.panda_xml())
        self._mjcf_root.model = name
        if not visual_meshes:
            _remove_visual_geoms(self._mjcf_root)
        if self._mjcf_root.keyframe is not None:
            for key in self._mjcf_root.keyframe.all_children():
                key.remove()
        # The real arm's joint torque limits (Menagerie's servo force ranges: 87 N m on joints
        # 1-4, 12 N m on 5-7), read before the servos may go: the torque motors take them,
        # and they bound how hard a mocap-driven hand may press (`surface_guard.py`).
        self._arm_torque_limits = tuple(
            _force_limit(self._mjcf_root.find("actuator", name)) for name in _ARM_ACTUATORS)
        self._arm_actuators = self._configure_arm(arm_actuation)
        self._configure_collisions()
        self._configure_gripper()

        hand = self._mjcf_root.find("body", "hand")
        self._tcp_site = hand.add(
            "site", name="tcp", pos=(0, 0, TCP_OFFSET), size=(0.005,), rgba=(1, 0.5, 0, 0.6),
            group=4,
        )
        self._tcp_velocity = self._mjcf_root.sensor.add(
            "framelinvel", name="tcp_velocity", objtype="site", objname=self._tcp_site
        )
        self._hand = hand
        self._wrist_camera = hand.add("camera", name="wrist", **WRIST_CAMERA)
        self._arm_joints = tuple(self._mjcf_root.find("joint", j) for j in _ARM_JOINTS)
        self._finger_joints = tuple(self._mjcf_root.find("joint", j) for j in _FINGER_JOINTS)
        self._gripper_actuator = self._mjcf_root.find("actuator", _GRIPPER_ACTUATOR)

    def _configure_arm(self, arm_actuation: str) -> tuple:
        """The arm's actuators (joint 1 first) for `arm_actuation`, and gravity compensation
        in the links where the actuation relies on it."""
        servos = [self._mjcf_root.find("actuator", name) for name in _ARM_ACTUATORS]
        for body_name in _MOVING_BODIES:
            self._mjcf_root.find("body", body_name).gravcomp = int(arm_actuation != "torque")
        if arm_actuation == "position":
            for servo in servos:
                stiffness = float(servo.gainprm[0])
                servo.biasprm = (0, -stiffness, -stiffness * SERVO_DERIVATIVE_TIME)
            return tuple(servos)
        for servo in servos:
            servo.remove()
        if arm_actuation == "none":
            return ()
        return tuple(
            self._mjcf_root.actuator.add(
                "motor", name=f"torque{index + 1}", joint=f"joint{index + 1}",
                ctrlrange=(-limit, limit), forcerange=(-limit, limit))
            for index, limit in enumerate(self._arm_torque_limits))

    def _configure_collisions(self) -> None:
        """Only the hand and fingers collide (with props and floor): the links never reach
        the workspace in a top-down pose, and skipping their meshes saves collision tests."""
        colliding = {self._mjcf_root.find("body", b) for b in _COLLIDING_BODIES}
        for geom in self._mjcf_root.find_all("geom"):
            if geom.dclass is not None and geom.dclass.dclass == "visual":
                continue
            if geom.parent in colliding:
                geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
            else:
                geom.contype, geom.conaffinity = 0, 0
            if geom.parent.name in _FINGER_BODIES:
                geom.condim, geom.friction = _FINGER_CONDIM, _FINGER_FRICTION

    def _configure_gripper(self) -> None:
        """The gripper servo's control is the finger width in metres, in [0, 0.08]."""
        actuator = self._mjcf_root.find("actuator", _GRIPPER_ACTUATOR)
        actuator.ctrlrange = (0.0, MAX_FINGER_WIDTH)
        # force = k * (ctrl / 2 - tendon) - d * tendon_velocity, tendon = width / 2.
        actuator.gainprm = (_GRIPPER_STIFFNESS / 2, 0, 0)
        actuator.biasprm = (0, -_GRIPPER_STIFFNESS, -_GRIPPER_DAMPING)

    def _build_observables(self) -> "PandaObservables":
        return PandaObservables(self)

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        return self._mjcf_root

    @property
    def actuators(self) -> tuple:
        """The arm's actuators (none under mocap control), then the gripper servo."""
        return (*self._arm_actuators, self._gripper_actuator)

    @property
    def arm_actuation(self) -> str:
        """How the arm is driven: one of `ARM_ACTUATIONS`."""
        return self._arm_actuation

    @property
    def arm_actuators(self) -> tuple:
        """The arm's torque motors or position servos, joint 1 first (none under mocap)."""
        return self._arm_actuators

    @property
    def gripper_actuator(self):
        return self._gripper_actuator

    @property
    def joints(self) -> tuple:
        """The seven arm joints."""
        return self._arm_joints

    @property
    def arm_joint_ranges(self) -> tuple[tuple[float, float], ...]:
        """Each arm joint's (lowest, highest) angle (rad), joint 1 first."""
        ranges = (_resolved(joint, "joint", "range") for joint in self._arm_joints)
        return tuple((float(lowest), float(highest)) for lowest, highest in ranges)

    def check_arm_qpos(self, name: str, qpos) -> None:
        """A ValueError naming `name` unless every angle lies within its joint's range."""
        for index, (angle, (low, high)) in enumerate(zip(qpos, self.arm_joint_ranges)):
            if not low <= angle <= high:
                raise ValueError(f"{name}[{index}] = {angle!r} is outside joint{index + 1}'s "
                                 f"range [{low:g}, {high:g}] rad")

    @property
    def arm_torque_limits(self) -> tuple[float, ...]:
        """Largest torque (N m) each arm joint can exert, joint 1 first (the real Panda's)."""
        return self._arm_torque_limits

    @property
    def colliding_bodies(self) -> tuple:
        """The bodies whose geoms touch the world: the hand and the two fingers."""
        return tuple(self._mjcf_root.find("body", b) for b in _COLLIDING_BODIES)

    @property
    def finger_joints(self) -> tuple:
        return self._finger_joints

    @property
    def hand(self):
        """The hand body; the mocap weld attaches here through `tcp_site`."""
        return self._hand

    @property
    def has_visual_meshes(self) -> bool:
        """Whether the model has Menagerie's visual meshes (`visual_meshes`)."""
        return self._has_visual_meshes

    @property
    def wrist_camera(self):
        """The camera on the hand (`WRIST_CAMERA`)."""
        return self._wrist_camera

    @property
    def tcp_velocity(self):
        """Sensor: linear velocity of the tool centre point (m/s, world frame)."""
        return self._tcp_velocity

    @property
    def tcp_site(self):
        """Tool centre point, between the fingertips (world frame when bound)."""
        return self._tcp_site

    def configure_joints(self, physics, arm_qpos, finger_width: float) -> None:
        """Puts the arm at `arm_qpos` (rad) at rest, fingers at `finger_width` (m) with the
        gripper servo holding that width, so the first step does not jerk."""
        physics.bind(self._arm_joints).qpos = arm_qpos
        physics.bind(self._arm_joints).qvel = 0.0
        physics.bind(self._finger_joints).qpos = finger_width / 2
        physics.bind(self._finger_joints).qvel = 0.0
        physics.bind(self._gripper_actuator).ctrl = finger_width

    def set_servo_gain(self, physics, factor: float) -> None:
        """Scales the arm's position servos' stiffness by `factor`, with the same derivative
        time (`SERVO_DERIVATIVE_TIME`), without recompiling; only under "position"."""
        if self._arm_actuation != "position":
            raise ValueError(f"the Panda's arm has no position servos under "
                             f"arm_actuation={self._arm_actuation!r}")
        for servo in self._arm_actuators:
            stiffness = float(servo.gainprm[0]) * factor
            bound = physics.bind(servo)
            bound.gainprm[0] = stiffness
            bound.biasprm[1:3] = (-stiffness, -stiffness * SERVO_DERIVATIVE_TIME)

    def set_gripper_gain(self, physics, factor: float) -> None:
        """Scales the gripper servo's stiffness by `factor`, its damping by the square root
        (the same damping ratio): for domain randomisation, without recompiling."""
        servo = physics.bind(self._gripper_actuator)
        stiffness, damping = _GRIPPER_STIFFNESS * factor, _GRIPPER_DAMPING * np.sqrt(factor)
        servo.gainprm[0] = stiffness / 2
        servo.biasprm[1:3] = (-stiffness, -damping)

    def finger_width(self, physics) -> float:
        """Distance between the fingers (m)."""
        return float(np.sum(physics.bind(self._finger_joints).qpos))


class PandaObservables(composer.Observables):
    """What a policy may see of the Panda; velocities are per second (world frame)."""

    @define.observable
    def tcp_position(self):
        return ArrayFeature("xpos", self._entity.tcp_site)

    @define.observable
    def tcp_linear_velocity(self):
        return ArrayFeature("sensordata", self._entity.tcp_velocity)

    @define.observable
    def finger_width(self):
        """Distance between the fingers (m), shape (1,)."""
        return ArrayFeature("qpos", self._entity.finger_joints,
                            lambda qpos: np.array([float(np.sum(qpos))]))

    @define.observable
    def joints_pos(self):
        # An ArrayFeature, whose readings are new arrays: MJCFFeature's are a view of qpos
        # for consecutive joints, and a delayed observation buffered the view (live angles).
        return ArrayFeature("qpos", self._entity.joints)

    @define.observable
    def joints_vel(self):
        return ArrayFeature("qvel", self._entity.joints)


def _remove_visual_geoms(root: mjcf.RootElement) -> None:
    """Removes the geoms of Menagerie's "visual" class, then the meshes nothing uses."""
    for geom in root.find_all("geom"):
        if geom.dclass is not None and geom.dclass.dclass == "visual":
            geom.remove()
    used = {geom.mesh for geom in root.find_all("geom") if geom.mesh is not None}
    for mesh in root.asset.find_all("mesh"):
        if mesh not in used:
            mesh.remove()


def _resolved(element, tag: str, attribute: str):
    """An MJCF attribute as MuJoCo resolves it: the element's own value, else that of its
    default class, else of the class's parents (Menagerie sets many in its classes)."""
    value, dclass = getattr(element, attribute), element.dclass
    ancestor = element.parent
    while dclass is None and ancestor is not None:  # The nearest body's childclass.
        dclass = getattr(ancestor, "childclass", None)
        ancestor = ancestor.parent
    while value is None and dclass is not None:
        defaults = getattr(dclass, tag)
        value = getattr(defaults, attribute) if defaults is not None else None
        dclass = dclass.parent
    if value is None:
        raise ValueError(f"{tag} {element.name!r} has no {attribute}")
    return value


def _force_limit(actuator) -> float:
    """An actuator's largest force magnitude (Menagerie: 87 N m in the class, 12 N m on the
    wrist actuators)."""
    forcerange = _resolved(actuator, "general", "forcerange")
    return float(max(abs(forcerange[0]), abs(forcerange[1])))
