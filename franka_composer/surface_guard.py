"""How far down the hand may be sent: to the surface beneath it, plus a press a Panda can make.

The controllers that move the hand to a target do it with a spring: the mocap weld, or the
operational-space law's Cartesian stiffness. A target below a surface drives the hand into
it with a force that grows with the depth: a full downward command puts the target 5 cm
below the hand, which pressed objects into the floor with kilonewtons under the weld
(measured before this guard: 3-135 kN), and saturates every joint under torque control, so
that nothing is left to hold the hand where it presses and it slides off. A real Panda
presses with what its joint torques allow. So before each control step sets the target,
rays cast straight down from the hand's lowest points (the bottom corners of each finger and
of the palm) find the surface beneath, the floor or an object's top, under the hand and
along the way to the target's (x, y) (halfway and at the end: a hand moving sideways while
it descends can land on an object it is not above yet), and the target is kept no deeper
than the press depth below where the hand would touch it.

The press depth is what the controller's spring, held still by the surface, needs to push
with the force the arm itself could push down with in its present configuration: the
largest F for which the joint torques J_z^T F stay within the joints' limits, min_i
tau_max_i / |J_z,i| (114-136 N over the object square: joint 6's 12 N m, 136 N, over most of
it, joint 2's 87 N m, 114-116 N, at its far edge, x = 0.75 m),
over the spring's vertical stiffness, which the controller supplies (`guard(tcp, target,
stiffness)`: about 1.3 mm for the weld, 8 mm for the operational-space law).

A block the hand carries (both fingers touch it, nothing else does) is part of the hand, not
a surface beneath it, where the task says so (`ControlSettings.guard_ignores_carried`): the
hand's rays meet a block held low in the grip (`experiments/held_rays.py`), and without it
the hand is held up by what it carries.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: Rays under the hand start this far above its lowest points, inside the hand, so a point
#: that already touches (or slightly penetrates) a surface still finds that surface. Rays
#: along the way start at the points' own height: MuJoCo's rays ignore a geom they start
#: inside, so an object the hand will meet side-on (a push) is not taken for a floor.
RAY_START_ABOVE = 0.03
#: A hit counts as a surface beneath the hand only this far (m) above its lowest points, at
#: most: a press sinks the fingertips ~0.1 mm. Higher hits are of objects held between the
#: fingers or beside them (a finger's footprint overlaps the block it holds), not beneath.
BENEATH_TOLERANCE = 0.006
#: Fractions of the step's sideways motion at which the footprint is probed as well.
PATH_FRACTIONS = (0.5, 1.0)
#: Objects whose top is more than this (m) below the palm are not checked against it: the
#: hand moves at most 5 cm a step.
PALM_REACH = 0.06
#: Sideways motion (m) below which only the footprint under the hand is probed.
MIN_SIDEWAYS = 0.002
#: A body's footprint is the extent of its collision vertices within this height of its
#: lowest one (m): the fingertips' pads and tips, the palm's underside.
FOOTPRINT_BAND = 0.002
#: Geom groups the rays see. Menagerie's Panda puts its visual and collision geoms in groups
#: 2 and 3, so the rays never hit the hand itself; the floor and the objects are in group 0.
VISIBLE_GROUPS = np.array([1, 1, 0, 0, 1, 1], dtype=np.uint8)
_DOWN = np.array([0.0, 0.0, -1.0])


class SurfaceGuard:
    """Finds the lowest tool-centre-point height the hand may be commanded to.

    Built for one compiled model with `bind`; the bound guard's `guard(tcp, target)` then
    runs each control step, reading the data it was bound to.
    """

    def __init__(self, panda, ignore_carried: bool = False) -> None:
        self._panda, self._ignore_carried = panda, ignore_carried
        self._torque_limits = np.asarray(panda.arm_torque_limits, dtype=np.float64)

    def bind(self, physics) -> "BoundSurfaceGuard":
        """This guard on `physics` (its model's ids, its data's arrays)."""
        model = physics.model.ptr
        bodies = np.array(physics.bind(self._panda.colliding_bodies).element_id)
        robot = set(physics.bind(self._panda.mjcf_model.find_all("body")).element_id)
        for geom in range(model.ngeom):
            if model.geom_bodyid[geom] in robot and VISIBLE_GROUPS[model.geom_group[geom]]:
                raise ValueError(f"robot geom {model.geom(geom).name!r} is in geom group "
                                 f"{model.geom_group[geom]}, which the surface rays see")
        return BoundSurfaceGuard(
            model, physics.data.ptr, bodies, _footprints(model, physics.data.ptr, bodies),
            tcp_site=int(physics.bind(self._panda.tcp_site).element_id),
            arm_dofs=np.array(physics.bind(self._panda.joints).dofadr),
            torque_limits=self._torque_limits, ignore_carried=self._ignore_carried)


class BoundSurfaceGuard:
    """A `SurfaceGuard` reading one MjData (valid while that data lives)."""

    def __init__(self, model, data, bodies, footprints, *, tcp_site, arm_dofs,
                 torque_limits, ignore_carried: bool = False) -> None:
        self._model, self._data = model, data
        self._ignore_carried = ignore_carried
        self._bodies, self._footprints = bodies, footprints
        self._tcp_site, self._arm_dofs = tcp_site, arm_dofs
        self._torque_limits = torque_limits
        visible = VISIBLE_GROUPS[model.geom_group].astype(bool)
        self._surfaces = np.flatnonzero(visible)  # What the rays can hit.
        # The objects: visible colliding geoms of bodies other than the world's (the floor).
        self._objects = np.array([
            geom for geom in self._surfaces
            if model.geom_bodyid[geom] != 0
            and (model.geom_contype[geom] or model.geom_conaffinity[geom])], dtype=int)
        self._palm, self._fingers = int(bodies[0]), {int(b) for b in bodies[1:]}
        corners = footprints[0]
        self._palm_low, self._palm_high = corners.min(axis=0)[:2], corners.max(axis=0)[:2]
        self._geom = np.zeros(1, np.int32)
        self._jacp = np.zeros((3, model.nv))

    def on(self, model, data) -> "BoundSurfaceGuard":
        """The same guard reading another MjData of the same model."""
        return BoundSurfaceGuard(model, data, self._bodies, self._footprints,
                                 tcp_site=self._tcp_site, arm_dofs=self._arm_dofs,
                                 torque_limits=self._torque_limits,
                                 ignore_carried=self._ignore_carried)

    def footprint(self) -> np.ndarray:
        """The hand's lowest points, world frame, shape (n, 3)."""
        data = self._data
        rotations = data.xmat[self._bodies].reshape(-1, 3, 3)
        points = data.xpos[self._bodies, None, :] + np.einsum(
            "bij,bkj->bki", rotations, self._footprints)
        return points.reshape(-1, 3)

    def reach_below_tcp(self) -> float:
        """How far (m) the hand's lowest point is below the tool centre point (7.3 mm with
        the fingers closed: where the fingertips are)."""
        return float(self._data.site_xpos[self._tcp_site, 2] - self.footprint()[:, 2].min())

    def clearance(self, sideways=(0.0, 0.0), points: np.ndarray | None = None) -> float:
        """How far (m) the hand can move straight down before it touches something, below
        it and, if `sideways` (m, x and y) is given, along the way there (inf if nothing is
        beneath; negative if the hand already presses into a surface). `points`: the
        footprint, if already computed."""
        points = self.footprint() if points is None else points
        lowest = self._lowest_hit(points, RAY_START_ABOVE)
        fractions: tuple[float, ...] = (0.0,)
        if np.hypot(*sideways) > MIN_SIDEWAYS:
            fractions += PATH_FRACTIONS
            for fraction in PATH_FRACTIONS:
                shifted = points.copy()
                shifted[:, :2] += fraction * np.asarray(sideways)
                lowest = min(lowest, self._lowest_hit(shifted, 0.0))
        return min(lowest, self._palm_clearance(np.asarray(sideways), fractions, points))

    def _palm_clearance(self, sideways: np.ndarray, fractions,
                        points: np.ndarray | None = None) -> float:
        """How far the palm's underside can move down before it meets the top of an object
        under it (now and at `fractions` of the way `sideways`), the objects held between
        the fingers excepted. The palm is 20 cm wide: a 6 cm puck fits between the corners
        the rays start from, and a hand lowered beside it would press it under the palm.
        `points`: the footprint, if already computed."""
        model, data, objects = self._model, self._data, self._objects
        if not len(objects):
            return np.inf
        points = self.footprint() if points is None else points
        bottom = points[:4, 2].min()  # The palm's corners come first.
        if bottom - np.max(data.geom_xpos[objects, 2] + model.geom_rbound[objects]) > PALM_REACH:
            return np.inf  # Every object's top is out of reach (its bounding sphere's is).
        rotation, origin = data.xmat[self._palm].reshape(3, 3), data.xpos[self._palm]
        held = None
        lowest = np.inf
        for geom in objects:
            top, radius = _top_and_radius(model, data, geom)
            if bottom - top > min(lowest, PALM_REACH):
                continue
            if held is None:
                held = self._held_bodies()
            if model.geom_bodyid[geom] in held:
                continue
            for fraction in fractions:
                # The object's centre in the palm's frame, the palm moved `fraction` of the way.
                offset = data.geom_xpos[geom] - origin
                offset[:2] -= fraction * sideways
                local = offset @ rotation
                if np.all(local[:2] >= self._palm_low - radius) and np.all(
                        local[:2] <= self._palm_high + radius):
                    lowest = min(lowest, bottom - top)
                    break
        return lowest

    def _held_bodies(self) -> set:
        """Bodies both fingers touch: held between them, not beneath the hand."""
        model, data = self._model, self._data
        touching: dict[int, set] = {}
        for index in range(data.ncon):
            contact = data.contact[index]
            first = int(model.geom_bodyid[contact.geom1])
            second = int(model.geom_bodyid[contact.geom2])
            for finger, other in ((first, second), (second, first)):
                if finger in self._fingers:
                    touching.setdefault(other, set()).add(finger)
        return {body for body, fingers in touching.items() if fingers == self._fingers}

    def _carried_bodies(self) -> set:
        """Held bodies (`_held_bodies`) that touch nothing but the hand: off the floor and
        off every other object. A block pushed or turned over on the floor, or set down on
        another, is held but not carried."""
        model, data = self._model, self._data
        hand = self._fingers | {self._palm}
        carried = self._held_bodies()
        for index in range(data.ncon):
            contact = data.contact[index]
            first = int(model.geom_bodyid[contact.geom1])
            second = int(model.geom_bodyid[contact.geom2])
            if first in carried and second not in hand:
                carried.discard(first)
            if second in carried and first not in hand:
                carried.discard(second)
        return carried

    def _lowest_hit(self, points: np.ndarray, start_above: float) -> float:
        """The smallest clearance below `points` of a surface at or under them (a ray that
        meets a carried body cast again past it, where the guard ignores those)."""
        model, data, geom = self._model, self._data, self._geom
        lowest, carried = np.inf, None
        for point in points:
            start = point.copy()
            start[2] += start_above
            distance = mujoco.mj_ray(model, data, start, _DOWN, VISIBLE_GROUPS, 1, -1, geom)
            if self._ignore_carried and distance >= 0.0 and model.geom_bodyid[geom[0]]:
                body = int(model.geom_bodyid[geom[0]])
                carried = self._carried_bodies() if carried is None else carried
                if body in carried:
                    distance = mujoco.mj_ray(model, data, start, _DOWN, VISIBLE_GROUPS, 1,
                                             body, geom)
            if distance >= 0.0 and distance - start_above >= -BENEATH_TOLERANCE:
                lowest = min(lowest, distance - start_above)
        return lowest

    def max_push_force(self) -> float:
        """The largest force (N) the arm's joint torques allow straight down at the tool
        centre point in the present configuration."""
        mujoco.mj_jacSite(self._model, self._data, self._jacp, None, self._tcp_site)
        lever = np.abs(self._jacp[2, self._arm_dofs])
        return float(np.min(self._torque_limits / np.maximum(lever, 1e-9)))

    def press_depth(self, stiffness: float) -> float:
        """How deep (m) below the touching height the target may go for a spring of
        `stiffness` (N/m) to push with at most `max_push_force`."""
        return self.max_push_force() / stiffness

    def touching(self, tcp: np.ndarray, target: np.ndarray) -> float:
        """The height of the tool centre point, now at `tcp`, at which the hand would touch
        a surface beneath it on its way to `target` (m, world): the floor or an object's
        top, under the hand or along the way; -inf if none is within reach."""
        descent = tcp[2] - target[2]
        sideways = target[:2] - tcp[:2]
        if descent <= 0.0:
            # Not going down: only the palm can press on something, carried sideways over
            # an object whose top is above the palm's underside.
            fractions = (0.0, *PATH_FRACTIONS) if np.hypot(*sideways) > MIN_SIDEWAYS else (0.0,)
            return tcp[2] - self._palm_clearance(sideways, fractions)
        surfaces = self._surfaces
        highest = np.max(self._data.geom_xpos[surfaces, 2] + self._model.geom_rbound[surfaces])
        points = self.footprint()
        if points[:, 2].min() - descent > highest:
            return -np.inf  # Nothing within reach below: no rays needed.
        return tcp[2] - self.clearance(sideways, points)

    def guard(self, tcp: np.ndarray, target: np.ndarray, stiffness: float) -> float:
        """The height for a target `target` (m, world) of the tool centre point now at
        `tcp`, pulled by a spring of vertical `stiffness` (N/m): `target[2]`, raised where
        it would send the hand into a surface beneath it deeper than the press depth."""
        touching = self.touching(tcp, target)
        if target[2] >= touching:
            return target[2]
        return max(target[2], touching - self.press_depth(stiffness))


def _top_and_radius(model, data, geom: int) -> tuple[float, float]:
    """A geom's highest point (m, world z) and the radius (m) of a circle about its centre
    that covers most of its horizontal footprint."""
    size, rotation = model.geom_size[geom], data.geom_xmat[geom].reshape(3, 3)
    kind = model.geom_type[geom]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        half_height = np.abs(rotation[2]) @ size
        radius = max(np.abs(rotation[0]) @ size, np.abs(rotation[1]) @ size)
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        upright = abs(rotation[2, 2])  # |cos| of the axis's tilt.
        tilted = np.sqrt(max(0.0, 1.0 - upright ** 2))
        half_height = upright * size[1] + tilted * size[0]
        radius = size[0] + tilted * size[1]
    else:
        half_height = radius = model.geom_rbound[geom]
    return float(data.geom_xpos[geom, 2] + half_height), float(radius)


def _footprints(model, data, bodies) -> np.ndarray:
    """For each body, the four corners (body frame) of the underside of its collision geoms,
    taken with the hand in its start pose (held top-down throughout)."""
    corners = []
    for body in bodies:
        vertices = np.concatenate([_geom_vertices(model, data, geom)
                                   for geom in range(model.ngeom)
                                   if model.geom_bodyid[geom] == body
                                   and (model.geom_contype[geom] or model.geom_conaffinity[geom])])
        lowest = vertices[:, 2].min()
        underside = vertices[vertices[:, 2] <= lowest + FOOTPRINT_BAND]
        # Body-frame coordinates; the hand points straight down, so body x, y are horizontal.
        rotation = data.xmat[body].reshape(3, 3)
        local = (underside - data.xpos[body]) @ rotation
        (x0, y0), (x1, y1) = local[:, :2].min(axis=0), local[:, :2].max(axis=0)
        # Every corner at the height of the lowest vertex.
        depth = ((underside[np.argmin(underside[:, 2])] - data.xpos[body]) @ rotation)[2]
        corners.append([[x0, y0, depth], [x0, y1, depth], [x1, y0, depth], [x1, y1, depth]])
    return np.asarray(corners, dtype=np.float64)


def _geom_vertices(model, data, geom) -> np.ndarray:
    """A geom's vertices (meshes) or bounding-box corners (primitives), world frame."""
    if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[geom]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        local = model.mesh_vert[start:start + count].astype(np.float64)
    else:
        centre, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        local = centre + signs * half
    return local @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
