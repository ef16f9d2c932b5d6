"""Compiled kernel for the other-agents term of :class:`swarmplan.planner.segment_cost.SegmentCost`.

Why numba here: the term interpolates every other agent's piecewise-linear intent at every
sample of every candidate (30 candidates × ~200 samples × up to 63 agents per call, 100 calls
per escape). In numpy that is one ``np.interp`` per axis per agent plus a dozen temporaries
of n × S × 3 per agent: ~5 ms per call, 0.5-3 s per escape in a 32-agent swap. Batching the
agents into one array op still materialises n × S × M × 3 temporaries and a knot search per
sample; the loop below walks each candidate's samples (whose times increase) and each
intent's knots together, skipping in O(1) every (candidate, intent) pair whose space-time
boxes are out of reach, with no temporaries. numba is imported only when the first escape
is planned (it costs ~0.4 s to import), and ``cache=True`` keeps the compiled code on disk.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _interp_box(times, points, nk, tlo, thi, out_lo, out_hi):  # noqa: ANN001, ANN202
    """Box of an intent's positions over the time window [tlo, thi] (it is piecewise linear,
    so the box of its knots inside the window and its positions at both ends)."""
    for a in range(3):
        out_lo[a] = np.inf
        out_hi[a] = -np.inf
    for end in range(2):
        tt = tlo if end == 0 else thi
        for a in range(3):
            v = _interp1(times, points, nk, tt, a)
            out_lo[a] = min(out_lo[a], v)
            out_hi[a] = max(out_hi[a], v)
    for k in range(nk):
        if tlo < times[k] < thi:
            for a in range(3):
                out_lo[a] = min(out_lo[a], points[k, a])
                out_hi[a] = max(out_hi[a], points[k, a])


@njit(cache=True, nogil=True)
def _interp1(times, points, nk, tt, a):  # noqa: ANN001, ANN202
    """``np.interp(tt, times[:nk], points[:nk, a])`` (same formula, clamped at both ends)."""
    if tt <= times[0]:
        return points[0, a]
    if tt >= times[nk - 1]:
        return points[nk - 1, a]
    k = 0
    while times[k + 1] <= tt:
        k += 1
    slope = (points[k + 1, a] - points[k, a]) / (times[k + 1] - times[k])
    return slope * (tt - times[k]) + points[k, a]


@njit(cache=True, nogil=True)
def agent_cost(pts, ds, t, times, points, nk, scale, contact, reach, w_agents, w_collision, per):  # noqa: ANN001, ANN201
    """Other-agents penalty of each candidate → (n,).

    pts (n, S, 3) samples, ds (n, S) their path-length weights, t (n, S) their times
    (non-decreasing along S), in blocks of ``per`` consecutive samples (a leg each); per
    intent j: knots ``times[j, :nk[j]]`` / ``points[j, :nk[j]]``, ellipsoid ``scale[j]`` (3,),
    contact distance ``contact[j]`` and ``reach[j]`` (beyond which both terms are zero).
    Per sample and intent: ``w_agents * max(1.2 - |(p - q) / scale|, 0) * ds
    + w_collision * (|p - q| < contact) * ds`` with q the intent's position at the sample's time.
    """
    n, S, _ = pts.shape
    M = len(nk)
    out = np.zeros(n)
    clo = np.empty(3)
    chi = np.empty(3)
    ilo = np.empty(3)
    ihi = np.empty(3)
    for c in range(n):
        acc = 0.0
        for b0 in range(0, S, per):
            b1 = min(b0 + per, S)
            for a in range(3):
                clo[a] = np.inf
                chi[a] = -np.inf
            for s in range(b0, b1):
                for a in range(3):
                    clo[a] = min(clo[a], pts[c, s, a])
                    chi[a] = max(chi[a], pts[c, s, a])
            tlo = t[c, b0]
            thi = t[c, b1 - 1]
            for j in range(M):
                m = nk[j]
                # Space-time cull: the block's box against the intent's box over the block's
                # time window; out of reach, every sample adds exactly zero.
                _interp_box(times[j], points[j], m, tlo, thi, ilo, ihi)
                g2 = 0.0
                for a in range(3):
                    g = max(ilo[a] - chi[a], clo[a] - ihi[a], 0.0)
                    g2 += g * g
                if g2 >= reach[j] * reach[j]:
                    continue
                k = 0
                sub = 0.0
                for s in range(b0, b1):
                    tt = t[c, s]
                    if m == 1 or tt <= times[j, 0]:
                        qx, qy, qz = points[j, 0, 0], points[j, 0, 1], points[j, 0, 2]
                    elif tt >= times[j, m - 1]:
                        qx, qy, qz = points[j, m - 1, 0], points[j, m - 1, 1], points[j, m - 1, 2]
                    else:
                        if tt < times[j, k]:
                            k = 0
                        while times[j, k + 1] <= tt:
                            k += 1
                        h = tt - times[j, k]
                        dt = times[j, k + 1] - times[j, k]
                        qx = (points[j, k + 1, 0] - points[j, k, 0]) / dt * h + points[j, k, 0]
                        qy = (points[j, k + 1, 1] - points[j, k, 1]) / dt * h + points[j, k, 1]
                        qz = (points[j, k + 1, 2] - points[j, k, 2]) / dt * h + points[j, k, 2]
                    dx = pts[c, s, 0] - qx
                    dy = pts[c, s, 1] - qy
                    dz = pts[c, s, 2] - qz
                    ex = dx / scale[j, 0]
                    ey = dy / scale[j, 1]
                    ez = dz / scale[j, 2]
                    e = np.sqrt(ex * ex + ey * ey + ez * ez)
                    if e < 1.2:
                        sub += w_agents * (1.2 - e) * ds[c, s]
                    if np.sqrt(dx * dx + dy * dy + dz * dz) < contact[j]:
                        sub += w_collision * ds[c, s]
                acc += sub
        out[c] = acc
    return out
