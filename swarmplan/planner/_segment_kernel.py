"""Compiled cost of a population of candidate segments (``segment_cost.SegmentCost``).

Why numba: in numpy every term was a dozen operations on (n, S, 3) temporaries, ~2 ms per
call of 30 candidates x ~450 samples, mostly per-operation overhead; here one loop per
candidate and leg computes the samples on the fly and every term beside them. The values
are the brute-force ones (every sample against every body and intent); work is cut only
where it provably adds zero: bodies and intents culled per candidate, then per leg
(space-time boxes), and **sphere tracing** along a leg: the distances are 1-Lipschitz in
the sample's position (exact signed distances; a mover or another agent also moves, at most
``vstep`` per grid step or ``v_max``), so a sample at distance D proves the next
(D - reach) / spacing samples out of reach; they are skipped (``_SLACK`` covers rounding).
Meshes, terrain peaks and threats are left to numpy (``SegmentCost``'s fallbacks). The
bodies' distances are the shapes' one compiled distance (``_shape_kernel.sdf``).
docs/performance.md ("Escape planning") has the measurements.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry._shape_kernel import sdf
from swarmplan.runtime.compiled import njit

# Columns of the kernel's output, in SegmentCost.terms' order.
LENGTH, TURNING, STATIC, VERTICES, FLOOR_BOUNDS, THREATS, MOVING, AGENTS = range(8)
N_TERMS = 8

# Metres by which a traced distance must clear the reach before samples are skipped: far
# above the rounding of the distances (~1e-12 m on kilometre-wide worlds).
_SLACK = 1e-6


@njit(cache=True, nogil=True, error_model="numpy")
def _body_distance(code, rot, ident, prm, j, rx, ry, rz):  # noqa: ANN001, ANN202
    """Signed distance to body ``j`` of the point at ``(rx, ry, rz)`` from its centre."""
    if ident[j]:
        return sdf(code[j], rx, ry, rz, prm[j, 0], prm[j, 1], prm[j, 2])
    R = rot[j]
    x = rx * R[0, 0] + ry * R[1, 0] + rz * R[2, 0]
    y = rx * R[0, 1] + ry * R[1, 1] + rz * R[2, 1]
    z = rx * R[0, 2] + ry * R[1, 2] + rz * R[2, 2]
    return sdf(code[j], x, y, z, prm[j, 0], prm[j, 1], prm[j, 2])


@njit(cache=True, nogil=True, error_model="numpy")
def _box_gap2(lo, hi, blo0, blo1, blo2, bhi0, bhi1, bhi2):  # noqa: ANN001, ANN202
    """Squared distance between the box lo..hi and the box blo..bhi."""
    g0 = max(blo0 - hi[0], lo[0] - bhi0, 0.0)
    g1 = max(blo1 - hi[1], lo[1] - bhi1, 0.0)
    g2 = max(blo2 - hi[2], lo[2] - bhi2, 0.0)
    return g0 * g0 + g1 * g1 + g2 * g2


@njit(cache=True, nogil=True, error_model="numpy")
def _point_gap(lo, hi, p):  # noqa: ANN001, ANN202
    """Distance between the box lo..hi and the point ``p`` (3,)."""
    return math.sqrt(_box_gap2(lo, hi, p[0], p[1], p[2], p[0], p[1], p[2]))


@njit(cache=True, nogil=True, error_model="numpy")
def _agents(P, c, lens, per, f, w, intents, ibox):  # noqa: ANN001, ANN202
    """Other-agents term of candidate ``c`` (``intents``: ``segment_terms``'): per sample and intent j,
    ``w_agents * max(1.2 - |(p - q) / scale_j|, 0) * ds + w_coll * (|p - q| < contact_j) * ds``
    with q the intent's position at the sample's time (``np.interp`` of its knots, clamped).

    Intent by intent, the legs are walked in time order with a knot pointer that only moves
    on; a leg whose samples' box stays beyond ``reach_j`` of the intent's box over the
    samples' time window adds exactly zero, and so do samples skipped by tracing."""
    times_, points_, nk_, scale, contact_, reach_, vmax = intents
    m = P.shape[1]
    t0, speed, w_agents, w_coll = f[4], f[3], w[8], w[1]
    acc = 0.0
    clo0, clo1, clo2 = np.inf, np.inf, np.inf
    chi0, chi1, chi2 = -np.inf, -np.inf, -np.inf
    for v in range(m):
        clo0, chi0 = min(clo0, P[c, v, 0]), max(chi0, P[c, v, 0])
        clo1, chi1 = min(clo1, P[c, v, 1]), max(chi1, P[c, v, 1])
        clo2, chi2 = min(clo2, P[c, v, 2]), max(chi2, P[c, v, 2])
    for j in range(len(nk_)):
        # The candidate's box against the intent's box over the whole call's time window
        # (``ibox``): a cheap first cull before the legs' own.
        g0 = max(ibox[j, 0] - chi0, clo0 - ibox[j, 3], 0.0)
        g1 = max(ibox[j, 1] - chi1, clo1 - ibox[j, 4], 0.0)
        g2 = max(ibox[j, 2] - chi2, clo2 - ibox[j, 5], 0.0)
        if g0 * g0 + g1 * g1 + g2 * g2 >= reach_[j] * reach_[j]:
            continue
        nk = nk_[j]
        times = times_[j]
        points = points_[j]
        sx, sy, sz = scale[j, 0], scale[j, 1], scale[j, 2]
        contact = contact_[j]
        reach = reach_[j]
        reach2 = reach * reach
        kp = 0  # knot pointer: times[kp] <= every later time asked (or kp == 0)
        cum = 0.0
        for leg in range(m - 1):
            L = lens[leg]
            ds = L / per
            ax, ay, az = P[c, leg, 0], P[c, leg, 1], P[c, leg, 2]
            lx = P[c, leg + 1, 0] - ax
            ly = P[c, leg + 1, 1] - ay
            lz = P[c, leg + 1, 2] - az
            u0 = 0.5 / per
            u1 = (per - 0.5) / per
            c0 = cum
            cum += L
            tlo = t0 + (c0 + u0 * L) / speed
            thi = t0 + (c0 + u1 * L) / speed
            # The intent's box over [tlo, thi]: its positions at both ends and the knots between.
            while kp + 1 < nk and times[kp + 1] <= tlo:
                kp += 1
            k1 = kp
            while k1 + 1 < nk and times[k1 + 1] <= thi:
                k1 += 1
            g2 = 0.0
            for a in range(3):
                pa = P[c, leg, a]
                la = P[c, leg + 1, a] - pa
                s0 = pa + u0 * la
                s1 = pa + u1 * la
                q0 = _interp_at(times, points, nk, kp, tlo, a)
                q1 = _interp_at(times, points, nk, k1, thi, a)
                qlo = min(q0, q1)
                qhi = max(q0, q1)
                for k in range(kp + 1, k1 + 1):
                    if tlo < times[k] < thi:
                        qlo = min(qlo, points[k, a])
                        qhi = max(qhi, points[k, a])
                g = max(qlo - max(s0, s1), min(s0, s1) - qhi, 0.0)
                g2 += g * g
            if g2 >= reach2:
                continue
            # Tracing: over k samples the relative position moves at most k * ds * (1 + v_max / speed).
            per_sample = ds * (1.0 + vmax[j] / speed)
            k = kp
            i = 0
            while i < per:
                u = (i + 0.5) / per
                tt = t0 + (c0 + u * L) / speed
                if nk == 1 or tt <= times[0]:
                    qx, qy, qz = points[0, 0], points[0, 1], points[0, 2]
                elif tt >= times[nk - 1]:
                    qx, qy, qz = points[nk - 1, 0], points[nk - 1, 1], points[nk - 1, 2]
                else:
                    if tt < times[k]:
                        k = 0
                    while times[k + 1] <= tt:
                        k += 1
                    h = tt - times[k]
                    dt = times[k + 1] - times[k]
                    qx = (points[k + 1, 0] - points[k, 0]) / dt * h + points[k, 0]
                    qy = (points[k + 1, 1] - points[k, 1]) / dt * h + points[k, 1]
                    qz = (points[k + 1, 2] - points[k, 2]) / dt * h + points[k, 2]
                dx = ax + u * lx - qx
                dy = ay + u * ly - qy
                dz = az + u * lz - qz
                ex = dx / sx
                ey = dy / sy
                ez = dz / sz
                e = math.sqrt(ex * ex + ey * ey + ez * ez)
                if e < 1.2:
                    acc += w_agents * (1.2 - e) * ds
                dist = math.sqrt(dx * dx + dy * dy + dz * dz)
                if dist < contact:
                    acc += w_coll * ds
                i += _advance((dist - reach - _SLACK) / per_sample, per)
    return acc


@njit(cache=True, nogil=True, error_model="numpy")
def _intent_box(times, points, nk, tlo, thi, out):  # noqa: ANN001, ANN202
    """Box (lo, hi) into ``out`` (6,) of an intent's positions over the times [tlo, thi], a
    little widened (1e-9 relative, so that it also holds every sample's rounded position)."""
    k0 = 0
    while k0 + 1 < nk and times[k0 + 1] <= tlo:
        k0 += 1
    k1 = k0
    while k1 + 1 < nk and times[k1 + 1] <= thi:
        k1 += 1
    for a in range(3):
        q0 = _interp_at(times, points, nk, k0, tlo, a)
        q1 = _interp_at(times, points, nk, k1, thi, a)
        lo = min(q0, q1)
        hi = max(q0, q1)
        for k in range(k0 + 1, k1 + 1):
            if tlo < times[k] < thi:
                lo = min(lo, points[k, a])
                hi = max(hi, points[k, a])
        pad = 1e-9 * (1.0 + abs(lo) + abs(hi))
        out[a] = lo - pad
        out[a + 3] = hi + pad


@njit(cache=True, nogil=True, error_model="numpy")
def _interp_at(times, points, nk, k, tt, a):  # noqa: ANN001, ANN202
    """``np.interp(tt, times[:nk], points[:nk, a])`` given the knot ``k`` with
    ``times[k] <= tt < times[k + 1]`` when ``tt`` is inside (the same formula)."""
    if tt <= times[0]:
        return points[0, a]
    if tt >= times[nk - 1]:
        return points[nk - 1, a]
    slope = (points[k + 1, a] - points[k, a]) / (times[k + 1] - times[k])
    return slope * (tt - times[k]) + points[k, a]


@njit(cache=True, nogil=True, error_model="numpy")
def _advance(room, per):  # noqa: ANN001, ANN202
    """Samples to move on after one whose distance proves the next ``room`` (a count, maybe
    fractional, negative or NaN) out of reach: 1 + the whole samples it clears, at most ``per``."""
    if room >= per:
        return per
    if room > 0.0:
        return 1 + int(room)
    return 1


@njit(cache=True, nogil=True, error_model="numpy")
def _angle(ax, ay, az, bx, by, bz):  # noqa: ANN001, ANN202
    """Angle between unit vectors, as ``segment_cost._angle``."""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)


@njit(cache=True, nogil=True, error_model="numpy")
def _turning(P, c, lens, f, w, heading):  # noqa: ANN001, ANN202
    """``SegmentCost.turning`` of candidate ``c``."""
    m = P.shape[1]
    eps = 1e-9
    turn_radius, max_climb, has_heading, fixed_wing = f[6], f[7], f[8], f[9]
    th_sum = 0.0
    fit = 0.0
    for v in range(1, m - 1):
        la, lb = lens[v - 1], lens[v]
        if la > 1e-6 and lb > 1e-6:
            da = max(la, eps)
            db = max(lb, eps)
            theta = _angle(
                (P[c, v, 0] - P[c, v - 1, 0]) / da,
                (P[c, v, 1] - P[c, v - 1, 1]) / da,
                (P[c, v, 2] - P[c, v - 1, 2]) / da,
                (P[c, v + 1, 0] - P[c, v, 0]) / db,
                (P[c, v + 1, 1] - P[c, v, 1]) / db,
                (P[c, v + 1, 2] - P[c, v, 2]) / db,
            )
        else:
            theta = 0.0
        th_sum += theta
        need = turn_radius * math.tan(min(theta, 3.0) / 2)
        fit += max(need - min(lb, la) / 2, 0.0)
    cost = w[4] * th_sum + w[5] * fit
    if has_heading > 0.0:
        l0 = lens[0]
        if l0 > 1e-6:
            d0 = max(l0, eps)
            th0 = _angle(
                (P[c, 1, 0] - P[c, 0, 0]) / d0,
                (P[c, 1, 1] - P[c, 0, 1]) / d0,
                (P[c, 1, 2] - P[c, 0, 2]) / d0,
                heading[0],
                heading[1],
                heading[2],
            )
        else:
            th0 = 0.0
        need0 = turn_radius * math.tan(min(th0, 3.0) / 2)
        k = w[5] if fixed_wing > 0.0 else 0.1 * w[5]
        cost = cost + w[4] * th0 + k * max(need0 - l0, 0.0)
    climb_sum = 0.0
    for v in range(m - 1):
        lx = P[c, v + 1, 0] - P[c, v, 0]
        ly = P[c, v + 1, 1] - P[c, v, 1]
        lz = P[c, v + 1, 2] - P[c, v, 2]
        horiz = math.sqrt(lx * lx + ly * ly)
        climb = math.atan2(abs(lz), max(horiz, eps))
        climb_sum += max(climb - max_climb, 0.0) * lens[v]
    return cost + w[6] * climb_sum


@njit(cache=True, nogil=True, error_model="numpy")
def segment_terms(P, f, w, heading, bounds, flags, statics, movers, intents, centers, vstep):  # noqa: ANN001, ANN201, PLR0912, PLR0915, C901
    """Terms (n, 8) of polylines ``P`` (n, m, 3), columns as ``SegmentCost.terms``, and their
    sum in that order (column 8); and 0, or the length of the movers' grid the candidates need
    when ``centers`` is shorter (then nothing was computed).

    ``f``: r, required, start_clearance, speed, t0, spacing, turn_radius, max_climb,
    has_heading, fixed_wing, vertex_clearance, floor, max_samples, pose_step.
    ``w``: clearance, collision, floor, bounds, turn, turn_radius, climb, moving, agents, vertex.
    ``bounds``: lowest and highest corner of the world.
    ``flags``: static term here, vertex term here, floor/bounds term here (1 or 0).
    ``statics``: the static bodies (code, centre, rotation, identity flag, shape parameters,
    bounding radius: ``_segment_pack.pack_bodies``); ``movers``: the moving ones (code,
    rotation, identity flag, parameters, bounding radius) with their predicted ``centers``
    (T, Mm, 3) on the ``pose_step`` grid from t0 and ``vstep`` (Mm,), a bound on a centre's move
    per grid step; ``intents``: (times, points, knots, scale, contact, reach, largest speed) as
    ``_segment_pack.pack_intents``.
    """
    bmin, bmax = bounds
    s_code, s_pos, s_rot, s_ident, s_prm, s_bound = statics
    m_code, m_rot, m_ident, m_prm, m_bound = movers
    i_nk = intents[2]
    n, m, _ = P.shape
    out = np.zeros((n, N_TERMS + 1))
    if n == 0:
        return out, 0
    r, required, start_clear, speed, t0 = f[0], f[1], f[2], f[3], f[4]
    spacing, vertex_clear, floor, max_samples, pose_step = f[5], f[10], f[11], f[12], f[13]
    w_clear, w_coll, w_floor, w_bounds = w[0], w[1], w[2], w[3]
    w_moving, w_vertex = w[7], w[9]
    do_static, do_vertex, do_floor = flags[0] > 0, flags[1] > 0 and m > 2, flags[2] > 0
    Ms = len(s_code)
    Mm = len(m_code)
    Mi = len(i_nk)
    T = centers.shape[0]

    # Leg lengths, the population's samples per leg (as SegmentCost.sample) and its box.
    lens = np.empty((n, m - 1))
    longest = 0.0
    plo = np.full(3, np.inf)
    phi = np.full(3, -np.inf)
    for c in range(n):
        for v in range(m - 1):
            dx = P[c, v + 1, 0] - P[c, v, 0]
            dy = P[c, v + 1, 1] - P[c, v, 1]
            dz = P[c, v + 1, 2] - P[c, v, 2]
            lens[c, v] = math.sqrt(dx * dx + dy * dy + dz * dz)
            longest = max(longest, lens[c, v])
        for v in range(m):
            for a in range(3):
                plo[a] = min(plo[a], P[c, v, a])
                phi[a] = max(phi[a], P[c, v, a])
    per = int(min(max(math.ceil(longest / spacing), 4.0), max(4.0, float(int(max_samples) // (m - 1)))))
    longest_total = 0.0
    for c in range(n):
        tot = 0.0
        for v in range(m - 1):
            tot += lens[c, v]
        longest_total = max(longest_total, tot)
    if Mm:
        # Grid times the samples need (the last sample is before the longest candidate's end):
        # when the movers' grid is shorter, the caller extends it and calls again.
        need = int(np.rint(longest_total / speed / pose_step)) + 2
        if need > T:
            return out, need
    if do_floor:
        # Every vertex (so every sample) above the floor and inside the bounds: the term is 0.
        inside = plo[2] >= floor
        for a in range(3):
            inside = inside and plo[a] >= bmin[a] + r and phi[a] <= bmax[a] - r
        do_floor = not inside

    near = np.empty(max(Ms, 1), dtype=np.int64)
    # Each intent's box over the call's whole time window (every sample's time is in it).
    ibox = np.empty((Mi, 6))
    if Mi:
        for j in range(Mi):
            _intent_box(intents[0][j], intents[1][j], i_nk[j], t0, t0 + longest_total / speed, ibox[j])
    # Each mover's box over the grid (every sample's grid time is in it).
    mbox = np.empty((Mm, 6))
    for j in range(Mm):
        for a in range(3):
            mbox[j, a] = np.inf
            mbox[j, a + 3] = -np.inf
        for kk in range(T):
            for a in range(3):
                mbox[j, a] = min(mbox[j, a], centers[kk, j, a])
                mbox[j, a + 3] = max(mbox[j, a + 3], centers[kk, j, a])
    s_near = np.empty(max(Ms, 1), dtype=np.int64)
    m_near = np.empty(max(Mm, 1), dtype=np.int64)
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(n):
        total = 0.0
        for v in range(m - 1):
            total += lens[c, v]
        out[c, LENGTH] = total
        out[c, TURNING] = _turning(P, c, lens[c], f, w, heading)
        # First cull per candidate (the box of its vertices), then per leg among those left.
        for a in range(3):
            lo[a] = np.inf
            hi[a] = -np.inf
            for v in range(m):
                lo[a] = min(lo[a], P[c, v, a])
                hi[a] = max(hi[a], P[c, v, a])
        ns = 0
        if do_static:
            for j in range(Ms):
                if _point_gap(lo, hi, s_pos[j]) - s_bound[j] < required:
                    s_near[ns] = j
                    ns += 1
        nm = 0
        for j in range(Mm):
            g2 = _box_gap2(lo, hi, mbox[j, 0], mbox[j, 1], mbox[j, 2], mbox[j, 3], mbox[j, 4], mbox[j, 5])
            if math.sqrt(g2) - m_bound[j] < required:
                m_near[nm] = j
                nm += 1

        cum = 0.0
        for leg in range(m - 1):
            ax, ay, az = P[c, leg, 0], P[c, leg, 1], P[c, leg, 2]
            lx = P[c, leg + 1, 0] - ax
            ly = P[c, leg + 1, 1] - ay
            lz = P[c, leg + 1, 2] - az
            L = lens[c, leg]
            ds = L / per
            for a in range(3):
                lo[a] = min(P[c, leg, a], P[c, leg + 1, a])
                hi[a] = max(P[c, leg, a], P[c, leg + 1, a])

            # ---------------------------------------------------------------- static bodies
            if ns:
                nn = 0
                for q in range(ns):
                    j = s_near[q]
                    if _point_gap(lo, hi, s_pos[j]) - s_bound[j] < required:
                        near[nn] = j
                        nn += 1
                if nn:
                    acc_c = 0.0
                    acc_k = 0.0
                    i = 0
                    while i < per:
                        u = (i + 0.5) / per
                        px, py, pz = ax + u * lx, ay + u * ly, az + u * lz
                        D = np.inf
                        for q in range(nn):
                            j = near[q]
                            rx, ry, rz = px - s_pos[j, 0], py - s_pos[j, 1], pz - s_pos[j, 2]
                            lb = math.sqrt(rx * rx + ry * ry + rz * rz) - s_bound[j]
                            if lb >= required:  # beyond reach: a lower bound is all tracing needs
                                D = min(D, lb)
                                continue
                            D = min(D, _body_distance(s_code, s_rot, s_ident, s_prm, j, rx, ry, rz))
                        req = min(required, start_clear + r + (cum + u * L))
                        if D < req:
                            acc_c += (req - D) * ds
                        if D < r:
                            acc_k += ds
                        i += _advance((D - required - _SLACK) / ds, per)
                    out[c, STATIC] += w_clear * acc_c + w_coll * acc_k

            # ---------------------------------------------------------------- floor and bounds
            if do_floor:
                clear = lo[2] >= floor
                for a in range(3):
                    clear = clear and lo[a] >= bmin[a] + r and hi[a] <= bmax[a] - r
                if not clear:
                    acc_f = 0.0
                    acc_b = 0.0
                    i = 0
                    while i < per:
                        u = (i + 0.5) / per
                        p0, p1, p2 = ax + u * lx, ay + u * ly, az + u * lz
                        acc_f += max(floor - p2, 0.0) * ds
                        o = (
                            max(bmin[0] + r - p0, 0.0)
                            + max(bmin[1] + r - p1, 0.0)
                            + max(bmin[2] + r - p2, 0.0)
                        )
                        o += (
                            max(p0 - bmax[0] + r, 0.0)
                            + max(p1 - bmax[1] + r, 0.0)
                            + max(p2 - bmax[2] + r, 0.0)
                        )
                        acc_b += o * ds
                        # Tracing: the sample's depth inside the allowed box bounds the next ones'.
                        inner = min(p2 - floor, p0 - (bmin[0] + r), p1 - (bmin[1] + r), p2 - (bmin[2] + r))
                        inner = min(inner, (bmax[0] - r) - p0, (bmax[1] - r) - p1, (bmax[2] - r) - p2)
                        i += _advance((inner - _SLACK) / ds, per)
                    out[c, FLOOR_BOUNDS] += w_floor * acc_f + w_bounds * acc_b

            # ---------------------------------------------------------------- moving bodies
            if nm:
                u0 = 0.5 / per
                u1 = (per - 0.5) / per
                k0 = int(np.rint(((t0 + (cum + u0 * L) / speed) - t0) / pose_step))
                k1 = int(np.rint(((t0 + (cum + u1 * L) / speed) - t0) / pose_step))
                k0 = min(max(k0, 0), T - 1)
                k1 = min(max(k1, 0), T - 1)
                for q in range(nm):
                    j = m_near[q]
                    # Cheap first: every centre of the leg's times is within (k1 - k0) vstep of
                    # the first one.
                    if _point_gap(lo, hi, centers[k0, j]) - (k1 - k0) * vstep[j] - m_bound[j] >= required:
                        continue
                    # The leg's box against the box of the centre's track over the leg's times.
                    b0, b1, b2 = np.inf, np.inf, np.inf
                    e0, e1, e2 = -np.inf, -np.inf, -np.inf
                    for kk in range(k0, k1 + 1):
                        b0 = min(b0, centers[kk, j, 0])
                        b1 = min(b1, centers[kk, j, 1])
                        b2 = min(b2, centers[kk, j, 2])
                        e0 = max(e0, centers[kk, j, 0])
                        e1 = max(e1, centers[kk, j, 1])
                        e2 = max(e2, centers[kk, j, 2])
                    if math.sqrt(_box_gap2(lo, hi, b0, b1, b2, e0, e1, e2)) - m_bound[j] >= required:
                        continue
                    # Tracing: over k samples the point moves k * ds and the centre at most
                    # (k * ds / (speed * pose_step) + 1) grid steps of vstep each.
                    per_sample = ds * (1.0 + vstep[j] / (speed * pose_step))
                    acc_c = 0.0
                    acc_k = 0.0
                    i = 0
                    while i < per:
                        u = (i + 0.5) / per
                        kk = int(np.rint(((t0 + (cum + u * L) / speed) - t0) / pose_step))
                        kk = min(max(kk, 0), T - 1)
                        rx = ax + u * lx - centers[kk, j, 0]
                        ry = ay + u * ly - centers[kk, j, 1]
                        rz = az + u * lz - centers[kk, j, 2]
                        d = _body_distance(m_code, m_rot, m_ident, m_prm, j, rx, ry, rz)
                        if d < required:
                            acc_c += (required - d) * ds
                        if d < r:
                            acc_k += ds
                        i += _advance((d - required - _SLACK - vstep[j]) / per_sample, per)
                    out[c, MOVING] += w_moving * acc_c + w_coll * acc_k

            cum += L

        # -------------------------------------------------------------------- other agents
        if Mi:
            out[c, AGENTS] = _agents(P, c, lens[c], per, f, w, intents, ibox)

        # -------------------------------------------------------------------- free waypoints
        if do_vertex:
            acc = 0.0
            for v in range(1, m - 1):
                px, py, pz = P[c, v, 0], P[c, v, 1], P[c, v, 2]
                D = np.inf
                for j in range(Ms):
                    rx, ry, rz = px - s_pos[j, 0], py - s_pos[j, 1], pz - s_pos[j, 2]
                    lb = math.sqrt(rx * rx + ry * ry + rz * rz) - s_bound[j]
                    if lb - r >= vertex_clear:  # lb <= d: this body leaves the term at 0
                        D = min(D, lb)
                        continue
                    D = min(D, _body_distance(s_code, s_rot, s_ident, s_prm, j, rx, ry, rz))
                acc += max(vertex_clear - (D - r), 0.0)
            out[c, VERTICES] = w_vertex * acc
        total = 0.0
        for k in range(N_TERMS):
            total += out[c, k]
        out[c, N_TERMS] = total
    return out, 0
