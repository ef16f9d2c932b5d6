"""Compiled (numba) phases of the simulation step, one call over all flying agents each.

The braking margin (``SafetyFilter.braking_margin``) ran ~40 numpy operations on arrays of a
swarm's rows plus a kernel call for the bisection, each paying numpy's per-call cost. Here it
is one loop over the rows. Every quantity is the numpy path's formula with its operations in
the same order (``norm3`` is ``sqrt((x*x + y*y) + z*z)``, ``np.minimum``/``np.maximum`` the
comparisons below, ``x ** 2`` numpy's ``x * x``), and no fast-math, so both paths give the
same bits (tests/test_step_kernels.py). Loaded with numba at the first call, like every kernel
(``swarmplan.runtime.compiled``).
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry.swept_kernels import HIT, UNDECIDED, step_status
from swarmplan.runtime.compiled import njit


@njit(cache=True, inline="always")
def _norm(x: float, y: float, z: float) -> float:
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True, inline="always")
def _min(a: float, b: float) -> float:
    return a if a <= b else b


@njit(cache=True, inline="always")
def _max(a: float, b: float) -> float:
    return a if a >= b else b


@njit(cache=True, inline="always")
def _limit(v0: np.ndarray, c: np.ndarray, vmax: float, amax_dt: float, out: np.ndarray) -> None:
    """``kinematics.limit_multirotor`` for one row: ``c`` clipped to ``vmax``, reached from
    ``v0`` with at most ``amax_dt`` of change (into ``out``)."""
    s = _norm(c[0], c[1], c[2])
    f = _min(1.0, vmax / _max(s, 1e-12))
    d0, d1, d2 = c[0] * f - v0[0], c[1] * f - v0[1], c[2] * f - v0[2]
    g = _min(1.0, amax_dt / _max(_norm(d0, d1, d2), 1e-12))
    out[0] = v0[0] + d0 * g
    out[1] = v0[1] + d1 * g
    out[2] = v0[2] + d2 * g


@njit(cache=True)
def braking_margin(
    rows: tuple,
    use_goal: bool,
    times: tuple,
    bounds: tuple,
    statics: tuple,
    movers: tuple,
    slack: float,
    halvings: int,
    check_step: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """``SafetyFilter.braking_margin`` for multirotor rows: ``rows`` = (pos0, vel0, v_cmd, goal,
    amax, vmax, radii), all arrays by row (``radii`` with the filter's margin); ``times`` =
    (dt, dt2, goal tolerance), ``dt2`` being Python's ``dt ** 2``; ``bounds``: lowest and
    highest corner; ``statics``, ``movers``: the bodies (``swept_kernels.sweep_one``). The new
    commands, the velocities they lead to (``kinematics.limit_multirotor``), and False when a
    sweep was undecided (a body within ``BAND`` of contact or a mesh: the caller then runs the
    numpy path, where FCL decides). With ``check_step``, also :func:`touches_many`'s answer for
    each row's step ``pos0 -> pos0 + vel1 dt`` (the safety filter's first check, same radii)."""
    pos0, vel0, v_cmd, goal, amax, vmax, radii = rows
    dt, dt2, tolerance = times
    n = len(pos0)
    out = np.empty((n, 3))
    vel1 = np.empty((n, 3))
    status = np.zeros(n, np.int64)
    end = np.empty(3)
    bodies = len(statics[1]) + len(movers[2]) > 0
    v1 = np.empty(3)
    c = np.empty(3)
    u = np.empty(3)
    for i in range(n):
        a = amax[i]
        a_dt = a * dt
        cap = np.inf
        if use_goal:
            to_goal = _norm(goal[i, 0] - pos0[i, 0], goal[i, 1] - pos0[i, 1], goal[i, 2] - pos0[i, 2])
            room = _max(to_goal - tolerance, 0.0)
            cap = _max(a_dt, a * (math.sqrt(dt2 + 2.0 * room / a) - dt))
        s_cmd = _norm(v_cmd[i, 0], v_cmd[i, 1], v_cmd[i, 2])
        f = _min(1.0, cap / _max(s_cmd, 1e-12))
        for k in range(3):
            c[k] = v_cmd[i, k] * f
        _limit(vel0[i], c, vmax[i], a_dt, v1)
        speed = _norm(v1[0], v1[1], v1[2])
        swept = False
        if speed > a_dt:
            for k in range(3):
                u[k] = v1[k] / speed
            reach = speed * speed / (2.0 * a) + speed * dt
            h = _probe(pos0[i], u, reach, radii[i], bounds, bodies, end, statics, movers, slack)
            if h == UNDECIDED:
                return out, vel1, status, False
            if h == HIT:
                lo, hi = 0.0, reach
                for _ in range(halvings):
                    mid = 0.5 * (lo + hi)
                    h = _probe(pos0[i], u, mid, radii[i], bounds, bodies, end, statics, movers, slack)
                    if h == UNDECIDED:
                        return out, vel1, status, False
                    if h == HIT:
                        hi = mid
                    else:
                        lo = mid
                cap = _min(cap, a * (math.sqrt(dt2 + 2.0 * lo / a) - dt))
                swept = True
        if cap == np.inf:
            for k in range(3):
                out[i, k] = v_cmd[i, k]
            _limit(vel0[i], out[i], vmax[i], a_dt, vel1[i])
        else:
            f = _min(1.0, cap / _max(s_cmd, 1e-12))
            for k in range(3):
                c[k] = v_cmd[i, k] * f
            if swept:
                _limit(vel0[i], c, vmax[i], a_dt, v1)
            if _norm(v1[0], v1[1], v1[2]) > cap + 1e-9:
                f0 = _min(1.0, cap / _max(_norm(vel0[i, 0], vel0[i, 1], vel0[i, 2]), 1e-12))
                for k in range(3):
                    out[i, k] = vel0[i, k] * f0
            else:
                for k in range(3):
                    out[i, k] = c[k]
            _limit(vel0[i], out[i], vmax[i], a_dt, vel1[i])
        if check_step:
            for k in range(3):
                end[k] = pos0[i, k] + vel1[i, k] * dt
            status[i] = step_status(pos0[i], end, radii[i], bounds, bodies, statics, movers, slack)
    return out, vel1, status, True


@njit(cache=True)
def touches_many(
    p0: np.ndarray,
    p1: np.ndarray,
    radii: np.ndarray,
    bounds: tuple,
    statics: tuple,
    movers: tuple,
    slack: float,
) -> np.ndarray:
    """Per step ``p0 -> p1`` over flat ground: whether it touches something (``first_hits``'
    bounds, ground and bodies as a yes/no question): NO, HIT or UNDECIDED (FCL must decide)."""
    n = len(p0)
    out = np.empty(n, np.int64)
    bodies = len(statics[1]) + len(movers[2]) > 0
    for i in range(n):
        out[i] = step_status(p0[i], p1[i], radii[i], bounds, bodies, statics, movers, slack)
    return out


@njit(cache=True, inline="always")
def _probe(
    start: np.ndarray,
    u: np.ndarray,
    length: float,
    r: float,
    bounds: tuple,
    bodies: bool,
    end: np.ndarray,
    statics: tuple,
    movers: tuple,
    slack: float,
) -> int:
    """``swept_kernels._touches`` (the sweep ``start -> start + u * length``: NO / HIT /
    UNDECIDED) with the end point in the caller's buffer ``end``, through
    ``swept_kernels.step_status``."""
    for c in range(3):
        end[c] = start[c] + u[c] * length
    return step_status(start, end, r, bounds, bodies, statics, movers, slack)


@njit(cache=True)
def round6(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.round(a, 6), np.round(b, 6)`` of two (n, 3) arrays (one shape) in one call: numpy's own steps
    (times 1e6, to the nearest integer with ties to even, divided by 1e6), so the same bits."""
    ra = np.empty(a.shape)
    rb = np.empty(b.shape)
    for i in range(a.shape[0]):
        for k in range(3):
            ra[i, k] = np.rint(a[i, k] * 1e6) / 1e6
            rb[i, k] = np.rint(b[i, k] * 1e6) / 1e6
    return ra, rb
