"""Compiled (numba) decisions of the swept checks that FCL made one Python call at a time.

Why numba: a step of a 64-agent world with 32 movers sent ~100 capsule-vs-body pairs through
python-fcl per swept check (the braking margin runs seven checks per step in a bisection), each
paying a Python call, a transform and an fcl object update; numpy cannot express the per-pair
early exits. Imported at the first swept check (numba stays out of start-up).

How it stays exact. A sphere of radius ``r`` swept along ``a -> b`` touches a convex body
exactly when ``min_t dist(a + t (b - a), body) <= r``, ``t`` in [0, 1]. ``dist`` to a convex
body is convex in the point and 1-Lipschitz, so ``f(t) = dist(a + t (b - a), body)`` is convex
and ``|b - a|``-Lipschitz in ``t``. For each (agent, body) pair the kernel brackets its minimum:

- an upper bound: any evaluated ``f(t)`` (a real point of the segment at that distance);
- a lower bound: the distance between the bounding boxes of the segment and of the body
  (local frame), then, after golden-section steps (which keep a minimiser inside the bracket
  ``[lo, hi]`` because ``f`` is convex), ``f(x) - |b - a| (hi - lo)`` for ``x`` in the bracket.

A pair is decided only outside the band ``r ± BAND``: ``lower > r + BAND`` is no contact,
``upper < r - BAND`` is contact. Inside the band the pair is *undecided* and the caller asks
FCL, the authority, as before: the kernel never replaces FCL where FCL's own tolerance or
rounding could decide differently. Meshes are always undecided (FCL decides).

Which pairs are looked at is the previous prefilter (bounding sphere within ``r + slack`` of
the segment, for moving bodies the relative motion), in world order: statics, then movers.

Also here, compiled for the same reason and equal term for term to their numpy references:
agent-agent contacts on a step, the near-miss pairs, and arrivals at the goals.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry._shape_kernel import SPHERE, exact, half_extents, sdf
from swarmplan.geometry._sort_kernel import argsort
from swarmplan.runtime.compiled import njit

MESH = -1
"""The code of meshes (``bodies.MESH``; the other codes are ``_shape_kernel``'s)."""

BAND = 1e-4
"""Metres either side of contact (``dist == r``) where FCL decides, not the kernel. On tangent
sweeps FCL's primitive tests agreed with exact geometry at 1e-6 m and beyond and disagreed only
at 1e-7 m and below (tests/test_swept_kernels.py checks the band's edge)."""

NO, HIT, UNDECIDED = 0, 1, 2

_GOLD = 0.6180339887498949
_RESOLVE = 1e-3 * BAND
"""Bracket width (metres along the segment) at which the golden search gives up: the pair is
then within ``BAND + _RESOLVE`` of contact and goes to FCL."""


@njit(cache=True)
def _point_distance(x: float, y: float, z: float, code: int, d0: float, d1: float, d2: float) -> float:
    """Distance from a local-frame point to the body, 0 inside (``_shape_kernel.sdf``)."""
    return max(sdf(code, x, y, z, d0, d1, d2), 0.0)


@njit(cache=True)
def classify(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    r: float,
    code: int,
    d0: float,
    d1: float,
    d2: float,
) -> int:
    """NO, HIT or UNDECIDED for the sphere of radius ``r`` swept ``a -> b`` (body's local frame)."""
    if code == MESH:
        return UNDECIDED
    hx, hy, hz = half_extents(code, d0, d1, d2)
    # Lower bound 1: the gap between the segment's bounding box and the body's.
    gx = max(min(ax, bx) - hx, -hx - max(ax, bx), 0.0)
    gy = max(min(ay, by) - hy, -hy - max(ay, by), 0.0)
    gz = max(min(az, bz) - hz, -hz - max(az, bz), 0.0)
    if math.sqrt(gx * gx + gy * gy + gz * gz) > r + BAND:
        return NO
    if not exact(code):  # no exact distance to bracket: FCL decides
        return UNDECIDED
    ux, uy, uz = bx - ax, by - ay, bz - az
    length = math.sqrt(ux * ux + uy * uy + uz * uz)
    if code == SPHERE:
        # Closed form: the point of the segment nearest the centre.
        den = ux * ux + uy * uy + uz * uz
        s = 0.0
        if den > 1e-18:
            s = min(max(-(ax * ux + ay * uy + az * uz) / den, 0.0), 1.0)
        cx, cy, cz = ax + s * ux, ay + s * uy, az + s * uz
        d = math.sqrt(cx * cx + cy * cy + cz * cz) - d0
        # The rounding of a few flops on coordinates of ~1e3 m is far below BAND.
        if d > r + BAND:
            return NO
        if d < r - BAND:
            return HIT
        return UNDECIDED
    f0 = _point_distance(ax, ay, az, code, d0, d1, d2)
    f1 = _point_distance(bx, by, bz, code, d0, d1, d2)
    upper = min(f0, f1)
    if upper < r - BAND:
        return HIT
    if length * 1.0 <= _RESOLVE:
        return NO if f0 - length > r + BAND else UNDECIDED
    lo, hi = 0.0, 1.0
    x1 = hi - _GOLD * (hi - lo)
    x2 = lo + _GOLD * (hi - lo)
    g1 = _point_distance(ax + x1 * ux, ay + x1 * uy, az + x1 * uz, code, d0, d1, d2)
    g2 = _point_distance(ax + x2 * ux, ay + x2 * uy, az + x2 * uz, code, d0, d1, d2)
    while True:
        upper = min(upper, g1, g2)
        if upper < r - BAND:
            return HIT
        # A minimiser lies in [lo, hi] and x1 too: f(x*) >= f(x1) - length * (hi - lo).
        if g1 - length * (hi - lo) > r + BAND:
            return NO
        if (hi - lo) * length <= _RESOLVE:
            return UNDECIDED
        if g1 < g2:
            hi, x2, g2 = x2, x1, g1
            x1 = hi - _GOLD * (hi - lo)
            g1 = _point_distance(ax + x1 * ux, ay + x1 * uy, az + x1 * uz, code, d0, d1, d2)
        else:
            lo, x1, g1 = x1, x2, g2
            x2 = lo + _GOLD * (hi - lo)
            g2 = _point_distance(ax + x2 * ux, ay + x2 * uy, az + x2 * uz, code, d0, d1, d2)


@njit(cache=True)
def _classify_body(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    r: float,
    c: np.ndarray,
    rot: np.ndarray,
    code: int,
    dims: np.ndarray,
) -> int:
    """:func:`classify` for a body at ``c`` rotated by ``rot`` (world = rot @ local + c)."""
    ax, ay, az = ax - c[0], ay - c[1], az - c[2]
    bx, by, bz = bx - c[0], by - c[1], bz - c[2]
    la = (
        rot[0, 0] * ax + rot[1, 0] * ay + rot[2, 0] * az,
        rot[0, 1] * ax + rot[1, 1] * ay + rot[2, 1] * az,
        rot[0, 2] * ax + rot[1, 2] * ay + rot[2, 2] * az,
    )
    lb = (
        rot[0, 0] * bx + rot[1, 0] * by + rot[2, 0] * bz,
        rot[0, 1] * bx + rot[1, 1] * by + rot[2, 1] * bz,
        rot[0, 2] * bx + rot[1, 2] * by + rot[2, 2] * bz,
    )
    return classify(la[0], la[1], la[2], lb[0], lb[1], lb[2], r, code, dims[0], dims[1], dims[2])


@njit(cache=True)
def _outside_box(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    cx: float,
    cy: float,
    cz: float,
    lim: float,
) -> bool:
    """The point c is farther than ``lim`` from the segment a -> b on some axis (then it is
    farther than ``lim`` from the segment): a cheap reject before the exact prefilter."""
    return (
        cx < min(ax, bx) - lim
        or cx > max(ax, bx) + lim
        or cy < min(ay, by) - lim
        or cy > max(ay, by) + lim
        or cz < min(az, bz) - lim
        or cz > max(az, bz) + lim
    )


@njit(cache=True)
def _point_segment(cx: float, cy: float, cz: float, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from a point to the segment a -> b."""
    ux, uy, uz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    wx, wy, wz = cx - a[0], cy - a[1], cz - a[2]
    den = max(ux * ux + uy * uy + uz * uz, 1e-18)
    s = min(max((wx * ux + wy * uy + wz * uz) / den, 0.0), 1.0)
    ex, ey, ez = wx - s * ux, wy - s * uy, wz - s * uz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True)
def _relative_min(a: np.ndarray, b: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> float:
    """min over s in [0, 1] of |(a + s (b - a)) - (q0 + s (q1 - q0))| (both move linearly)."""
    w0x, w0y, w0z = a[0] - q0[0], a[1] - q0[1], a[2] - q0[2]
    dx = (b[0] - a[0]) - (q1[0] - q0[0])
    dy = (b[1] - a[1]) - (q1[1] - q0[1])
    dz = (b[2] - a[2]) - (q1[2] - q0[2])
    den = dx * dx + dy * dy + dz * dz
    s = 0.0
    if den > 1e-18:
        s = min(max(-(w0x * dx + w0y * dy + w0z * dz) / den, 0.0), 1.0)
    ex, ey, ez = w0x + s * dx, w0y + s * dy, w0z + s * dz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True)
def sweep_one(
    a: np.ndarray,
    b: np.ndarray,
    r: float,
    statics: tuple,
    movers: tuple,
    slack: float,
    first: bool,
) -> tuple[int, int]:
    """The bodies (statics, then movers, world order) the swept sphere touches.

    Returns (kind, index): kind 0 none, 1 static ``index``, 2 mover ``index``, 3 undecided (FCL
    must decide). With ``first`` the answer is the first body in order that touches (an
    undecided body before it makes the whole answer undecided); without, any body that
    certainly touches is enough (a yes/no question). ``statics``: (centres, bounding radii,
    shape codes, rotations, parameters) of the static bodies (``CollisionWorld.kernel_statics``);
    ``movers``: (positions at the step's start and end, bounding radii, codes, rotations,
    parameters) of the moving ones (``CollisionWorld.kernel_movers``)."""
    s_center, s_radius, s_code, s_rot, s_dims = statics
    q0, q1, m_radius, m_code, m_rot, m_dims = movers
    undecided = False
    for k in range(len(s_radius)):
        # The cheap reject (twice the slack: it only saves work) before the previous prefilter.
        lim = s_radius[k] + r + 2.0 * slack
        if _outside_box(
            a[0], a[1], a[2], b[0], b[1], b[2], s_center[k, 0], s_center[k, 1], s_center[k, 2], lim
        ):
            continue
        if _point_segment(s_center[k, 0], s_center[k, 1], s_center[k, 2], a, b) - s_radius[k] > r + slack:
            continue
        c = _classify_body(a[0], a[1], a[2], b[0], b[1], b[2], r, s_center[k], s_rot[k], s_code[k], s_dims[k])
        if c == HIT:
            if first and undecided:
                return 3, -1
            return 1, k
        if c == UNDECIDED:
            undecided = True
    for k in range(len(m_radius)):
        # Relative to the body the agent moves a - q0 -> b - q1 and the body sits at the origin.
        lim = m_radius[k] + r + 2.0 * slack
        bx, by, bz = b[0] - q1[k, 0], b[1] - q1[k, 1], b[2] - q1[k, 2]
        if _outside_box(a[0] - q0[k, 0], a[1] - q0[k, 1], a[2] - q0[k, 2], bx, by, bz, 0.0, 0.0, 0.0, lim):
            continue
        if _relative_min(a, b, q0[k], q1[k]) - m_radius[k] - r > slack:
            continue
        # Relative motion: the body stays at q0, the agent sweeps a -> b - (q1 - q0).
        c = _classify_body(
            a[0], a[1], a[2],
            b[0] - (q1[k, 0] - q0[k, 0]), b[1] - (q1[k, 1] - q0[k, 1]), b[2] - (q1[k, 2] - q0[k, 2]),
            r, q0[k], m_rot[k], m_code[k], m_dims[k],
        )  # fmt: skip
        if c == HIT:
            if first and undecided:
                return 3, -1
            return 2, k
        if c == UNDECIDED:
            undecided = True
    return (3, -1) if undecided else (0, -1)


@njit(cache=True)
def sweep_many(
    p0: np.ndarray,
    p1: np.ndarray,
    radii: np.ndarray,
    skip: np.ndarray,
    statics: tuple,
    movers: tuple,
    slack: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sweep_one` (first body in order) for each row not ``skip``ped: kinds and indices."""
    n = len(p0)
    kind = np.zeros(n, np.int64)
    index = np.full(n, -1, np.int64)
    for i in range(n):
        if skip[i]:
            continue
        kind[i], index[i] = sweep_one(p0[i], p1[i], radii[i], statics, movers, slack, True)
    return kind, index


@njit(cache=True)
def _touches(
    start: np.ndarray,
    u: np.ndarray,
    length: float,
    r: float,
    bounds: tuple,
    statics: tuple,
    movers: tuple,
    slack: float,
) -> int:
    """NO / HIT / UNDECIDED for the sweep ``start -> start + u * length`` over flat ground:
    ``first_hits``' bounds (``bounds``: lowest and highest corner), ground and body checks as a
    yes/no question."""
    end = np.empty(3)
    for c in range(3):
        end[c] = start[c] + u[c] * length
    return step_status(start, end, r, bounds, True, statics, movers, slack)


@njit(cache=True, inline="always")
def _closest_gap(w0x: float, w0y: float, w0z: float, dwx: float, dwy: float, dwz: float) -> float:
    """Smallest ``|w0 + s dw|`` over ``s`` in [0, 1]: the closest approach of two points that
    start ``w0`` apart and move ``dw`` relative to each other in one step
    (``segment_segment_min_distance``'s terms)."""
    aa = dwx * dwx + dwy * dwy + dwz * dwz
    s = 0.0
    if aa > 1e-18:
        s = min(max(-(w0x * dwx + w0y * dwy + w0z * dwz) / max(aa, 1e-18), 0.0), 1.0)
    ex, ey, ez = w0x + s * dwx, w0y + s * dwy, w0z + s * dwz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True, inline="always")
def step_status(
    a: np.ndarray,
    b: np.ndarray,
    r: float,
    bounds: tuple,
    bodies: bool,
    statics: tuple,
    movers: tuple,
    slack: float,
) -> int:
    """NO, HIT or UNDECIDED for the step ``a -> b`` over flat ground: ``first_hits``' bounds
    (``bounds``: lowest and highest corner), ground and body checks as a yes/no question
    (``bodies``: the world has obstacles; without, the bodies' check is skipped, its answer
    being NO)."""
    lo_b, hi_b = bounds
    for c in range(3):
        if b[c] < lo_b[c] - 1e-9 or b[c] > hi_b[c] + 1e-9:
            return HIT
    if min(a[2], b[2]) < r - 1e-9:
        return HIT
    if not bodies:
        return NO
    kind, _ = sweep_one(a, b, r, statics, movers, slack, False)
    return UNDECIDED if kind == 3 else (NO if kind == 0 else HIT)


@njit(cache=True)
def free_distances(
    start: np.ndarray,
    u: np.ndarray,
    reach: np.ndarray,
    radii: np.ndarray,
    bounds: tuple,
    statics: tuple,
    movers: tuple,
    slack: float,
    halvings: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The braking margin's bisection (``SafetyFilter.braking_margin``), row by row: whether the
    sweep over ``reach`` touches something (1), not (0), or FCL must decide (2, the row is then
    redone by the caller), and for touching rows the free distance ``lo`` after ``halvings``
    halvings of [0, reach] (the same midpoints as the numpy bisection)."""
    n = len(start)
    status = np.zeros(n, np.int64)
    free = np.zeros(n)
    for i in range(n):
        h = _touches(start[i], u[i], reach[i], radii[i], bounds, statics, movers, slack)
        if h != HIT:
            status[i] = h
            continue
        status[i] = 1
        lo, hi = 0.0, reach[i]
        for _ in range(halvings):
            mid = 0.5 * (lo + hi)
            h = _touches(start[i], u[i], mid, radii[i], bounds, statics, movers, slack)
            if h == UNDECIDED:
                status[i] = 2
                break
            if h == HIT:
                hi = mid
            else:
                lo = mid
        free[i] = lo
    return status, free


@njit(cache=True)
def agent_contacts(
    p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, active: np.ndarray, margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i < j in ``np.triu_indices`` order, of agents (one of them active) whose
    swept spheres (inflated by ``margin``) come closer than the sum of their radii + margin.

    Sweep and prune on the step midpoints' x + y: two points moving along their steps stay within
    half of each step of their midpoints, so a pair can only touch when its midpoints are
    within ``reach`` (both half-steps, both radii and the margin) on every axis. The distance of
    each candidate pair is ``segment_segment_min_distance``'s arithmetic, term for term."""
    n = len(p0)
    mid = np.empty((n, 3))
    half_max = 0.0
    r_max = 0.0
    for i in range(n):
        dx, dy, dz = p1[i, 0] - p0[i, 0], p1[i, 1] - p0[i, 1], p1[i, 2] - p0[i, 2]
        half_max = max(half_max, 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz))
        r_max = max(r_max, radii[i])
        for c in range(3):
            mid[i, c] = 0.5 * (p0[i, c] + p1[i, c])
    # Slightly wider than needed: the rounding of the midpoints cannot drop a pair.
    reach = (2.0 * half_max + 2.0 * r_max + margin) * (1.0 + 1e-9) + 1e-9
    # Swept along the diagonal x + y (|dw| < 2 reach for a candidate; swarms that start on lines
    # of equal x or y would pile up on one axis), the margin covering w's rounding.
    w = mid[:, 0] + mid[:, 1]
    w_reach = 2.0 * reach + 1e-9 * (1.0 + np.abs(w).max()) if n else 0.0
    order = argsort(w)
    keys = np.empty(0, np.int64)
    found = []
    for oi in range(n):
        i = order[oi]
        for oj in range(oi + 1, n):
            j = order[oj]
            if w[j] - w[i] > w_reach:
                break
            if (
                abs(mid[j, 0] - mid[i, 0]) > reach
                or abs(mid[j, 1] - mid[i, 1]) > reach
                or abs(mid[j, 2] - mid[i, 2]) > reach
            ):
                continue
            a, b = (i, j) if i < j else (j, i)
            if not (active[a] or active[b]):
                continue
            w0x = p0[a, 0] - p0[b, 0]
            w0y = p0[a, 1] - p0[b, 1]
            w0z = p0[a, 2] - p0[b, 2]
            dwx = (p1[a, 0] - p0[a, 0]) - (p1[b, 0] - p0[b, 0])
            dwy = (p1[a, 1] - p0[a, 1]) - (p1[b, 1] - p0[b, 1])
            dwz = (p1[a, 2] - p0[a, 2]) - (p1[b, 2] - p0[b, 2])
            if _closest_gap(w0x, w0y, w0z, dwx, dwy, dwz) < radii[a] + radii[b] + margin:
                found.append(a * n + b)
    if len(found):
        keys = np.array(found, np.int64)
        keys = keys[argsort(keys)]
    return keys // n, keys % n


@njit(cache=True)
def separation_keys(
    pos: np.ndarray, separation: np.ndarray, radius: np.ndarray, active: np.ndarray
) -> np.ndarray:
    """Keys ``i * n + j`` (i < j, sorted) of the pairs inside each other's separation ellipsoid,
    ``|dp / (max(sep_i, sep_j) + r_i + r_j)| < 1`` per axis, one of them active: the pairs of
    ``neighbours.separation_violations``, with its arithmetic term for term.

    Sweep and prune on the diagonal ``w = x + y`` (swarms starting on lines of equal x or y
    would pile up on one axis): a pair inside has ``|dx| < max(sep_x) + 2 max(r)`` and
    ``|dy| < max(sep_y) + 2 max(r)``, so ``|dw|`` is below their sum."""
    n = len(pos)
    reach_x = 0.0
    reach_y = 0.0
    r_max = 0.0
    w_max = 0.0
    for i in range(n):
        reach_x = max(reach_x, separation[i, 0])
        reach_y = max(reach_y, separation[i, 1])
        r_max = max(r_max, radius[i])
        w_max = max(w_max, abs(pos[i, 0]) + abs(pos[i, 1]))
    reach = (reach_x + reach_y + 4.0 * r_max) * (1.0 + 1e-9) + 1e-9 * (1.0 + w_max)
    w = pos[:, 0] + pos[:, 1]
    order = argsort(w)
    found = []
    for oi in range(n):
        i = order[oi]
        for oj in range(oi + 1, n):
            j = order[oj]
            if w[j] - w[i] > reach:
                break
            a, b = (i, j) if i < j else (j, i)
            if not (active[a] or active[b]):
                continue
            rr = radius[a] + radius[b]
            dx = (pos[a, 0] - pos[b, 0]) / (max(separation[a, 0], separation[b, 0]) + rr)
            dy = (pos[a, 1] - pos[b, 1]) / (max(separation[a, 1], separation[b, 1]) + rr)
            dz = (pos[a, 2] - pos[b, 2]) / (max(separation[a, 2], separation[b, 2]) + rr)
            if math.sqrt(dx * dx + dy * dy + dz * dz) < 1.0:
                found.append(a * n + b)
    keys = np.empty(len(found), np.int64)
    for k in range(len(found)):
        keys[k] = found[k]
    return keys[argsort(keys)]


@njit(cache=True)
def arrivals(
    pos0: np.ndarray,
    pos1: np.ndarray,
    goal: np.ndarray,
    vel1: np.ndarray,
    active: np.ndarray,
    stop_speed: np.ndarray,
    tolerance: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Active agents whose step ``pos0 -> pos1`` passes within ``tolerance`` of their goal at a
    speed ``|vel1| <= stop_speed (1 + 1e-9)``, in index order, and their closest approach:
    ``segment_segment_min_distance(pos0, pos1, goal, goal)`` term for term."""
    rows = []
    dist = []
    for i in range(len(pos0)):
        if not active[i]:
            continue
        w0x, w0y, w0z = pos0[i, 0] - goal[i, 0], pos0[i, 1] - goal[i, 1], pos0[i, 2] - goal[i, 2]
        dwx = (pos1[i, 0] - pos0[i, 0]) - (goal[i, 0] - goal[i, 0])
        dwy = (pos1[i, 1] - pos0[i, 1]) - (goal[i, 1] - goal[i, 1])
        dwz = (pos1[i, 2] - pos0[i, 2]) - (goal[i, 2] - goal[i, 2])
        d = _closest_gap(w0x, w0y, w0z, dwx, dwy, dwz)
        speed = math.sqrt(vel1[i, 0] * vel1[i, 0] + vel1[i, 1] * vel1[i, 1] + vel1[i, 2] * vel1[i, 2])
        if d <= tolerance and speed <= stop_speed[i] * (1.0 + 1e-9):
            rows.append(i)
            dist.append(d)
    out_rows = np.empty(len(rows), np.int64)
    out_dist = np.empty(len(rows))
    for k in range(len(rows)):
        out_rows[k] = rows[k]
        out_dist[k] = dist[k]
    return out_rows, out_dist
