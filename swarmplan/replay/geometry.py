"""Geometry conventions of the world contract, vectorised with numpy.

Box ``size`` is full extents; ``rotation`` is [roll, pitch, yaw] in degrees with
R = Rz(yaw) Ry(pitch) Rx(roll); cylinder and capsule axes are local z; capsule ``height``
is the straight section; quaternions are [qx, qy, qz, qw]; inlined mesh ``vertices`` are
in world coordinates.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from swarmplan.geometry import bodies, shapes


def _euler(rpy) -> Rotation:
    """R = Rz(yaw) Ry(pitch) Rx(roll): extrinsic x, then y, then z ("xyz" in scipy)."""
    return Rotation.from_euler("xyz", np.asarray((list(rpy) + [0, 0, 0])[:3], float), degrees=True)


def euler_deg_to_matrix(rpy) -> np.ndarray:
    """3x3 rotation matrix of [roll, pitch, yaw] in degrees."""
    return _euler(rpy).as_matrix()


def euler_deg_to_quat(rpy) -> np.ndarray:
    """[qx, qy, qz, qw] of R = Rz(yaw) Ry(pitch) Rx(roll), with qw >= 0."""
    q = _euler(rpy).as_quat()
    return -q if q[3] < 0 else q


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrices from quaternions [qx, qy, qz, qw]: (4,) -> (3,3), (N,4) -> (N,3,3).

    Quaternions need not be unit length; an all-zero one (a missing orientation) is the identity.
    """
    q = np.array(q, dtype=float)
    zero = ~np.any(q, axis=-1)
    q[zero] = [0.0, 0.0, 0.0, 1.0]
    return Rotation.from_quat(q).as_matrix()


def primitive_distance(local: np.ndarray, obst: dict[str, Any]) -> np.ndarray | None:
    """Signed distance from points (N,3) in the obstacle's frame to its surface (<0 inside):
    the shapes' numpy distance (``swarmplan.geometry.shapes.DISTANCE``) with the parameters
    the obstacle of the log gives (its world-format keys; a capsule's ``length`` read as its
    ``height``, as older logs name it). Returns None for meshes and unknown shapes."""
    s = bodies.BY_NAME.get(str(obst.get("shape")))
    if s is None or s.code < 0:
        return None
    values = dict(obst)
    if "height" not in values and "length" in values:
        values["height"] = values["length"]
    return shapes.distance_of(s.code, np.asarray(local, float), np.array(s.params(values)))


class MeshDistance:
    """Signed distance (<0 inside) to an inlined triangle mesh, via trimesh proximity.

    Exact queries are costly, so :meth:`min_distance` prunes with the distance to the
    mesh's bounding box (a lower bound) and only queries candidate points exactly.
    """

    def __init__(self, vertices, faces):
        import trimesh

        self.mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, int), process=False)
        self.lo, self.hi = self.mesh.bounds
        self._watertight = bool(self.mesh.is_watertight)

    def distance(self, points: np.ndarray) -> np.ndarray:
        import trimesh

        pts = np.asarray(points, float).reshape(-1, 3)
        if not len(pts):
            return np.zeros(0)
        if self._watertight:
            return -trimesh.proximity.signed_distance(self.mesh, pts)
        _, dist, _ = trimesh.proximity.closest_point(self.mesh, pts)
        return dist

    def box_lower_bound(self, points: np.ndarray) -> np.ndarray:
        d = np.maximum(np.maximum(self.lo - points, points - self.hi), 0.0)
        return np.linalg.norm(d, axis=1)

    def distances_pruned(self, points: np.ndarray, batch: int = 64) -> np.ndarray:
        """Distances of ``points`` (N,3): exact where the point can hold the minimum, a lower
        bound (distance to the bounding box) elsewhere. The minimum of the result is exact, and
        so is every entry <= 0 (contacts)."""
        pts = np.asarray(points, float)
        out = self.box_lower_bound(pts)
        order = np.argsort(out, kind="stable")
        best = math.inf
        start = 0
        while start < len(order):
            cand = order[start : start + batch]
            cand = cand[out[cand] <= max(best, 0.0)]
            if not len(cand):
                break
            d = self.distance(pts[cand])
            out[cand] = d
            best = min(best, float(d.min()))
            start += batch
        return out


def terrain_height(world: dict[str, Any], xy: np.ndarray) -> np.ndarray:
    """z of the terrain height field (sum of Gaussian peaks) at points (N,2)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    z = np.zeros(len(xy))
    for pk in (world.get("terrain") or {}).get("peaks") or []:
        cx, cy = pk["center"][:2]
        sx, sy = (pk.get("spread") or [1, 1])[:2]
        z += float(pk["height"]) * np.exp(-(((xy[:, 0] - cx) / sx) ** 2) - ((xy[:, 1] - cy) / sy) ** 2)
    return z
