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

from swarmplan.flight._fixed_wing_kernel import manoeuvre_settling, manoeuvre_start, manoeuvre_step
from swarmplan.geometry._shape_kernel import exact, sdf
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


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _room(x, y, z, r, ground, bmin, bmax):  # noqa: ANN001, ANN202
    """The height of a body of radius ``r`` at (x, y, z) above ``ground`` and its distance inside
    the bounds ``bmin``..``bmax``, the less of the two."""
    c = z - ground - r
    inside = min(min(x - bmin[0], bmax[0] - x), min(y - bmin[1], bmax[1] - y))
    inside = min(inside, min(z - bmin[2], bmax[2] - z))
    return min(c, inside - r)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _clearance(x, y, z, r, e, ground, scene, t):  # noqa: ANN001, ANN202
    """The clearance of one point (x, y, z) of body radius ``r`` at row ``t`` of the movers'
    centres (:func:`clearances`; ``scene``: :func:`first_safe`'s)."""
    bmin, bmax, static, movers, origin, centers, bodies = scene
    code, prm, position, rotation, identity = bodies
    c = _room(x, y, z, r, ground, bmin, bmax)
    if static.shape[0]:
        d = np.inf
        for k in range(static.shape[0]):
            d = min(d, _body_distance(x, y, z, static[k], code, prm, position, rotation, identity))
        c = min(c, d - r - e)
    for k in range(movers.shape[0]):
        sx = x - (centers[t, k, 0] - origin[k, 0])
        sy = y - (centers[t, k, 1] - origin[k, 1])
        sz = z - (centers[t, k, 2] - origin[k, 2])
        d = _body_distance(sx, sy, sz, movers[k], code, prm, position, rotation, identity)
        c = min(c, d - r - e)
    return c


@njit(cache=True, nogil=True, error_model="numpy")
def clearances(points, radii, extra, ground, bmin, bmax, static, movers, origin, centers, row, bodies):  # noqa: ANN001, ANN201
    """Per point ``points[i]`` (P, 3) of body radius ``radii[i]``: the least of its height above
    ``ground[i]``, its distance inside the bounds ``bmin``..``bmax`` (each less the radius), and
    its distance to the static bodies ``static`` and to the movers ``movers`` (less the radius
    and ``extra[i]``). Mover ``movers[k]`` is at ``centers[row[i], k]`` at the point's time,
    having started at ``origin[k]``: the point is measured shifted back by that way, against
    the body where it started. ``bodies``: the field's ``(code, prm, position, rotation,
    identity)`` (``geometry.bodies.Bodies``)."""
    n = points.shape[0]
    out = np.empty(n)
    scene = (bmin, bmax, static, movers, origin, centers, bodies)
    for i in range(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        out[i] = _clearance(x, y, z, radii[i], extra[i], ground[i], scene, row[i])
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _clearance_over(x, y, z, r, e, floor, scene, t, seen, level):  # noqa: ANN001, ANN202
    """:func:`_clearance` of the point (x, y, z) over flat ground where it is below ``floor``;
    elsewhere a value at least ``floor`` (the clearance is too). A body whose distance is exact
    (1-Lipschitz) is measured again only when the point (shifted back by its way, for a mover)
    has come farther from ``seen[j]``, where it was last measured, than that measure's value
    ``level[j]`` (less a rounding allowance) is over ``floor``: closer, it cannot be below
    ``floor`` (``level[j] = -inf``: measure)."""
    bmin, bmax, static, movers, origin, centers, bodies = scene
    code, prm, position, rotation, identity = bodies
    c = _room(x, y, z, r, 0.0, bmin, bmax)
    ns = static.shape[0]
    for j in range(ns + movers.shape[0]):
        if j < ns:
            body, sx, sy, sz = static[j], x, y, z
        else:
            k = j - ns
            body = movers[k]
            sx = x - (centers[t, k, 0] - origin[k, 0])
            sy = y - (centers[t, k, 1] - origin[k, 1])
            sz = z - (centers[t, k, 2] - origin[k, 2])
        room = level[j] - floor
        if room > 0.0:
            dx, dy, dz = sx - seen[j, 0], sy - seen[j, 1], sz - seen[j, 2]
            if dx * dx + dy * dy + dz * dz < room * room:
                continue
        d = _body_distance(sx, sy, sz, body, code, prm, position, rotation, identity)
        c = min(c, d - r - e)
        if exact(code[body]):
            seen[j, 0], seen[j, 1], seen[j, 2] = sx, sy, sz
            level[j] = (d - r - e) - (1e-6 * (1.0 + abs(d)) + 1e-9 * (abs(sx) + abs(sy) + abs(sz)))
    return c


@njit(cache=True, nogil=True, error_model="numpy")
def first_safe(rollout, rows, radii, extra, required, scene):  # noqa: ANN001, ANN201
    """``rollout = (pos, vel, kappa, turn, top, amax, radius, climb, roll, dt)`` (the arguments
    of ``_fixed_wing_kernel.rollouts`` but the steps), ``scene = (bmin, bmax, static, movers,
    origin, centers, bodies)`` (those of :func:`clearances` but the points' own).

    Per fixed wing i at ``pos[i]``/``vel[i]``/``kappa[i]``: its clearance where it is (the
    movers at row ``rows[0]``) and the first of its sustained manoeuvres c (``turn[i, c]``,
    ``top[i, c]``; ``_fixed_wing_kernel.manoeuvre_step``) whose predicted positions all keep
    ``required[i]``, -1 if none: the horizon H = (len(rows) - 1) / 2 steps and one more for
    each step it was settling (``_fixed_wing_kernel.rollout``), step k at row ``rows[k + 1]``;
    each position measured as :func:`clearances` measures it over flat ground (height 0), and a
    manoeuvre left at its first position that does not keep it. Returns both, (n,) each."""
    pos, vel, kappa, turn, tops, amax, radius, climb, roll, dt = rollout
    static, movers = scene[2], scene[3]
    n, nc, base = pos.shape[0], turn.shape[1], (rows.shape[0] - 1) // 2
    here = np.empty(n)
    first = np.full(n, -1, dtype=np.int64)
    seen = np.empty((static.shape[0] + movers.shape[0], 3))
    level = np.empty(static.shape[0] + movers.shape[0])
    for i in range(n):
        r, e, need = radii[i], extra[i], required[i]
        here[i] = _clearance(pos[i, 0], pos[i, 1], pos[i, 2], r, e, 0.0, scene, rows[0])
        for c in range(nc):
            state, speed = manoeuvre_start(pos[i], vel[i], kappa[i])
            level[:] = -np.inf
            safe = True
            top, w, a, rad, g, p = tops[i, c], turn[i, c], amax[i], radius[i], climb[i], roll[i]
            k, more = 0, 0
            while k < base + more:
                if more < base and manoeuvre_settling(state, speed, top, rad, g, dt):
                    more += 1
                state = manoeuvre_step(state, speed, top, w, a, rad, g, p, dt)
                x, y, z = state[0], state[1], state[2]
                k += 1
                if _clearance_over(x, y, z, r, e, need, scene, rows[k], seen, level) < need:
                    safe = False
                    break
            if safe:
                first[i] = c
                break
    return here, first


@njit(cache=True, nogil=True, error_model="numpy")
def least_clearances(rollout, rows, radii, extra, required, scene):  # noqa: ANN001, ANN201
    """Per fixed wing i and manoeuvre c of ``rollout`` (:func:`first_safe`'s): the least
    clearance of its predicted positions (the horizon H = len(rows) / 2 steps and one more for
    each step it was settling, step k at row ``rows[k]``), each measured as :func:`clearances`
    measures it over flat ground, a body measured again only where it could be nearer than the
    least so far; and the steps it keeps ``required[i]`` before the first that does not (all
    it flew when none). Returns both, (n, C) each."""
    pos, vel, kappa, turn, tops, amax, radius, climb, roll, dt = rollout
    static, movers = scene[2], scene[3]
    n, nc, base = pos.shape[0], turn.shape[1], rows.shape[0] // 2
    out = np.empty((n, nc))
    kept = np.empty((n, nc), dtype=np.int64)
    seen = np.empty((static.shape[0] + movers.shape[0], 3))
    level = np.empty(static.shape[0] + movers.shape[0])
    for i in range(n):
        for c in range(nc):
            state, speed = manoeuvre_start(pos[i], vel[i], kappa[i])
            top, w, a, rad, g, p = tops[i, c], turn[i, c], amax[i], radius[i], climb[i], roll[i]
            level[:] = -np.inf
            least = np.inf
            k, more, until = 0, 0, -1
            while k < base + more:
                if more < base and manoeuvre_settling(state, speed, top, rad, g, dt):
                    more += 1
                state = manoeuvre_step(state, speed, top, w, a, rad, g, p, dt)
                x, y, z = state[0], state[1], state[2]
                c_k = _clearance_over(x, y, z, radii[i], extra[i], least, scene, rows[k], seen, level)
                least = min(least, c_k)
                if until < 0 and c_k < required[i]:
                    until = k
                k += 1
            out[i, c] = least
            kept[i, c] = k if until < 0 else until
    return out, kept
