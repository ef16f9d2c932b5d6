"""FCL collision registry: the authority on contact between agents and obstacles.

Every check is *swept*: a sphere of radius r moving in a straight line from p0 to p1
covers exactly a capsule, so one discrete capsule test per step cannot tunnel through a
thin wall, whatever the speed. Moving obstacles translate, so the same holds in the
obstacle's frame: the agent sweeps from ``p0 - q0`` to ``p1 - q1`` relative to it, and
that relative capsule is tested against the obstacle placed at ``q0``. This also covers
meshes, for which FCL's continuous collision segfaults or misses (see
shared/notes/library-facts.md). Agent-agent contact and terrain/ground are analytic.

Static obstacles live in one ``DynamicAABBTreeCollisionManager`` built once; moving
obstacles and the query capsule are fcl objects created once and moved by transforms.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import fcl
import numpy as np

from swarmplan.geometry.bodies import body_table, shape
from swarmplan.geometry.vec3 import dot3, norm3
from swarmplan.runtime.compiled import kernel_module, use_compiled_checks

if TYPE_CHECKING:
    from swarmplan.world.model import Obstacle, World


_Z = np.array([0.0, 0.0, 1.0])

SLACK = 1e-3
"""Metres added to a body's bounding radius when choosing the candidates of the narrow phase
(only costs narrow-phase calls; covers FCL's own tolerance on contact)."""


def shape_table(obstacles: list[Obstacle]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per obstacle the kernels' shape code, rotation (k, 3, 3) and parameters (k, 3), from
    ``bodies.body_table`` (FCL's shapes are centred on their local origin, axis along local z)."""
    table = body_table(obstacles)
    return table.code, table.rotation, table.prm


def fcl_geometry(o: Obstacle) -> fcl.CollisionGeometry:
    """The fcl geometry of an obstacle in its local frame."""
    if o.shape != "mesh":
        return shape(o.shape).fcl(o.shape_params)
    model = fcl.BVHModel()
    model.beginModel(len(o.vertices), len(o.faces))
    model.addSubModel(
        np.ascontiguousarray(o.vertices, dtype=float), np.ascontiguousarray(o.faces, dtype=np.int32)
    )
    model.endModel()
    return model


def _align_z(d: np.ndarray) -> np.ndarray:
    """Rotation matrix taking the local z axis onto the unit vector ``d`` (Rodrigues, scalar math)."""
    x, y, z = float(d[0]), float(d[1]), float(d[2])
    if z > 1 - 1e-12:
        return np.eye(3)
    if z < -1 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    # v = z_hat x d = (-y, x, 0); R = I + [v]x + [v]x^2 / (1 + z)
    k = 1.0 / (1.0 + z)
    return np.array(
        [
            [1.0 - x * x * k, -x * y * k, x],
            [-x * y * k, 1.0 - y * y * k, y],
            [-x, -y, 1.0 - (x * x + y * y) * k],
        ]
    )


def _align_z_rows(u: np.ndarray) -> np.ndarray:
    """:func:`_align_z` of each row of ``u`` (n, 3), the same arithmetic elementwise (equal bits)."""
    x, y, z = u[:, 0], u[:, 1], u[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        k = 1.0 / (1.0 + z)
        out = np.empty((len(u), 3, 3))
        out[:, 0, 0] = 1.0 - x * x * k
        out[:, 0, 1] = -x * y * k
        out[:, 0, 2] = x
        out[:, 1, 0] = -x * y * k
        out[:, 1, 1] = 1.0 - y * y * k
        out[:, 1, 2] = y
        out[:, 2, 0] = -x
        out[:, 2, 1] = -y
        out[:, 2, 2] = 1.0 - (x * x + y * y) * k
    out[z > 1 - 1e-12] = np.eye(3)
    out[z < -1 + 1e-12] = np.diag([1.0, -1.0, -1.0])
    return out


def point_segment_distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``c`` (M, 3) to each segment ``a``→``b`` (N, 3): shape (N, M)."""
    ab = b - a
    ac = c[None, :, :] - a[:, None, :]
    den = np.maximum(np.einsum("nd,nd->n", ab, ab), 1e-18)
    s = np.clip(np.einsum("nmd,nd->nm", ac, ab) / den[:, None], 0.0, 1.0)
    return norm3(ac - s[..., None] * ab[:, None, :])


def segment_segment_min_distance(
    p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray
) -> np.ndarray:
    """Minimum over s in [0, 1] of |(p0 + s(p1-p0)) - (q0 + s(q1-q0))| for rows of points moving together.

    Two bodies moving linearly during the same step: their separation is linear in s, so
    the closest approach has a closed form.
    """
    w0 = p0 - q0
    dw = (p1 - p0) - (q1 - q0)
    a = dot3(dw, dw)
    s = np.where(a > 1e-18, np.clip(-dot3(w0, dw) / np.maximum(a, 1e-18), 0.0, 1.0), 0.0)
    return norm3(w0 + s[..., None] * dw)


class CollisionWorld:
    """Swept collision queries of agent spheres against the world's obstacles, terrain and bounds."""

    def __init__(self, world: World):
        self.world = world
        self.static = list(world.static_obstacles)
        self.moving = list(world.moving_obstacles)
        self._static_objs = []
        for o in self.static:
            obj = fcl.CollisionObject(fcl_geometry(o), fcl.Transform(o.rotation, o.position.astype(float)))
            self._static_objs.append(obj)
        self._manager = fcl.DynamicAABBTreeCollisionManager()
        if self._static_objs:
            self._manager.registerObjects(self._static_objs)
            self._manager.setup()
        self._moving_objs = [
            fcl.CollisionObject(fcl_geometry(o), fcl.Transform(o.rotation, o.position.astype(float)))
            for o in self.moving
        ]
        self._static_centers = np.array([o.position for o in self.static]).reshape(-1, 3)
        self._static_radii = np.array([o.bounding_radius for o in self.static])
        self._moving_radii = np.array([o.bounding_radius for o in self.moving])
        self._static_table = shape_table(self.static)
        self._moving_table = shape_table(self.moving)
        self._kernel_statics = (
            np.ascontiguousarray(self._static_centers, dtype=float),
            np.ascontiguousarray(self._static_radii, dtype=float),
            *self._static_table,
        )
        self._kernel_moving_radii = np.ascontiguousarray(self._moving_radii, dtype=float)
        self._capsule = fcl.Capsule(1.0, 1.0)
        self._capsule_obj = fcl.CollisionObject(self._capsule, fcl.Transform())
        self._spheres: dict[float, tuple[fcl.Sphere, fcl.CollisionObject]] = {}
        self._request = fcl.CollisionRequest()

    # ------------------------------------------------------------------ fcl primitives

    def _swept_object(self, a: np.ndarray, b: np.ndarray, radius: float) -> fcl.CollisionObject:
        d = b - a
        length = float(np.linalg.norm(d))
        mid = (a + b) / 2
        return self._capsule_object(mid, length, None if length < 1e-9 else _align_z(d / length), radius)

    def _capsule_object(
        self, mid: np.ndarray, length: float, rotation: np.ndarray | None, radius: float
    ) -> fcl.CollisionObject:
        """The swept sphere as an fcl object: a capsule of ``length`` along ``rotation``'s z axis
        centred at ``mid`` (a sphere when the step is shorter than 1e-9)."""
        if length < 1e-9:
            if radius not in self._spheres:
                g = fcl.Sphere(radius)
                self._spheres[radius] = (g, fcl.CollisionObject(g, fcl.Transform()))
            obj = self._spheres[radius][1]
            obj.setTransform(fcl.Transform(np.ascontiguousarray(mid, dtype=float)))
            return obj
        self._capsule.radius = radius
        self._capsule.lz = length
        # A changed geometry keeps its old local AABB (the broadphase then misses long
        # sweeps): recompute it, then set a fresh transform so the world AABB follows.
        self._capsule.computeLocalAABB()
        self._capsule_obj.setTransform(fcl.Transform(rotation, np.ascontiguousarray(mid, dtype=float)))
        return self._capsule_obj

    def kernel_statics(self) -> tuple[np.ndarray, ...]:
        """The static bodies as the kernels take them: centres, bounding radii, shape table."""
        return self._kernel_statics

    def kernel_movers(self, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, ...]:
        """The moving bodies at ``q0`` -> ``q1`` as the kernels take them: positions at both
        ends, bounding radii, shape table."""
        return (
            np.ascontiguousarray(q0, dtype=float).reshape(-1, 3),
            np.ascontiguousarray(q1, dtype=float).reshape(-1, 3),
            self._kernel_moving_radii,
            *self._moving_table,
        )

    def _collides(self, a: fcl.CollisionObject, b: fcl.CollisionObject) -> bool:
        return fcl.collide(a, b, self._request, fcl.CollisionResult()) > 0

    # ------------------------------------------------------------------ queries

    def sweep_static(self, p0: np.ndarray, p1: np.ndarray, radius: float) -> str | None:
        """Id of a static obstacle the sphere touches moving from ``p0`` to ``p1``, else None."""
        if not self.static:
            return None
        near = point_segment_distance(self._static_centers, p0[None], p1[None])[0] - self._static_radii
        return self._sweep_static_near(self._swept_object(p0, p1, radius), near <= radius + SLACK)

    def _sweep_static_near(self, obj: fcl.CollisionObject, near: np.ndarray) -> str | None:
        """The first static obstacle (world order) among ``near`` (mask) that ``obj`` touches.

        Narrow phase on the candidates directly: a body the sweep touches has its centre within
        its bounding radius + the sweep's radius of the segment, so it is among them, and the
        first hit in world order is the body the broadphase manager's check named (its
        Python callback per candidate pair cost more than the narrow phase itself)."""
        for k in np.flatnonzero(near).tolist():
            if self._collides(obj, self._static_objs[k]):
                return self.static[k].id
        return None

    def sweep_moving(
        self, p0: np.ndarray, p1: np.ndarray, radius: float, q0: np.ndarray, q1: np.ndarray
    ) -> str | None:
        """Id of a moving obstacle (at ``q0`` → ``q1`` during the step) the sphere touches, else None."""
        if not self.moving:
            return None
        gap = segment_segment_min_distance(p0[None, :], p1[None, :], q0, q1) - self._moving_radii - radius
        return self._sweep_moving_near(p0, p1, radius, q0, q1, np.flatnonzero(gap <= 1e-6))

    def _sweep_moving_near(
        self, p0: np.ndarray, p1: np.ndarray, radius: float, q0: np.ndarray, q1: np.ndarray, near: np.ndarray
    ) -> str | None:
        """:meth:`sweep_moving` over the moving bodies ``near`` (indices, in order) only."""
        for k in near.tolist():
            # Relative motion in the obstacle's frame: the obstacle stays at q0, the agent sweeps.
            obj = self._swept_object(p0, p1 - (q1[k] - q0[k]), radius)
            mo = self._moving_objs[k]
            mo.setTransform(fcl.Transform(self.moving[k].rotation, np.ascontiguousarray(q0[k], dtype=float)))
            if self._collides(obj, mo):
                return self.moving[k].id
        return None

    def sweep_terrain(self, p0: np.ndarray, p1: np.ndarray, radius: float) -> str | None:
        """ "ground"/"terrain" when the sphere dips below the height field during the step.

        Samples the step at a quarter radius (the terrain is smooth at that scale).
        """
        n = int(np.ceil(np.linalg.norm(p1 - p0) / max(radius * 0.25, 1e-3))) + 2
        s = np.linspace(0.0, 1.0, min(n, 4000))[:, None]
        pts = p0 + s * (p1 - p0)
        h = self.world.terrain_height(pts[:, :2])
        if np.any(pts[:, 2] - h < radius - 1e-9):
            return "terrain" if self.world.peaks else "ground"
        return None

    def sweep_bounds(self, p1: np.ndarray) -> bool:
        """True when the centre leaves the flight volume (the volume is convex: the end point suffices)."""
        return bool(np.any(p1 < self.world.bounds_min - 1e-9) or np.any(p1 > self.world.bounds_max + 1e-9))

    def first_hit(
        self, p0: np.ndarray, p1: np.ndarray, radius: float, q0: np.ndarray, q1: np.ndarray
    ) -> str | None:
        """What a sphere moving ``p0`` → ``p1`` touches: obstacle id, terrain, ground, bounds or None."""
        if self.sweep_bounds(p1):
            return "bounds"
        return (
            self.sweep_terrain(p0, p1, radius)
            or self.sweep_static(p0, p1, radius)
            or self.sweep_moving(p0, p1, radius, q0, q1)
        )


def first_hits(
    cw: CollisionWorld, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, q0: np.ndarray, q1: np.ndarray
) -> list[str | None]:
    """:meth:`CollisionWorld.first_hit` for many agents at once.

    Swarm-sized worlds (``use_compiled_checks``): bounds, ground and terrain are decided in
    numpy; the bodies by the compiled kernels (``swept_kernels``: exact geometry, decided only
    away from contact), and the agents whose answer the kernels leave undecided (a body within
    ``BAND`` of contact, or a mesh) by :func:`first_hits_fcl`. Smaller worlds:
    :func:`first_hits_fcl` for all (the same answers).
    """
    n = len(p0)
    out: list[str | None] = [None] * n
    if n == 0:
        return out
    if not use_compiled_checks(len(cw.world.agents), any(a.model == "fixed_wing" for a in cw.world.agents)):
        return first_hits_fcl(cw, p0, p1, radii, q0, q1)
    oob, low, ground_name = _bounds_and_ground(cw.world, p0, p1, radii)
    kind, index = kernel_module("swarmplan.geometry.swept_kernels").sweep_many(
        np.ascontiguousarray(p0, dtype=float),
        np.ascontiguousarray(p1, dtype=float),
        np.ascontiguousarray(radii, dtype=float),
        oob | low,
        cw.kernel_statics(),
        cw.kernel_movers(q0, q1),
        SLACK,
    )
    fcl_rows = []
    for i in np.flatnonzero(oob | low | (kind != 0)).tolist():
        kd, k = int(kind[i]), int(index[i])
        if oob[i]:
            out[i] = "bounds"
        elif low[i]:
            out[i] = ground_name
        elif kd == 1:
            out[i] = cw.static[k].id
        elif kd == 2:
            out[i] = cw.moving[k].id
        elif kd == 3:
            fcl_rows.append(i)
    if fcl_rows:
        rows = np.array(fcl_rows)
        for i, hit in zip(fcl_rows, first_hits_fcl(cw, p0[rows], p1[rows], radii[rows], q0, q1), strict=True):
            out[i] = hit
    return out


def _bounds_and_ground(
    w: World, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str]:
    """Per step: its end leaves the flight volume; the swept sphere dips below ground or
    terrain (terrain sampled at a quarter radius); and the name of that surface."""
    oob = np.any(p1 < w.bounds_min - 1e-9, axis=1) | np.any(p1 > w.bounds_max + 1e-9, axis=1)
    if w.peaks:
        step = np.linalg.norm(p1 - p0, axis=1)
        k = int(min(4000, np.ceil(np.max(step / np.maximum(radii * 0.25, 1e-3), initial=0.0)) + 2))
        s = np.linspace(0.0, 1.0, k)
        pts = p0[:, None, :] + s[None, :, None] * (p1 - p0)[:, None, :]
        low = np.any(pts[..., 2] - w.terrain_height(pts[..., :2]) < radii[:, None] - 1e-9, axis=1)
        return oob, low, "terrain"
    return oob, np.minimum(p0[:, 2], p1[:, 2]) < radii - 1e-9, "ground"


def first_hits_fcl(
    cw: CollisionWorld, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, q0: np.ndarray, q1: np.ndarray
) -> list[str | None]:
    """:meth:`CollisionWorld.first_hit` for many agents at once, with vectorized prefilters.

    Bounds, ground and terrain are decided in numpy for all agents; FCL only sees the
    (agent, body) pairs whose bounding spheres the swept sphere can reach.
    """
    n = len(p0)
    out: list[str | None] = [None] * n
    oob, low, ground_name = _bounds_and_ground(cw.world, p0, p1, radii)
    if cw.static:
        reach = point_segment_distance(cw._static_centers, p0, p1) - cw._static_radii[None, :]
        near_static = np.any(reach <= radii[:, None] + 1e-6, axis=1)
        candidates = reach <= radii[:, None] + SLACK
    else:
        near_static = np.zeros(n, dtype=bool)
    if cw.moving:
        gap = segment_segment_min_distance(p0[:, None, :], p1[:, None, :], q0[None], q1[None])
        close = gap - cw._moving_radii[None, :] - radii[:, None] <= 1e-6
        near_moving = np.any(close, axis=1)
    else:
        near_moving = np.zeros(n, dtype=bool)
    todo = np.flatnonzero(~oob & ~low & (near_static | near_moving))
    if len(todo):
        # The capsules of the agents the narrow phase sees, for all of them at once (the same
        # arithmetic as CollisionWorld._swept_object row by row).
        d = p1[todo] - p0[todo]
        length = norm3(d)
        mid = (p0[todo] + p1[todo]) / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            rotation = _align_z_rows(d / length[:, None])
    for i in range(n):
        if oob[i]:
            out[i] = "bounds"
        elif low[i]:
            out[i] = ground_name
    for row, i in enumerate(todo.tolist()):
        hit = None
        if near_static[i]:
            obj = cw._capsule_object(mid[row], float(length[row]), rotation[row], radii[i])
            hit = cw._sweep_static_near(obj, candidates[i])
        if hit is None and near_moving[i]:
            hit = cw._sweep_moving_near(p0[i], p1[i], radii[i], q0, q1, np.flatnonzero(close[i]))
        out[i] = hit
    return out


def agent_contacts(
    p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, active: np.ndarray, margin: float = 0.0
) -> list[tuple[int, int]]:
    """Pairs (i, j), i < j, of agents whose spheres (inflated by ``margin``) touch during the step.

    Agents that are not ``active`` (arrived) still count as bodies, standing still.
    """
    n = len(p0)
    if n < 2:
        return []
    i, j = np.triu_indices(n, 1)
    keep = active[i] | active[j]
    i, j = i[keep], j[keep]
    d = segment_segment_min_distance(p0[i], p1[i], p0[j], p1[j])
    hit = d < radii[i] + radii[j] + margin
    return list(zip(i[hit].tolist(), j[hit].tolist(), strict=True))
