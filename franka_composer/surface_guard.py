"""How far down the hand may be sent: to the surface beneath it, plus a press a Panda can make.

The mocap weld is a spring, so a target below a surface drives the hand into it with a force
that grows with the depth: a full downward command puts the target 5 cm below the hand,
which pressed objects into the floor with kilonewtons (measured before this guard: 3-135 kN).
A real Panda cannot: its joint torque limits bound the force at the hand. So before each
control step sets the target, rays cast straight down from the hand's lowest points (the
bottom corners of each finger and of the palm) find the surface beneath, the floor or an
object's top, under the hand and along the way to the target's (x, y) (halfway and at the
end: a hand moving sideways while it descends can land on an object it is not above yet),
and the target is kept no deeper than `press depth` below where the hand would touch it.

The press depth is what the weld's spring, held still by the surface, needs to push with the
force the arm itself could push down with in its present configuration: the largest F for
which the joint torques J_z^T F stay within the joints' limits, min_i tau_max_i / |J_z,i|
(114-136 N over the object square, where joint 2's 87 N m is the limit). MuJoCo holds a
weld row of regulariser R = 1 / D, impedance d and time constant tc, blocked at depth r,
with the force r D / (d tc^2); the depth is therefore F d tc^2 / D, read from the weld's
vertical row each step (about 1.3 mm).
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
BENEATH_TOLERANCE = 0.002
#: Fractions of the step's sideways motion at which the footprint is probed as well.
PATH_FRACTIONS = (0.5, 1.0)
#: Sideways motion (m) below which only the footprint under the hand is probed.
MIN_SIDEWAYS = 0.002
#: A body's footprint is the extent of its collision vertices within this height of its
#: lowest one (m): the fingertips' pads and tips, the palm's underside.
FOOTPRINT_BAND = 0.002
#: Geom groups the rays see. Menagerie's Panda puts its visual and collision geoms in groups
#: 2 and 3, so the rays never hit the hand itself; the floor and the objects are in group 0.
VISIBLE_GROUPS = np.array([1, 1, 0, 0, 1, 1], dtype=np.uint8)
_ROBOT_GROUPS = (2, 3)
_DOWN = np.array([0.0, 0.0, -1.0])
_EQUALITY = mujoco.mjtConstraint.mjCNSTR_EQUALITY


class SurfaceGuard:
    """Finds the lowest tool-centre-point height the hand may be commanded to.

    Built for one compiled model with `bind`; the bound guard's `guard(tcp, target)` then
    runs each control step, reading the data it was bound to.
    """

    def __init__(self, panda, weld, weld_timeconst: float, weld_impedance: float) -> None:
        self._panda, self._weld = panda, weld
        # s^2: press depth = force x this / the weld row's D (see the module docstring).
        self._weld_compliance = weld_impedance * weld_timeconst ** 2
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
            weld=int(physics.bind(self._weld).element_id),
            arm_dofs=np.array(physics.bind(self._panda.joints).dofadr),
            torque_limits=self._torque_limits, weld_compliance=self._weld_compliance)


class BoundSurfaceGuard:
    """A `SurfaceGuard` reading one MjData (valid while that data lives)."""

    def __init__(self, model, data, bodies, footprints, *, tcp_site, weld, arm_dofs,
                 torque_limits, weld_compliance) -> None:
        self._model, self._data = model, data
        self._bodies, self._footprints = bodies, footprints
        self._tcp_site, self._weld, self._arm_dofs = tcp_site, weld, arm_dofs
        self._torque_limits, self._weld_compliance = torque_limits, weld_compliance
        visible = VISIBLE_GROUPS[model.geom_group].astype(bool)
        self._surfaces = np.flatnonzero(visible)  # What the rays can hit.
        self._geom = np.zeros(1, np.int32)
        self._jacp = np.zeros((3, model.nv))

    def on(self, model, data) -> "BoundSurfaceGuard":
        """The same guard reading another MjData of the same model."""
        return BoundSurfaceGuard(model, data, self._bodies, self._footprints,
                                 tcp_site=self._tcp_site, weld=self._weld,
                                 arm_dofs=self._arm_dofs,
                                 torque_limits=self._torque_limits,
                                 weld_compliance=self._weld_compliance)

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
        if np.hypot(*sideways) > MIN_SIDEWAYS:
            for fraction in PATH_FRACTIONS:
                shifted = points.copy()
                shifted[:, :2] += fraction * np.asarray(sideways)
                lowest = min(lowest, self._lowest_hit(shifted, 0.0))
        return lowest

    def _lowest_hit(self, points: np.ndarray, start_above: float) -> float:
        """The smallest clearance below `points` of a surface at or under them."""
        model, data, geom = self._model, self._data, self._geom
        lowest = np.inf
        for point in points:
            start = point.copy()
            start[2] += start_above
            distance = mujoco.mj_ray(model, data, start, _DOWN, VISIBLE_GROUPS, 1, -1, geom)
            if distance >= 0.0 and distance - start_above >= -BENEATH_TOLERANCE:
                lowest = min(lowest, distance - start_above)
        return lowest

    def max_push_force(self) -> float:
        """The largest force (N) the arm's joint torques allow straight down at the tool
        centre point in the present configuration."""
        mujoco.mj_jacSite(self._model, self._data, self._jacp, None, self._tcp_site)
        lever = np.abs(self._jacp[2, self._arm_dofs])
        return float(np.min(self._torque_limits / np.maximum(lever, 1e-9)))

    def press_stiffness(self) -> float:
        """Newtons per metre the weld pushes with when held still below its target: D / (d
        tc^2) of its vertical row (equality rows come first in MuJoCo's constraint arrays;
        a weld's first three rows are x, y, z)."""
        data = self._data
        rows = np.flatnonzero((data.efc_type[:data.ne] == _EQUALITY)
                              & (data.efc_id[:data.ne] == self._weld))
        return float(data.efc_D[rows[2]]) / self._weld_compliance

    def press_depth(self) -> float:
        """How deep (m) below the touching height the target may go: the weld then pushes
        with at most `max_push_force`."""
        return self.max_push_force() / self.press_stiffness()

    def guard(self, tcp: np.ndarray, target: np.ndarray) -> float:
        """The height for a target `target` (m, world) of the tool centre point now at
        `tcp`: `target[2]`, raised where it would send the hand into a surface beneath it
        deeper than the press depth."""
        descent = tcp[2] - target[2]
        if descent <= 0.0:
            return target[2]  # Not going down: nothing to press into.
        surfaces = self._surfaces
        highest = np.max(self._data.geom_xpos[surfaces, 2] + self._model.geom_rbound[surfaces])
        points = self.footprint()
        if points[:, 2].min() - descent > highest:
            return target[2]  # Nothing within reach below: no rays needed.
        touching = tcp[2] - self.clearance(target[:2] - tcp[:2], points)
        if target[2] >= touching:
            return target[2]
        return max(target[2], touching - self.press_depth())


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
