"""Analytic signed distances (and their gradients) from points to obstacle shapes, in numpy.

Used by the potential field and the planners' costs, where thousands of point/obstacle
pairs are scored per call; FCL (``collision.py``) remains the authority on contact.
Distances are to the surface: positive outside, negative inside. Meshes use a signed
distance grid built once (voxelization + Euclidean distance transform), so their
distances are approximate to about one voxel.

``SDF[code]`` (distance and gradient) and ``DISTANCE[code]`` (distance only) are the numpy
twins of the compiled ``_shape_kernel.sdf_grad`` and ``sdf``, the same bits (tests/
test_shape_distance.py): each takes local points ``p`` (..., 3) and the kernel parameters
``prm`` (..., 3) of ``bodies.Shape.params``, broadcast against the points.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from swarmplan.geometry import bodies
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime import disk_cache

if TYPE_CHECKING:
    from swarmplan.world.model import Obstacle


_EPS = 1e-12
_DIRECT_PAIRS = 50_000  # point-triangle pairs measured directly in MeshGrid.exact


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, _EPS)


def sdf_sphere(p: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(p, axis=-1)
    return n - radius, _normalize(p)


def sdf_box(p: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q = np.abs(p) - half
    qpos = np.maximum(q, 0.0)
    outside = np.linalg.norm(qpos, axis=-1)
    qmax = q.max(axis=-1)
    d = outside + np.minimum(qmax, 0.0)
    sign = np.where(p >= 0, 1.0, -1.0)
    g_out = _normalize(qpos) * sign
    axis = np.argmax(q, axis=-1)
    g_in = np.zeros_like(p)
    np.put_along_axis(g_in, axis[..., None], np.take_along_axis(sign, axis[..., None], axis=-1), axis=-1)
    g = np.where((outside > 0)[..., None], g_out, g_in)
    return d, g


def sdf_cylinder(p: np.ndarray, radius: float, half_height: float) -> tuple[np.ndarray, np.ndarray]:
    rxy = np.linalg.norm(p[..., :2], axis=-1)
    dr = rxy - radius
    dz = np.abs(p[..., 2]) - half_height
    out_r, out_z = np.maximum(dr, 0.0), np.maximum(dz, 0.0)
    outside = np.hypot(out_r, out_z)
    d = outside + np.minimum(np.maximum(dr, dz), 0.0)
    radial = np.zeros_like(p)
    radial[..., :2] = p[..., :2] / np.maximum(rxy, _EPS)[..., None]
    zdir = np.zeros_like(p)
    zdir[..., 2] = np.where(p[..., 2] >= 0, 1.0, -1.0)
    g_out = _normalize(radial * out_r[..., None] + zdir * out_z[..., None])
    g_in = np.where((dr > dz)[..., None], radial, zdir)
    return d, np.where((outside > 0)[..., None], g_out, g_in)


def sdf_capsule(p: np.ndarray, radius: float, half_height: float) -> tuple[np.ndarray, np.ndarray]:
    closest = np.zeros_like(p)
    closest[..., 2] = np.clip(p[..., 2], -half_height, half_height)
    v = p - closest
    return np.linalg.norm(v, axis=-1) - radius, _normalize(v)


ROOT_STEPS = 200  # _shape_kernel.ROOT_STEPS


def sdf_ellipsoid(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance and gradient to the ellipsoid of semi-axes a, b, c: exact outside,
    minus an upper bound of the depth inside (``_shape_kernel._ellipsoid``, its operations
    element by element: the bisection runs on the points whose bracket is still open)."""
    x, y, z, a, b, c = np.broadcast_arrays(p[..., 0], p[..., 1], p[..., 2], a, b, c)
    ux, uy, uz = x / a, y / b, z / c
    k = np.sqrt(ux * ux + uy * uy + uz * uz)
    n = np.sqrt(x * x + y * y + z * z)
    ea, eb, ec = a * a, b * b, c * c
    d = np.empty(x.shape)
    g = np.empty(x.shape + (3,))
    out = np.flatnonzero(k.ravel() > 1.0)
    if len(out):
        X, Y, Z, A, B, C, EA, EB, EC = (v.ravel()[out] for v in (x, y, z, a, b, c, ea, eb, ec))
        s0 = np.zeros(len(out))
        s1 = np.maximum(np.maximum(A, B), C) * n.ravel()[out]
        s = s0.copy()
        rows = np.arange(len(out))  # the points whose bracket is open
        for _ in range(ROOT_STEPS):
            if not len(rows):
                break
            lo, hi = s0[rows], s1[rows]
            mid = 0.5 * (lo + hi)
            s[rows] = mid
            go = (mid != lo) & (mid != hi)
            rows, mid = rows[go], mid[go]
            r0 = A[rows] * X[rows] / (mid + EA[rows])
            r1 = B[rows] * Y[rows] / (mid + EB[rows])
            r2 = C[rows] * Z[rows] / (mid + EC[rows])
            f = r0 * r0 + r1 * r1 + r2 * r2 - 1.0
            s0[rows[f > 0.0]] = mid[f > 0.0]
            s1[rows[f < 0.0]] = mid[f < 0.0]
            rows = rows[(f > 0.0) | (f < 0.0)]
        dx = X - EA * X / (s + EA)
        dy = Y - EB * Y / (s + EB)
        dz = Z - EC * Z / (s + EC)
        dist = np.sqrt(dx * dx + dy * dy + dz * dz)
        m = np.maximum(dist, _EPS)
        d.ravel()[out] = dist
        g.reshape(-1, 3)[out] = np.stack([dx / m, dy / m, dz / m], axis=-1)
    inside = np.flatnonzero(~(k.ravel() > 1.0))
    if len(inside):
        X, Y, Z, A, B, C, EA, EB, EC = (v.ravel()[inside] for v in (x, y, z, a, b, c, ea, eb, ec))
        K, N = k.ravel()[inside], n.ravel()[inside]
        depth = np.minimum(np.minimum(A, B), C)
        pos = K > 0.0
        depth[pos] = np.minimum(N[pos] / K[pos] - N[pos], depth[pos])
        vx, vy, vz = X / EA, Y / EB, Z / EC
        m = np.maximum(np.sqrt(vx * vx + vy * vy + vz * vz), _EPS)
        d.ravel()[inside] = -depth
        g.reshape(-1, 3)[inside] = np.stack([vx / m, vy / m, vz / m], axis=-1)
    return d, g


# The distances alone, written per component (``vec3.norm3``: ``np.linalg.norm`` over the last
# axis, the same bits; the largest of three by two ``np.maximum``): a reduction over a length-3
# axis costs several times the arithmetic (the static guide measures thousands of points a step).


def _max3(q: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(q[..., 0], q[..., 1]), q[..., 2])


def dist_sphere(p: np.ndarray, radius: np.ndarray) -> np.ndarray:
    return norm3(p) - radius


def dist_box(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    q = np.abs(p) - half
    return norm3(np.maximum(q, 0.0)) + np.minimum(_max3(q), 0.0)


def dist_cylinder(p: np.ndarray, radius: np.ndarray, half_height: np.ndarray) -> np.ndarray:
    x, y = p[..., 0], p[..., 1]
    dr = np.sqrt(x * x + y * y) - radius
    dz = np.abs(p[..., 2]) - half_height
    return np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(np.maximum(dr, dz), 0.0)


def dist_capsule(p: np.ndarray, radius: np.ndarray, half_height: np.ndarray) -> np.ndarray:
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    dz = z - np.clip(z, -half_height, half_height)  # to the closest point of the axis segment
    return np.sqrt(x * x + y * y + dz * dz) - radius


SDF: dict[int, Any] = {
    0: lambda p, prm: sdf_sphere(p, prm[..., 0]),
    1: lambda p, prm: sdf_box(p, prm[..., :3]),
    2: lambda p, prm: sdf_cylinder(p, prm[..., 0], prm[..., 1]),
    3: lambda p, prm: sdf_capsule(p, prm[..., 0], prm[..., 1]),
    4: lambda p, prm: sdf_ellipsoid(p, prm[..., 0], prm[..., 1], prm[..., 2]),
}
"""Shape code -> ``(p, prm) -> (distance, gradient)``: ``_shape_kernel.sdf_grad``'s twin."""

DISTANCE: dict[int, Any] = {
    0: lambda p, prm: dist_sphere(p, prm[..., 0]),
    1: lambda p, prm: dist_box(p, prm[..., :3]),
    2: lambda p, prm: dist_cylinder(p, prm[..., 0], prm[..., 1]),
    3: lambda p, prm: dist_capsule(p, prm[..., 0], prm[..., 1]),
    4: lambda p, prm: sdf_ellipsoid(p, prm[..., 0], prm[..., 1], prm[..., 2])[0],
}
"""Shape code -> ``(p, prm) -> distance``: ``_shape_kernel.sdf``'s twin."""


def distance_of(code: int, p: np.ndarray, prm: np.ndarray) -> np.ndarray:
    """Signed distance of local points ``p`` (..., 3) to the shape ``code`` with parameters
    ``prm`` (3,) or (..., 3)."""
    return DISTANCE[int(code)](np.asarray(p, dtype=float), np.asarray(prm, dtype=float))


def point_triangle_distance(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unsigned distances (N, F) from points (N, 3) to triangles (F, 3, 3), exact.

    Closest point by Voronoi region of the triangle (vertex, edge or face), as in Ericson,
    *Real-Time Collision Detection*, 5.1.5, vectorized over every point-triangle pair.
    """
    p = np.asarray(points, dtype=float)[:, None, :]
    a, b, c = (np.asarray(triangles, dtype=float)[None, :, k, :] for k in range(3))
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_face, w_face = vb / denom, vc / denom
        w_ab, w_ac = d1 / (d1 - d3), d2 / (d2 - d6)
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    # Regions, checked in Ericson's order: the first that applies wins.
    regions = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + w_ab[..., None] * ab),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + w_ac[..., None] * ac),
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + w_bc[..., None] * (c - b)),
    ]
    closest = a + v_face[..., None] * ab + w_face[..., None] * ac
    for mask, point in reversed(regions):
        closest = np.where(mask[..., None], np.broadcast_to(point, closest.shape), closest)
    return np.linalg.norm(p - closest, axis=-1)


class MeshGrid:
    """Signed distance grid of a closed mesh in its local frame (trilinear interpolation).

    Far from the surface the values come from a voxelization and Euclidean distance
    transforms (about one voxel accurate); within three voxels of the surface they are
    exact distances from trimesh, so clearances near walls are reliable.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, cells: int = 48, pad: float | None = None):
        import trimesh

        mesh = trimesh.Trimesh(vertices, faces, process=False)
        # The grid depends on the mesh alone: kept on disk for the next process (~0.6 s each).
        key = disk_cache.digest("mesh grid", np.asarray(vertices), np.asarray(faces), cells, pad)
        stored = disk_cache.load("mesh-grid", key)
        if stored is None:
            stored = self._compute(mesh, cells, pad)
            disk_cache.save("mesh-grid", key, stored)
        self.grid, self.lo, self.pitch = stored["grid"], stored["lo"], float(stored["pitch"])
        self.grad = np.stack(np.gradient(self.grid, self.pitch), axis=-1)
        self.hi = self.lo + (np.array(self.grid.shape) - 1) * self.pitch
        self.mesh_lo, self.mesh_hi = mesh.bounds
        self.mesh = mesh
        self.watertight = bool(stored["watertight"])

    @staticmethod
    def _compute(mesh: Any, cells: int, pad: float | None) -> dict[str, np.ndarray]:
        """The grid's values, corner, pitch and whether the mesh is closed."""
        import trimesh
        from scipy import ndimage

        lo, hi = mesh.bounds
        extent = float(np.max(hi - lo))
        pitch = extent / cells
        pad = 4 * pitch if pad is None else pad
        corner = lo - pad
        shape = np.ceil((hi - lo + 2 * pad) / pitch).astype(int) + 1
        # Voxel centres inside the mesh (filled voxelization), then two distance transforms.
        vox = mesh.voxelized(pitch).fill()
        occ = np.zeros(shape, dtype=bool)
        idx = np.round((vox.points - corner) / pitch).astype(int)
        ok = np.all((idx >= 0) & (idx < shape), axis=1)
        occ[tuple(idx[ok].T)] = True
        outside = ndimage.distance_transform_edt(~occ) * pitch
        inside = ndimage.distance_transform_edt(occ) * pitch
        # Surface lies about half a voxel from voxel centres.
        grid = np.where(occ, -(inside - 0.5 * pitch), outside - 0.5 * pitch)
        # Near the surface, where clearance matters, replace the voxel estimate by exact values.
        band = np.abs(grid) < 3 * pitch
        nodes = corner + np.argwhere(band) * pitch
        if len(nodes):
            grid[band] = -trimesh.proximity.signed_distance(mesh, nodes)  # trimesh: positive inside
        closed = np.array(mesh.is_watertight)
        return {"grid": grid, "lo": corner, "pitch": np.array(pitch), "watertight": closed}

    def exact(self, p: np.ndarray, approx: np.ndarray | None = None) -> np.ndarray:
        """Exact distances from local points (N, 3) to the mesh surface, for metrics.

        Signed (<0 inside) on a closed mesh; on an open one inside is undefined, so unsigned.
        Small meshes are measured against every triangle at once in numpy (trimesh's per-call
        set-up costs milliseconds, every step); the sign is asked of trimesh only where the
        grid value (``approx``, this grid's ``query`` at ``p`` when at hand) is within two
        voxels of the surface or below it, i.e. where the point may be inside.
        """
        import trimesh

        pts = np.asarray(p, dtype=float).reshape(-1, 3)
        if not len(pts):
            return np.zeros(0)
        if len(pts) * len(self.mesh.faces) <= _DIRECT_PAIRS:
            dist = point_triangle_distance(pts, self.mesh.triangles).min(axis=1)
        else:
            dist = trimesh.proximity.closest_point(self.mesh, pts)[1]
        if self.watertight:
            approx = self.query(pts)[0] if approx is None else np.asarray(approx, dtype=float)
            maybe_inside = approx < 2 * self.pitch
            if maybe_inside.any():  # trimesh: positive inside
                dist[maybe_inside] = -trimesh.proximity.signed_distance(self.mesh, pts[maybe_inside])
        return dist

    def box_lower_bound(self, p: np.ndarray) -> np.ndarray:
        """Distance from local points (N, 3) to the mesh's bounding box: never above the true distance."""
        return np.linalg.norm(p - np.clip(p, self.mesh_lo, self.mesh_hi), axis=-1)

    def query(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        from scipy import ndimage

        flat = p.reshape(-1, 3)
        clamped = np.clip(flat, self.lo, self.hi)
        coords = ((clamped - self.lo) / self.pitch).T
        d = ndimage.map_coordinates(self.grid, coords, order=1, mode="nearest")
        g = np.stack(
            [ndimage.map_coordinates(self.grad[..., k], coords, order=1, mode="nearest") for k in range(3)],
            -1,
        )
        # Outside the grid the clamped value plus the offset would overstate clearance off the
        # diagonals. Two lower bounds hold there: the distance to the mesh's bounding box (the
        # surface lies inside it) and the clamped value minus the offset (triangle inequality);
        # the larger is within a few voxels of the truth and exact far away along the axes.
        off = flat - clamped
        far = np.linalg.norm(off, axis=-1) > 0
        if far.any():
            pf = flat[far]
            to_box = pf - np.clip(pf, self.mesh_lo, self.mesh_hi)
            d_box = np.linalg.norm(to_box, axis=-1)
            d[far] = np.maximum(d_box, d[far] - np.linalg.norm(off[far], axis=-1))
            g[far] = to_box
        g = _normalize(g)
        return d.reshape(p.shape[:-1]), g.reshape(p.shape)


_GRID_CACHE: dict[tuple[bytes, bytes], MeshGrid] = {}


def mesh_grid(o: Obstacle) -> MeshGrid:
    """The (cached) distance grid of a mesh obstacle: built once per distinct mesh per process."""
    key = (o.vertices.tobytes(), o.faces.tobytes())
    if key not in _GRID_CACHE:
        _GRID_CACHE[key] = MeshGrid(o.vertices, o.faces)
    return _GRID_CACHE[key]


def _local_sdf(o: Obstacle, local: np.ndarray, grid: MeshGrid | None) -> tuple[np.ndarray, np.ndarray]:
    if o.shape == "mesh":
        return (grid if grid is not None else mesh_grid(o)).query(local)
    s = bodies.shape(o.shape)
    return SDF[s.code](local, np.array(s.params(o.shape_params)))


def distance_and_gradient(
    o: Obstacle, points: np.ndarray, center: np.ndarray | None = None, grid: MeshGrid | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance from ``points`` (..., 3) to ``o`` placed at ``center`` and its world-frame gradient."""
    c = o.position if center is None else center
    local = (np.asarray(points, dtype=float) - c) @ o.rotation
    d, g = _local_sdf(o, local, grid)
    return d, g @ o.rotation.T


def signed_distance(o: Obstacle, points: np.ndarray, center: np.ndarray | None = None) -> np.ndarray:
    """Signed distance from ``points`` (N, 3) to obstacle ``o`` (at ``center``, default its t=0 position)."""
    return distance_and_gradient(o, points, center)[0]


class ObstacleField:
    """Distances from many points to every obstacle at once, for the potential field and costs.

    Mesh grids are built once here. ``query(points, centers)`` returns ``(N, M)`` distances
    and ``(N, M, 3)`` gradients for ``N`` points and the ``M`` obstacles placed at ``centers``.
    """

    def __init__(self, obstacles: Sequence[Obstacle]):
        self.obstacles = tuple(obstacles)
        self.mesh_grids = {i: mesh_grid(o) for i, o in enumerate(self.obstacles) if o.shape == "mesh"}

    def __len__(self) -> int:
        return len(self.obstacles)

    def query(self, points: np.ndarray, centers: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(points, dtype=float)
        n, m = len(points), len(self.obstacles)
        d = np.empty((n, m))
        g = np.empty((n, m, 3))
        for j, o in enumerate(self.obstacles):
            c = o.position if centers is None else centers[j]
            d[:, j], g[:, j] = distance_and_gradient(o, points, c, self.mesh_grids.get(j))
        return d, g

    def min_distance(
        self, points: np.ndarray, centers: np.ndarray | None = None, d: np.ndarray | None = None
    ) -> np.ndarray:
        """Exact minimum signed distance from each of ``points`` (N, 3) to any obstacle, for metrics.

        ``query`` is exact for primitives, but mesh values come from the distance grid: about
        one voxel off in it, and beyond it only a lower bound (several metres low over a
        hangar's roof). A mesh is queried exactly (trimesh) only at the points where it can be
        the nearest body: where its bounding-box distance, a strict lower bound, does not exceed
        the smallest distance known so far. ``d`` is this field's ``query`` at the same points
        and centers, when already at hand. Returns ``inf`` per point when there are no obstacles.
        """
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        if d is None:
            d = self.query(points, centers)[0]
        best = np.full(len(points), np.inf)
        prim = [j for j in range(len(self.obstacles)) if j not in self.mesh_grids]
        if prim:
            best = d[:, prim].min(axis=1)
        for j, grid in self.mesh_grids.items():
            o = self.obstacles[j]
            c = o.position if centers is None else centers[j]
            local = (points - c) @ o.rotation
            rows = np.flatnonzero(grid.box_lower_bound(local) <= best)
            if len(rows):
                best[rows] = np.minimum(best[rows], grid.exact(local[rows], d[rows, j]))
        return best
