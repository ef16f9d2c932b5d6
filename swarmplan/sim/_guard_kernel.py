"""The turn-ahead guard's clearances compiled: the distance of many predicted positions of fixed
wings to the terrain, the bounds and the primitive obstacles near them, moving ones where they
are at each position's time (``SafetyFilter.guard_fixed_wings``, whose numpy twin
``guard_clearance`` is held to this bit for bit by tests/test_guard_clearance.py).

Why numba: each fixed wing near something is measured at ~170 predicted positions a step
(a full turn plus a second), against a handful of obstacles; in numpy that is a dozen calls
on small temporaries per obstacle, most of the guard's time in a world of a few aircraft.
Each value here is numpy's, operation for operation: the offsets from a body's centre
coordinate by coordinate, a rotated body's frame as ``batch.rotate_rows`` writes it
(``(r0 R0l + r1 R1l) + r2 R2l``, then ``+ 0.0``), the distance ``_shape_kernel.sdf`` (the
twin of ``shapes.DISTANCE``), a mover's offset ``p - (c_t - c_0)`` taken before its frame.

Loaded by ``runtime.compiled.kernel_module`` at the guard's first call (fixed wings load
numba with their model anyway).
"""

from __future__ import annotations

import numpy as np

from swarmplan.geometry._shape_kernel import sdf
from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _body_distance(x, y, z, j, code, prm, position, rotation, identity):  # noqa: ANN001, ANN202
    """Signed distance of the world point (x, y, z) to primitive body ``j`` placed at ``position[j]``."""
    r0 = x - position[j, 0]
    r1 = y - position[j, 1]
    r2 = z - position[j, 2]
    if not identity[j]:
        a = (r0 * rotation[j, 0, 0] + r1 * rotation[j, 1, 0]) + r2 * rotation[j, 2, 0]
        b = (r0 * rotation[j, 0, 1] + r1 * rotation[j, 1, 1]) + r2 * rotation[j, 2, 1]
        c = (r0 * rotation[j, 0, 2] + r1 * rotation[j, 1, 2]) + r2 * rotation[j, 2, 2]
        r0, r1, r2 = a + 0.0, b + 0.0, c + 0.0
    return sdf(code[j], r0, r1, r2, prm[j, 0], prm[j, 1], prm[j, 2])


@njit(cache=True, nogil=True, error_model="numpy")
def clearances(points, radii, extra, ground, bmin, bmax, static, movers, origin, centers, row, bodies):  # noqa: ANN001, ANN201
    """Per point ``points[i]`` (P, 3) of body radius ``radii[i]``: the least of its height above
    ``ground[i]``, its distance inside the bounds ``bmin``..``bmax`` (each less the radius), and
    its distance to the static bodies ``static`` and to the movers ``movers`` (less the radius
    and ``extra[i]``). Mover ``movers[k]`` is at ``centers[row[i], k]`` at the point's time,
    having started at ``origin[k]``: the point is measured shifted back by that way, against
    the body where it started. ``bodies``: the field's ``(code, prm, position, rotation,
    identity)`` (``geometry.bodies.Bodies``)."""
    code, prm, position, rotation, identity = bodies
    n = points.shape[0]
    out = np.empty(n)
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        r = radii[i]
        c = z - ground[i] - r
        inside = min(min(x - bmin[0], bmax[0] - x), min(y - bmin[1], bmax[1] - y))
        inside = min(inside, min(z - bmin[2], bmax[2] - z))
        c = min(c, inside - r)
        if static.shape[0]:
            d = np.inf
            for k in range(static.shape[0]):
                d = min(d, _body_distance(x, y, z, static[k], code, prm, position, rotation, identity))
            c = min(c, d - r - extra[i])
        for k in range(movers.shape[0]):
            t = row[i]
            sx = x - (centers[t, k, 0] - origin[k, 0])
            sy = y - (centers[t, k, 1] - origin[k, 1])
            sz = z - (centers[t, k, 2] - origin[k, 2])
            d = _body_distance(sx, sy, sz, movers[k], code, prm, position, rotation, identity)
            c = min(c, d - r - extra[i])
        out[i] = c
    return out
