"""Signed distances from many points to many obstacles, batched by shape type.

:class:`swarmplan.geometry.shapes.ObstacleField` calls ``distance_and_gradient`` once per
obstacle from Python; :class:`ShapeBatch` groups the obstacles by shape (their table,
``bodies.body_table``) and evaluates each group as one array operation over
``(points, obstacles)``, with the same formulas (``shapes.SDF`` and ``shapes.DISTANCE``
broadcast over the group's parameters), so the values equal the per-shape path up to the rounding of the
batched rotation (tests: 1e-12). Meshes keep their per-obstacle distance grid.
:meth:`ShapeBatch.distance` skips the gradients where only distances are needed.
With ``compiled=True`` (the simulation's swarm-sized worlds, ``runtime.compiled.use_compiled``)
:meth:`ShapeBatch.query` computes every primitive in one compiled pass
(:mod:`swarmplan.geometry._distance_kernels`, the same formulas; tests/test_distance_kernels.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.geometry.bodies import body_table
from swarmplan.geometry.shapes import DISTANCE, SDF, distance_and_gradient, mesh_grid
from swarmplan.runtime.compiled import kernel_module, read_only

if TYPE_CHECKING:
    from swarmplan.world.model import Obstacle


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
        self.bodies = body_table(self.obstacles)
        # Shape code of each obstacle (-1 for meshes), its pose and its kernel parameters.
        self.code = self.bodies.code
        self.position = self.bodies.position
        self.rotation = self.bodies.rotation
        self.identity = self.bodies.identity  # the identity needs no matmul (most boxes, spheres)
        self.prm = self.bodies.prm
        # The obstacles of each analytic shape, by code.
        self.groups: dict[int, np.ndarray] = {}
        for code in np.unique(self.code[self.code >= 0]):
            self.groups[int(code)] = np.flatnonzero(self.code == code)
        self.meshes = [int(j) for j in np.flatnonzero(self.code < 0)]
        self.mesh_grids = {j: mesh_grid(self.obstacles[j]) for j in self.meshes}
        # The compiled query's view: the primitives with and without a rotation.
        self.primitives = np.flatnonzero(self.code >= 0)
        self.unrotated = np.flatnonzero((self.code >= 0) & self.identity)
        self.rotated = np.flatnonzero((self.code >= 0) & ~self.identity)

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
        for code, idx in self.groups.items():
            pos = np.flatnonzero(self.code[cols] == code) if subset is not None else idx
            if not len(pos):
                continue
            sel = cols[pos]
            d[:, pos] = DISTANCE[code](self._local(points, sel, c), self.prm[sel])
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
        for code in self.groups:
            sel = np.flatnonzero(self.code[bodies] == code)
            if not len(sel):
                continue
            b = bodies[sel]
            rel = points[sel] - c[b]
            local = rel if self.identity[b].all() else np.einsum("nk,nkl->nl", rel, self.rotation[b])
            d[sel] = DISTANCE[code](local, self.prm[b])
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
            kernels = kernel_module("swarmplan.geometry._distance_kernels")
            if len(self.unrotated):
                kernels.distance_query(points, read_only(c), self.unrotated, self.code, self.prm, d, g)
            if len(self.rotated):
                # The 3x3 products in numpy (BLAS), as below: the same bits.
                rot = self.rotated
                local = self._local_exact(points, rot, c)
                g_local = np.empty_like(local)
                kernels.distance_query_local(local, rot, self.code, self.prm, d, g_local)
                g[:, rot] = (g_local @ self.rotation[rot].transpose(0, 2, 1)).transpose(1, 0, 2)
            for j in self.meshes:
                d[:, j], g[:, j] = distance_and_gradient(self.obstacles[j], points, c[j], self.mesh_grids[j])
            return d, g
        for code, idx in self.groups.items():
            local = self._local_exact(points, idx, c)  # (m, N, 3)
            dj, gj = SDF[code](local, self.prm[idx][:, None, :])
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
