"""Compiled per-step geometry of swarm-sized worlds: the distance field of every primitive
obstacle (``ShapeBatch.query``), the nearest static surface per agent
(``Obstacles.nearest_surface``) and the agents' clearance to each other
(``neighbours.agent_clearance_indexed``).

Why numba: at 64-256 agents and 40 obstacles each of these was a dozen or more numpy calls
on (agents, obstacles, 3) temporaries per step (``ShapeBatch.query`` alone ~1.1 ms at 64
agents, 2.2 ms at 256, mostly per-call overhead and temporaries; the clearance a k-d tree
build and query per step); one loop per point and obstacle computes each value where it is
used. The distances are ``_shape_kernel.sdf_grad`` (the shapes' one compiled distance, whose
numpy twin ``shapes.SDF`` the numpy callers use), so the values are theirs bit for bit
(tests/test_distance_kernels.py): rotated bodies get their
local points and their gradients' rotation back from numpy (``ShapeBatch.query``), because
numpy's 3x3 products go through BLAS, whose fused multiply-adds a loop here would not
reproduce (30 % of the coordinates differed in the last bit). The clearance is exact (the
same value per pair, a minimum). Meshes stay with their numpy grid.

Imported lazily (``runtime.compiled.kernel_module``): numba is not loaded by small worlds,
and never at start-up.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry._shape_kernel import sdf_grad
from swarmplan.geometry._sort_kernel import argsort
from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True, error_model="numpy")
def distance_query(points, centers, cols, code, prm, d, g):  # noqa: ANN001, ANN201
    """``d[i, j], g[i, j]`` (signed distance, world-frame gradient) of ``points[i]`` to the
    unrotated primitive obstacle ``j`` placed at ``centers[j]``, for every ``j`` in ``cols``.
    numpy multiplies by the identity through BLAS, whose sums start from +0.0: its products
    with 0 and 1 are exact, so its result is each coordinate plus 0.0 (a -0.0 becomes +0.0)."""
    for i in range(points.shape[0]):
        px = points[i, 0]
        py = points[i, 1]
        pz = points[i, 2]
        for k in range(cols.shape[0]):
            j = cols[k]
            x = (px - centers[j, 0]) + 0.0
            y = (py - centers[j, 1]) + 0.0
            z = (pz - centers[j, 2]) + 0.0
            dist, gx, gy, gz = sdf_grad(code[j], x, y, z, prm[j, 0], prm[j, 1], prm[j, 2])
            d[i, j] = dist
            g[i, j, 0] = gx + 0.0
            g[i, j, 1] = gy + 0.0
            g[i, j, 2] = gz + 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def distance_query_local(local, cols, code, prm, d, g_local):  # noqa: ANN001, ANN201
    """``d[i, cols[k]]`` and the local gradient ``g_local[k, i]`` of the local points
    ``local[k, i]`` (point i in the frame of obstacle ``cols[k]``)."""
    for k in range(cols.shape[0]):
        j = cols[k]
        for i in range(local.shape[1]):
            dist, gx, gy, gz = sdf_grad(
                code[j], local[k, i, 0], local[k, i, 1], local[k, i, 2], prm[j, 0], prm[j, 1], prm[j, 2]
            )
            d[i, j] = dist
            g_local[k, i, 0] = gx
            g_local[k, i, 1] = gy
            g_local[k, i, 2] = gz


@njit(cache=True, nogil=True, error_model="numpy")
def nearest_surface(d, g, static, r, pz, h, gh, clear, normal):  # noqa: ANN001, ANN201
    """``Obstacles.nearest_surface``: per row, the terrain clearance ``pz - h - r`` and its unit
    normal, replaced by the closest static obstacle (the first on ties) when that is closer."""
    n, m = d.shape
    for i in range(n):
        c = pz[i] - h[i] - r[i]
        nx = -gh[i, 0]
        ny = -gh[i, 1]
        nn = math.sqrt(nx * nx + ny * ny + 1.0)
        nx, ny, nz = nx / nn, ny / nn, 1.0 / nn
        best = np.inf
        jb = -1
        for j in range(m):
            if static[j]:
                v = d[i, j] - r[i]
                if jb < 0 or v < best:
                    best = v
                    jb = j
        if jb >= 0 and best < c:
            c = best
            nx, ny, nz = g[i, jb, 0], g[i, jb, 1], g[i, jb, 2]
        clear[i] = c
        normal[i, 0] = nx
        normal[i, 1] = ny
        normal[i, 2] = nz


@njit(cache=True, nogil=True, error_model="numpy")
def agent_clearance(pos, radius, out):  # noqa: ANN001, ANN201
    """``out[i]`` = min over j != i of |p_i - p_j| - (r_i + r_j) (inf alone), exactly.

    A sweep along the diagonal ``w = x + y``: the others are visited outwards from ``i`` in
    ``w`` order and the walk stops once the ``w`` gap alone exceeds sqrt(2) x (the best value
    found plus the largest radii) (``|dw| <= sqrt(2) |dp|``: any farther agent is provably worse;
    a 1e-9 m margin covers rounding). The diagonal, not x: swarms that start on lines of equal x
    (or y) would pile up in one stretch of a single axis. Each pair's value is computed as numpy
    does, so the minimum is the all-pairs one bit for bit."""
    n = pos.shape[0]
    w = pos[:, 0] + pos[:, 1]
    order = argsort(w)
    xs = w[order]
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, radius[i])
    for s in range(n):
        i = order[s]
        xi, yi, zi, ri = pos[i, 0], pos[i, 1], pos[i, 2], radius[i]
        xi_w = xs[s]
        best = np.inf
        for direction in (1, -1):
            t = s + direction
            while 0 <= t < n:
                lim = best + ri + rmax + 1e-9 * (1.0 + abs(best) + ri + rmax)
                gap = xs[t] - xi_w if direction > 0 else xi_w - xs[t]
                if gap > 1.4142135623730951 * lim * (1.0 + 1e-9) + 1e-9 * (1.0 + abs(xi_w)):
                    break
                j = order[t]
                dx = xi - pos[j, 0]
                dy = yi - pos[j, 1]
                dz = zi - pos[j, 2]
                d2 = dx * dx + dy * dy + dz * dz
                if lim <= 0.0 or d2 <= lim * lim:
                    v = math.sqrt(d2) - (ri + radius[j])
                    if v < best:
                        best = v
                t += direction
        out[i] = best
