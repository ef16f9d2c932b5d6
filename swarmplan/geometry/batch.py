"""Signed distances from many points to many obstacles, batched by shape type.

:class:`swarmplan.geometry.shapes.ObstacleField` calls ``distance_and_gradient`` once per
obstacle from Python; :class:`ShapeBatch` groups the obstacles by shape (all spheres, all
boxes, all cylinders, all capsules) and evaluates each group as one array operation over
``(points, obstacles)``, with the same formulas (``shapes.sdf_*`` broadcast over the
group's parameters), so the values equal the per-shape path up to the rounding of the
batched rotation (tests: 1e-12). Meshes keep their per-obstacle distance grid.
:meth:`ShapeBatch.distance` skips the gradients where only distances are needed.
With ``compiled=True`` (the simulation's swarm-sized worlds, ``runtime.compiled.use_compiled``)
:meth:`ShapeBatch.query` computes every primitive in one compiled pass
(:mod:`swarmplan.geometry._field_kernels`, the same formulas; tests/test_field_kernels.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.geometry.shapes import (
    distance_and_gradient,
    mesh_grid,
    sdf_box,
    sdf_capsule,
    sdf_cylinder,
    sdf_sphere,
)
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module

if TYPE_CHECKING:
    from swarmplan.world.model import Obstacle

_SHAPES = ("sphere", "box", "cylinder", "capsule")


# The distances written per component (``vec3.norm3``: ``np.linalg.norm`` over the last axis,
# the same bits; the largest of three by two ``np.maximum``): a reduction over a length-3 axis
# costs several times the arithmetic (the static guide measures thousands of points a step).


def _max3(q: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(q[..., 0], q[..., 1]), q[..., 2])


def _dist_sphere(p: np.ndarray, radius: np.ndarray) -> np.ndarray:
    return norm3(p) - radius


def _dist_box(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    q = np.abs(p) - half
    return norm3(np.maximum(q, 0.0)) + np.minimum(_max3(q), 0.0)


def _dist_cylinder(p: np.ndarray, radius: np.ndarray, half_height: np.ndarray) -> np.ndarray:
    x, y = p[..., 0], p[..., 1]
    dr = np.sqrt(x * x + y * y) - radius
    dz = np.abs(p[..., 2]) - half_height
    return np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(np.maximum(dr, dz), 0.0)


def _dist_capsule(p: np.ndarray, radius: np.ndarray, half_height: np.ndarray) -> np.ndarray:
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    dz = z - np.clip(z, -half_height, half_height)  # to the closest point of the axis segment
    return np.sqrt(x * x + y * y + dz * dz) - radius


SHAPE_DISTANCE = {
    "sphere": _dist_sphere,
    "box": _dist_box,
    "cylinder": _dist_cylinder,
    "capsule": _dist_capsule,
}


def rotate_rows_of(r0: np.ndarray, r1: np.ndarray, r2: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Points ``(r0, r1, r2)`` (offsets from their obstacles' centres, coordinate by coordinate)
    in their obstacles' frames (``rotation``: one matrix per point, or per column), as ``ShapeBatch``
    turns them: the same bits as its distances per pair of a point and an obstacle."""
    return _rotate(r0, r1, r2, rotation)


def rotate_rows(rel: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``np.einsum("nmk,mkl->nml", rel, rotation)``: each point ``rel[n, m]`` times the matrix
    ``rotation[m]``, written per output coordinate (``(r0 R0l + r1 R1l) + r2 R2l``, the sum
    einsum makes, in its order, from +0.0: the same bits, tests/test_batch_distance_bits.py) at
    ~1/3 of einsum's time for a few obstacles and thousands of points."""
    return _rotate(rel[..., 0], rel[..., 1], rel[..., 2], rotation)


def _rotate(r0: np.ndarray, r1: np.ndarray, r2: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    out = np.empty(r0.shape + (3,))
    for col in range(3):
        out[..., col] = r0 * rotation[:, 0, col] + r1 * rotation[:, 1, col] + r2 * rotation[:, 2, col]
    out += 0.0  # einsum's sums start from +0.0: a zero is never -0.0
    return out


class ShapeBatch:
    """The obstacles grouped by shape; ``query``/``distance`` give ``(N, M)`` in input order."""

    def __init__(self, obstacles: Sequence[Obstacle], compiled: bool = False):
        self.obstacles = tuple(obstacles)
        self.compiled = compiled
        self.groups: dict[str, np.ndarray] = {}
        for shape in _SHAPES:
            idx = np.array([j for j, o in enumerate(self.obstacles) if o.shape == shape], dtype=int)
            if len(idx):
                self.groups[shape] = idx
        # Shape code of each obstacle (index into _SHAPES, -1 for meshes) for subset queries.
        self.code = np.array(
            [_SHAPES.index(o.shape) if o.shape in _SHAPES else -1 for o in self.obstacles], dtype=int
        )
        self.meshes = [j for j, o in enumerate(self.obstacles) if o.shape not in _SHAPES]
        self.mesh_grids = {j: mesh_grid(self.obstacles[j]) for j in self.meshes}
        self.position = np.array([o.position for o in self.obstacles], dtype=float).reshape(-1, 3)
        self.rotation = np.array([o.rotation for o in self.obstacles], dtype=float).reshape(-1, 3, 3)
        # Rotations that are the identity (most boxes and every sphere) need no matmul.
        self.identity = np.array([np.array_equal(R, np.eye(3)) for R in self.rotation], dtype=bool)
        self.params: dict[str, tuple[np.ndarray, ...]] = {}
        for shape, idx in self.groups.items():
            obs = [self.obstacles[j] for j in idx]
            if shape == "sphere":
                self.params[shape] = (np.array([o.radius for o in obs]),)
            elif shape == "box":
                self.params[shape] = (np.array([o.size for o in obs]) / 2,)
            else:
                self.params[shape] = (
                    np.array([o.radius for o in obs]),
                    np.array([o.height for o in obs]) / 2,
                )

        # The same parameters indexed by obstacle (pair queries gather them directly).
        self.by_obstacle: dict[str, tuple[np.ndarray, ...]] = {}
        for shape, idx in self.groups.items():
            cols = []
            for v in self.params[shape]:
                full = np.zeros((len(self.obstacles),) + v.shape[1:])
                full[idx] = v
                cols.append(full)
            self.by_obstacle[shape] = tuple(cols)
        # The compiled query's view: the primitives with and without a rotation, and up to
        # three parameters per obstacle.
        self.primitives = np.flatnonzero(self.code >= 0)
        self.unrotated = np.flatnonzero((self.code >= 0) & self.identity)
        self.rotated = np.flatnonzero((self.code >= 0) & ~self.identity)
        self.prm = np.zeros((len(self.obstacles), 3))
        for shape, idx in self.groups.items():
            cols = np.column_stack(self.by_obstacle[shape])[idx]
            self.prm[idx, : cols.shape[1]] = cols

    def __len__(self) -> int:
        return len(self.obstacles)

    def _local(self, points: np.ndarray, idx: np.ndarray, centers: np.ndarray) -> np.ndarray:
        """Points in each obstacle's frame: (N, len(idx), 3)."""
        if self.identity[idx].all():
            return points[:, None, :] - centers[idx][None]
        c = centers[idx]  # the offsets' coordinates, each as the whole subtraction gives it
        rel = [points[:, None, k] - c[None, :, k] for k in range(3)]
        return _rotate(*rel, self.rotation[idx])

    def _local_exact(self, points: np.ndarray, idx: np.ndarray, centers: np.ndarray) -> np.ndarray:
        """Points in each obstacle's frame, (len(idx), N, 3), computed as
        ``distance_and_gradient`` does it (one (N, 3) @ (3, 3) product per obstacle, the same
        BLAS call, stacked), so the simulator's field is ObstacleField's bit for bit."""
        rel = np.ascontiguousarray(points[None, :, :] - centers[idx][:, None, :])
        return rel @ self.rotation[idx]

    def distance(
        self, points: np.ndarray, centers: np.ndarray | None = None, subset: np.ndarray | None = None
    ) -> np.ndarray:
        """Signed distances (N, M) from ``points`` (N, 3) to every obstacle (at ``centers``, (M, 3)),
        or (N, len(subset)) to the obstacles ``subset`` (indices, in that order)."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        c = self.position if centers is None else np.asarray(centers, dtype=float)
        cols = np.arange(len(self.obstacles)) if subset is None else np.asarray(subset, dtype=int)
        d = np.empty((len(points), len(cols)))
        for shape, idx in self.groups.items():
            pos = np.flatnonzero(self.code[cols] == _SHAPES.index(shape)) if subset is not None else idx
            if not len(pos):
                continue
            sel = cols[pos]
            local = self._local(points, sel, c)
            prm = (
                self.params[shape]
                if subset is None
                else tuple(a[np.searchsorted(idx, sel)] for a in self.params[shape])
            )
            if shape == "sphere":
                d[:, pos] = _dist_sphere(local, prm[0])
            elif shape == "box":
                d[:, pos] = _dist_box(local, prm[0])
            elif shape == "cylinder":
                d[:, pos] = _dist_cylinder(local, *prm)
            else:
                d[:, pos] = _dist_capsule(local, *prm)
        for j in self.meshes:
            for col in np.flatnonzero(cols == j):
                d[:, col] = distance_and_gradient(self.obstacles[j], points, c[j], self.mesh_grids[j])[0]
        return d

    def pair_distance(
        self, points: np.ndarray, bodies: np.ndarray, centers: np.ndarray | None = None
    ) -> np.ndarray:
        """Signed distance (K,) from ``points[k]`` (K, 3) to obstacle ``bodies[k]``: work in
        proportion to the pairs asked for, not points x obstacles."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        bodies = np.asarray(bodies, dtype=int)
        c = self.position if centers is None else np.asarray(centers, dtype=float)
        d = np.empty(len(points))
        for shape in self.groups:
            sel = np.flatnonzero(self.code[bodies] == _SHAPES.index(shape))
            if not len(sel):
                continue
            b = bodies[sel]
            rel = points[sel] - c[b]
            local = rel if self.identity[b].all() else np.einsum("nk,nkl->nl", rel, self.rotation[b])
            prm = tuple(v[b] for v in self.by_obstacle[shape])
            if shape == "sphere":
                d[sel] = _dist_sphere(local, prm[0])
            elif shape == "box":
                d[sel] = _dist_box(local, prm[0])
            elif shape == "cylinder":
                d[sel] = _dist_cylinder(local, *prm)
            else:
                d[sel] = _dist_capsule(local, *prm)
        for j in self.meshes:
            sel = np.flatnonzero(bodies == j)
            if len(sel):
                d[sel] = distance_and_gradient(self.obstacles[j], points[sel], c[j], self.mesh_grids[j])[0]
        return d

    def query(self, points: np.ndarray, centers: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Distances (N, M) and world-frame gradients (N, M, 3), as ``ObstacleField.query``."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        c = self.position if centers is None else np.asarray(centers, dtype=float)
        n, m = len(points), len(self.obstacles)
        d = np.empty((n, m))
        g = np.empty((n, m, 3))
        if self.compiled:
            kernels = kernel_module("swarmplan.geometry._field_kernels")
            if len(self.unrotated):
                kernels.field_query(points, c, self.unrotated, self.code, self.prm, d, g)
            if len(self.rotated):
                # The 3x3 products in numpy (BLAS), as below: the same bits.
                rot = self.rotated
                local = self._local_exact(points, rot, c)
                g_local = np.empty_like(local)
                kernels.field_query_local(local, rot, self.code, self.prm, d, g_local)
                g[:, rot] = (g_local @ self.rotation[rot].transpose(0, 2, 1)).transpose(1, 0, 2)
            for j in self.meshes:
                d[:, j], g[:, j] = distance_and_gradient(self.obstacles[j], points, c[j], self.mesh_grids[j])
            return d, g
        for shape, idx in self.groups.items():
            local = self._local_exact(points, idx, c)  # (m, N, 3)
            prm = tuple(v[:, None] for v in self.params[shape])
            if shape == "sphere":
                dj, gj = sdf_sphere(local, prm[0])
            elif shape == "box":
                dj, gj = sdf_box(local, prm[0])
            elif shape == "cylinder":
                dj, gj = sdf_cylinder(local, *prm)
            else:
                dj, gj = sdf_capsule(local, *prm)
            d[:, idx] = dj.T
            g[:, idx] = (np.ascontiguousarray(gj) @ self.rotation[idx].transpose(0, 2, 1)).transpose(1, 0, 2)
        for j in self.meshes:
            d[:, j], g[:, j] = distance_and_gradient(self.obstacles[j], points, c[j], self.mesh_grids[j])
        return d, g

    def min_distance(
        self, points: np.ndarray, centers: np.ndarray | None = None, d: np.ndarray | None = None
    ) -> np.ndarray:
        """Exact minimum signed distance from each of ``points`` (N, 3) to any obstacle, for
        metrics: as ``ObstacleField.min_distance`` (same rule, same values). Mesh values in
        ``query`` come from the distance grid (a lower bound beyond it), so a mesh is measured
        exactly (trimesh) at the points where its bounding-box distance, a strict lower bound,
        does not exceed the smallest distance known so far. ``d``: this batch's ``query`` at the
        same points and centers, when at hand. ``inf`` per point when there are no obstacles."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        c = self.position if centers is None else np.asarray(centers, dtype=float)
        if d is None:
            d = self.distance(points, c)
        best = np.full(len(points), np.inf)
        if not len(self.meshes) and len(self.obstacles):
            best = d.min(axis=1)  # every column a primitive: the same columns, in the same order
        elif len(self.meshes) < len(self.obstacles):
            best = d[:, self.code >= 0].min(axis=1)
        for j in self.meshes:
            grid = self.mesh_grids[j]
            local = (points - c[j]) @ self.obstacles[j].rotation
            rows = np.flatnonzero(grid.box_lower_bound(local) <= best)
            if len(rows):
                best[rows] = np.minimum(best[rows], grid.exact(local[rows], d[rows, j]))
        return best
