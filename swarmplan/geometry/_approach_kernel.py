"""Compiled (numba) closest approaches of moving points to fixed points, for the pairs that can
come close: the evasion's threat test (``swarmplan.sim.evasion``) at swarm size.

A threat ``j`` at ``c_j`` moving at ``u_j`` passes a fixed point ``p`` no closer than
``|c_j - p| - H |u_j|`` within a horizon ``H``; it can only come within ``need`` of ``p`` if
``|c_j - p| < need + H |u_j|``, so ``|x_j - x_p|`` is below that too. A sweep along x keeps the
pairs within that reach (with a relative slack far above rounding) and runs the exact test, with
numpy's formulas term for term (``evasion._approach``), on them only.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry._sort_kernel import argsort, search_left, search_right
from swarmplan.runtime.compiled import njit

_EPS = 1e-9
_SLACK = 1e-6
"""Relative (and absolute, metres) widening of the sweep's reach: pairs beyond it are far from
the exact test's bound by many orders of magnitude more than its rounding."""


@njit(cache=True)
def _window(xs: np.ndarray, lo: float, hi: float) -> tuple[int, int]:
    return search_left(xs, lo), search_right(xs, hi)


@njit(cache=True)
def _clip(t: float, h: float, keep_neg_zero: bool) -> float:
    """``np.clip(t, 0.0, h)``; numpy keeps a ``-0.0`` when both bounds broadcast as scalars."""
    if t < 0.0 or (t == 0.0 and not keep_neg_zero):
        t = 0.0
    return min(t, h)


@njit(cache=True)
def threat_pairs(
    c: np.ndarray,
    u: np.ndarray,
    margin: np.ndarray,
    who: np.ndarray,
    rows: np.ndarray,
    radius: np.ndarray,
    position: np.ndarray,
    goal: np.ndarray,
    horizon: np.ndarray,
    keep_neg_zero: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs (watching agent ``k``, threat ``j``) whose closest approach within
    ``horizon[k]`` to ``position[k]`` or ``goal[k]`` is below ``margin[j] + radius[k]``
    (``who[j] != rows[k]``), sorted by ``k * T + j``: their keys (P,), times (P, 2) (to the
    position, to the goal), misses (P, 2) and the offsets at the closest approach to the
    position (P, 3)."""
    n_r, n_t = len(rows), len(c)
    h_max = 0.0
    r_max = 0.0
    for k in range(n_r):
        h_max = max(h_max, horizon[k])
        r_max = max(r_max, radius[k])
    xs_p = np.ascontiguousarray(position[:, 0])
    xs_g = np.ascontiguousarray(goal[:, 0])
    order_p = argsort(xs_p)
    order_g = argsort(xs_g)
    xs_p = xs_p[order_p]
    xs_g = xs_g[order_g]
    seen = np.full(n_r, -1, np.int64)
    keys = []
    times = []
    misses = []
    offsets = []
    for j in range(n_t):
        ux, uy, uz = u[j, 0], u[j, 1], u[j, 2]
        ww = ux * ux + uy * uy + uz * uz
        reach = (margin[j] + r_max + h_max * math.sqrt(ww)) * (1.0 + _SLACK)
        reach += _SLACK * (1.0 + abs(c[j, 0]) + abs(c[j, 1]) + abs(c[j, 2]))
        cand = []
        for xs, order in ((xs_p, order_p), (xs_g, order_g)):
            lo, hi = _window(xs, c[j, 0] - reach, c[j, 0] + reach)
            for m in range(lo, hi):
                k = order[m]
                if seen[k] != j:
                    seen[k] = j
                    cand.append(k)
        den = max(ww, _EPS)
        for k in cand:
            if who[j] == rows[k]:
                continue
            need = margin[j] + radius[k]
            dx, dy, dz = c[j, 0] - position[k, 0], c[j, 1] - position[k, 1], c[j, 2] - position[k, 2]
            t = _clip(-(dx * ux + dy * uy + dz * uz) / den, horizon[k], keep_neg_zero)
            ox, oy, oz = dx + t * ux, dy + t * uy, dz + t * uz
            miss = math.sqrt(ox * ox + oy * oy + oz * oz)
            gx, gy, gz = c[j, 0] - goal[k, 0], c[j, 1] - goal[k, 1], c[j, 2] - goal[k, 2]
            tg = _clip(-(gx * ux + gy * uy + gz * uz) / den, horizon[k], keep_neg_zero)
            qx, qy, qz = gx + tg * ux, gy + tg * uy, gz + tg * uz
            miss_g = math.sqrt(qx * qx + qy * qy + qz * qz)
            if miss < need or miss_g < need:
                keys.append(k * n_t + j)
                times.append((t, tg))
                misses.append((miss, miss_g))
                offsets.append((ox, oy, oz))
    n = len(keys)
    key = np.empty(n, np.int64)
    tm = np.empty((n, 2))
    ms = np.empty((n, 2))
    off = np.empty((n, 3))
    for m in range(n):
        key[m] = keys[m]
        tm[m, 0], tm[m, 1] = times[m]
        ms[m, 0], ms[m, 1] = misses[m]
        off[m, 0], off[m, 1], off[m, 2] = offsets[m]
    s = argsort(key)
    return key[s], tm[s], ms[s], off[s]


@njit(cache=True, inline="always")
def _maximum(a: float, b: float) -> float:
    """``np.maximum`` of two values (NaN wins; of two equal values, the second)."""
    return a if a > b or a != a else b


@njit(cache=True)
def horizons(
    need: float, radius: np.ndarray, amax: np.ndarray, vmax: np.ndarray, factor: float, extra: float
) -> np.ndarray:
    """``factor * evasion.sideways_time(need + radius, amax, vmax) + extra`` per row, numpy's
    operations in numpy's order (the evasion's horizon of each watching agent)."""
    out = np.empty(len(radius))
    for k in range(len(radius)):
        d = _maximum(need + radius[k], 0.0)
        a = _maximum(amax[k], _EPS)
        v = _maximum(vmax[k], _EPS)
        st = 2.0 * math.sqrt(d / a) if d <= v * v / a else d / v + v / a
        out[k] = factor * st + extra
    return out
