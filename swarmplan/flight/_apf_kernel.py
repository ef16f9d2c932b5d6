"""Compiled potential field of swarm-sized worlds (``apf.apf_forces`` from ``COMPILED_FROM``
agents on): every term of every agent in one pass.

Why numba: in numpy the field is ~60 array operations per step on (agents, bodies, 3) and
(pairs, 3) temporaries plus a k-d tree for the agent term (3.8 ms per step at 256 agents,
2.1 ms at 64 with 32 movers), mostly per-call overhead and memory traffic; here each agent's
force is summed where its terms are computed. The formulas, their order, the order of the
terms and of every sum are those of ``apf.py`` (``np.einsum`` adds in index order; the
potentials' ``sum`` is numpy's pairwise summation, reproduced by :func:`_pairwise`; the agent
term is the indexed one, in index order): the forces are numpy's bit for bit, so a world
runs the same either way (tests/test_apf_compiled.py, tests/test_field_kernels.py).

The agent term visits every other agent, but a pair is dismissed with a few products (no
division) when the closest approach of the two centres within the prediction horizon stays
beyond ``reach``, the distance past which both of its terms are provably zero
(``apf.agent_reach``'s bound without the speed part): the scaled distances are at least the
unscaled ones over the largest semi-axis. At 256 agents that is ~65k cheap tests per step;
a spatial index would pay off only for swarms several times larger.

Imported lazily (:func:`swarmplan.flight.apf._kernel`); every compiled function of the field is
in this file (numba's cache does not see changes of callees in other files).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_EPS = 1e-9  # apf._EPS


@njit(cache=True, nogil=True, error_model="numpy")
def _unit(x, y, z):  # noqa: ANN001, ANN202
    n = max(math.sqrt(x * x + y * y + z * z), _EPS)
    return x / n, y / n, z / n


@njit(cache=True, nogil=True, error_model="numpy")
def _power(x, p):  # noqa: ANN001, ANN202
    """``x ** p`` as numpy computes an array to a Python-float power (its fast paths)."""
    if p == 2.0:
        return x * x
    if p == 1.0:
        return x
    if p == 0.5:
        return math.sqrt(x)
    if p == -1.0:
        return 1.0 / x
    if p == 0.0:
        return 1.0
    return math.pow(x, p)


@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise_block(a, lo, n):  # noqa: ANN001, ANN202
    """numpy's pairwise summation of ``a[lo:lo + n]`` for n <= 128 (eight running sums)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True, error_model="numpy")
def _pairwise(a, lo, n):  # noqa: ANN001, ANN202
    """``a[lo:lo + n].sum()`` in numpy's order: blocks of up to 128, longer runs split in
    halves (a multiple of 8 first) and the halves' sums added. The halving is walked with
    an explicit stack (numba's cache breaks callers of self-recursive functions)."""
    if n <= 128:
        return _pairwise_block(a, lo, n)
    depth = 2 * (int(math.log2(n)) + 2)
    s_lo = np.empty(depth, np.int64)
    s_n = np.empty(depth, np.int64)
    s_phase = np.zeros(depth, np.int64)
    vals = np.empty(depth)
    s_lo[0], s_n[0], top, nv = lo, n, 1, 0
    while top:
        t = top - 1
        m = s_n[t]
        if m <= 128:
            vals[nv] = _pairwise_block(a, s_lo[t], m)
            nv += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if s_phase[t] == 0:  # the left half first
            s_phase[t] = 1
            s_lo[top], s_n[top], s_phase[top] = s_lo[t], half, 0
            top += 1
        elif s_phase[t] == 1:  # then the right
            s_phase[t] = 2
            s_lo[top], s_n[top], s_phase[top] = s_lo[t] + half, m - half, 0
            top += 1
        else:
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return vals[0]


@njit(cache=True, nogil=True, error_model="numpy")
def _rep(rho, rho0, k):  # noqa: ANN001, ANN202
    """``apf._rep_magnitude`` of one value."""
    if rho < rho0:
        return k * (1.0 / max(rho, 0.05) - 1.0 / rho0)
    return 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _face(offset, sign, r, rb0, k_rep, gfac):  # noqa: ANN001, ANN202
    """Force component from a face of ``bounds`` at ``offset = p - plane`` (sign +1: low face)."""
    rho_b = sign * offset - r
    mag = k_rep * (1.0 / max(rho_b, 0.05) - 1.0 / rb0) if rho_b < rb0 else 0.0
    return sign * mag * gfac


@njit(cache=True, nogil=True, error_model="numpy")
def _near(px, py, pz, vx, vy, vz, X, Y, Z, VX, VY, VZ, horizon, reach, near):  # noqa: ANN001, ANN202
    """``near[b]`` = False when ``|d + t v| >= reach`` for every t in [0, horizon], d and v the
    position and velocity of (px, py, pz) relative to agent b (a margin covers rounding): the
    closest approach of the segment from squared lengths only, no division and no branch, so
    the loop over the swarm is vectorized."""
    r2 = reach * reach
    r2_end = r2 * (1.0 + 1e-9)
    for b in range(X.shape[0]):
        dx, dy, dz = px - X[b], py - Y[b], pz - Z[b]
        wx, wy, wz = vx - VX[b], vy - VY[b], vz - VZ[b]
        dd = dx * dx + dy * dy + dz * dz
        bb = dx * wx + dy * wy + dz * wz
        a = wx * wx + wy * wy + wz * wz
        ex, ey, ez = dx + horizon * wx, dy + horizon * wy, dz + horizon * wz
        ee = ex * ex + ey * ey + ez * ez
        to_end = -bb >= a * horizon  # still approaching at the horizon: the end is the closest
        inside = -bb < a * horizon
        # Interior minimum dd - bb^2 / a >= r2 without the division; the difference cancels
        # when d and v are nearly parallel, hence the margin relative to dd * a.
        far = (dd >= r2) & (
            (bb >= 0.0)  # moving apart: the start is the closest point
            | (to_end & (ee >= r2_end))
            | (inside & (dd * a - bb * bb >= r2 * a + 1e-9 * dd * a))
        )
        near[b] = not far


@njit(cache=True, nogil=True, error_model="numpy")
def apf_forces(  # noqa: ANN201, PLR0913, PLR0915
    pos,
    vel,
    goal,
    target,
    static_scale,
    idx,
    radius,
    separation,
    min_altitude,
    dist,
    grad,
    moving,
    o_center,
    o_vel,
    o_radius,
    h,
    gh,
    h_goal,
    terrain_floor,
    lo,
    hi,
    all_pos,
    all_vel,
    parked,
    reach,
    gains,
    out,
):
    """``out[i]``: the force of ``apf.apf_forces`` on agent ``idx[i]`` (row i of pos/vel/goal/
    target). ``gains``: (k_att, k_rep, influence, k_agent, quadratic_radius, goal_power,
    k_moving, horizon). ``h``, ``gh``, ``h_goal``: terrain height and gradient under each agent
    and height under its goal; ``terrain_floor``: the terrain clearance (0 without peaks);
    ``parked`` (all agents): agents that no longer fly, whose repulsion takes the goal factor."""
    k_att, k_rep, rho0, k_agent, dq, npow, k_moving, horizon = gains
    n = pos.shape[0]
    m = dist.shape[1]
    n_all = all_pos.shape[0]
    any_moving = False
    for j in range(m):
        if moving[j]:
            any_moving = True
    fmax = -np.inf
    for i in range(n):
        fmax = max(fmax, max(min_altitude[idx[i]], terrain_floor))
    rho0_g = max(min(rho0, 3.0 * fmax), 2.0)
    rb0 = min(rho0, 10.0)
    k_mv = k_rep * k_moving
    # The swarm by coordinate (contiguous columns for the vectorized pair test).
    X, Y, Z = all_pos[:, 0].copy(), all_pos[:, 1].copy(), all_pos[:, 2].copy()
    VX, VY, VZ = all_vel[:, 0].copy(), all_vel[:, 1].copy(), all_vel[:, 2].copy()
    near = np.empty(n_all, dtype=np.bool_)
    pot_s, pot_m = np.empty(m), np.empty(m)
    for i in range(n):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        ri = radius[idx[i]]
        # Attraction (quadratic well only at the goal itself).
        ex, ey, ez = goal[i, 0] - px, goal[i, 1] - py, goal[i, 2] - pz
        dg = math.sqrt(ex * ex + ey * ey + ez * ez)
        tx, ty, tz = target[i, 0] - px, target[i, 1] - py, target[i, 2] - pz
        dt = math.sqrt(tx * tx + ty * ty + tz * tz)
        well = (
            dt <= dq
            and abs(target[i, 0] - goal[i, 0]) <= 1e-9
            and abs(target[i, 1] - goal[i, 1]) <= 1e-9
            and abs(target[i, 2] - goal[i, 2]) <= 1e-9
        )
        if well:
            fx, fy, fz = k_att * tx, k_att * ty, k_att * tz
        else:
            mt = max(dt, _EPS)
            fx, fy, fz = k_att * (dq * tx / mt), k_att * (dq * ty / mt), k_att * (dq * tz / mt)
        ux, uy, uz = _unit(ex, ey, ez)
        ratio = min(1.0, dg / rho0)
        gfac = _power(ratio, npow)
        gfac_d = npow * _power(ratio, npow - 1.0) / rho0 if dg < rho0 else 0.0

        # Obstacle surfaces: static (scaled per agent) then moving, as two sums.
        if m:
            ks = k_rep * static_scale[i]
            sx = sy = sz = 0.0
            mx = my = mz = 0.0
            n_s = n_m = 0
            for j in range(m):
                rho = dist[i, j] - ri
                pot = 0.0
                if rho < rho0:
                    k = k_rep if moving[j] else ks
                    x = 1.0 / max(rho, 0.05) - 1.0 / rho0
                    w = k * x * gfac
                    pot = 0.5 * k * (x * x) * rho0
                    if moving[j]:
                        mx += w * grad[i, j, 0]
                        my += w * grad[i, j, 1]
                        mz += w * grad[i, j, 2]
                    else:
                        sx += w * grad[i, j, 0]
                        sy += w * grad[i, j, 1]
                        sz += w * grad[i, j, 2]
                if moving[j]:
                    pot_m[n_m] = pot
                    n_m += 1
                else:
                    pot_s[n_s] = pot
                    n_s += 1
            fx, fy, fz = fx + sx, fy + sy, fz + sz
            # The companion term sums the potentials as numpy's sum does (pairwise).
            c = _pairwise(pot_s, 0, n_s) * gfac_d if gfac_d != 0.0 else 0.0
            fx, fy, fz = fx + c * ux, fy + c * uy, fz + c * uz
            if any_moving:
                fx, fy, fz = fx + mx, fy + my, fz + mz
                c = _pairwise(pot_m, 0, n_m) * gfac_d if gfac_d != 0.0 else 0.0
                fx, fy, fz = fx + c * ux, fy + c * uy, fz + c * uz
                # Predicted closest approach to each mover, right-hand bias on collision course.
                vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
                sx = sy = sz = 0.0
                for j in range(m):
                    if not moving[j]:
                        continue
                    dpx, dpy, dpz = px - o_center[j, 0], py - o_center[j, 1], pz - o_center[j, 2]
                    dvx, dvy, dvz = vx - o_vel[j, 0], vy - o_vel[j, 1], vz - o_vel[j, 2]
                    a = dvx * dvx + dvy * dvy + dvz * dvz
                    tau = min(max(-(dpx * dvx + dpy * dvy + dpz * dvz) / max(a, _EPS), 0.0), horizon)
                    if tau <= 0.0:
                        continue
                    spx, spy, spz = dpx + tau * dvx, dpy + tau * dvy, dpz + tau * dvz
                    d = math.sqrt(spx * spx + spy * spy + spz * spz)
                    mag = _rep(d - o_radius[j] - ri, rho0, k_mv) * (1.0 - tau / (horizon + _EPS))
                    if mag == 0.0:
                        continue
                    rx, ry, rz = _unit(dvy, -dvx, 0.0)
                    if d < 0.25 * (o_radius[j] + ri + 1.0):
                        wx, wy, wz = rx, ry, rz
                    else:
                        qx, qy, qz = _unit(spx, spy, spz)
                        wx, wy, wz = _unit(qx + 0.3 * rx, qy + 0.3 * ry, qz + 0.3 * rz)
                    sx += mag * wx
                    sy += mag * wy
                    sz += mag * wz
                fx, fy, fz = fx + sx, fy + sy, fz + sz

        # Terrain / ground, pushing only while it is not the way to the goal.
        nx, ny, nz = _unit(-gh[i, 0], -gh[i, 1], 1.0)
        floor = max(min_altitude[idx[i]], terrain_floor)
        rho_g = (pz - h[i]) - ri
        mag = k_rep * (1.0 / max(rho_g, 0.05) - 1.0 / rho0_g) if rho_g < rho0_g else 0.0
        if goal[i, 2] - h_goal[i] < floor:
            mag = mag * gfac
        fx, fy, fz = fx + mag * nx, fy + mag * ny, fz + mag * nz

        # Faces of the flight volume (the floor is the ground's): low face, then high, per axis.
        fx += _face(px - lo[0], 1.0, ri, rb0, k_rep, gfac)
        fx += _face(px - hi[0], -1.0, ri, rb0, k_rep, gfac)
        fy += _face(py - lo[1], 1.0, ri, rb0, k_rep, gfac)
        fy += _face(py - hi[1], -1.0, ri, rb0, k_rep, gfac)
        fz += _face(pz - hi[2], -1.0, ri, rb0, k_rep, gfac)

        # Other agents: ellipsoidal separation, current and predicted (apf._agent_repulsion_indexed).
        ax = ay = az = 0.0
        if n_all >= 2:
            ia = idx[i]
            vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
            _near(px, py, pz, vx, vy, vz, X, Y, Z, VX, VY, VZ, horizon, reach, near)
            for b in range(n_all):
                if b == ia or not near[b]:
                    continue
                dpx, dpy, dpz = px - all_pos[b, 0], py - all_pos[b, 1], pz - all_pos[b, 2]
                dwx, dwy, dwz = vx - all_vel[b, 0], vy - all_vel[b, 1], vz - all_vel[b, 2]
                rr = radius[ia] + radius[b]
                cx = max(separation[ia, 0], separation[b, 0]) + rr
                cy = max(separation[ia, 1], separation[b, 1]) + rr
                cz = max(separation[ia, 2], separation[b, 2]) + rr
                qx, qy, qz = dpx / cx, dpy / cy, dpz / cz
                e = math.sqrt(qx * qx + qy * qy + qz * qz)
                e0 = 1.0 + rho0 / max(math.sqrt(cx * cx + cy * cy + cz * cz), _EPS)
                dvx, dvy, dvz = dwx / cx, dwy / cy, dwz / cz
                aa = dvx * dvx + dvy * dvy + dvz * dvz
                tau = min(max(-(qx * dvx + qy * dvy + qz * dvz) / max(aa, _EPS), 0.0), horizon)
                sx, sy, sz = qx + tau * dvx, qy + tau * dvy, qz + tau * dvz
                es = math.sqrt(sx * sx + sy * sy + sz * sz)
                current = e < e0
                predicted = es < e0 and tau > 0
                if not (current or predicted):
                    continue
                gx, gy, gz = _unit(qx / cx, qy / cy, qz / cz)
                mag = k_agent * (1.0 / max(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)) if current else 0.0
                urgency = 1.0 - tau / (horizon + _EPS)
                mag_p = k_agent * (1.0 / max(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)) if predicted else 0.0
                mag_p = mag_p * urgency
                if parked[b]:  # a parked agent repels as a static body: with the goal factor
                    mag = mag * gfac
                    mag_p = mag_p * gfac
                wx, wy, wz = _unit(sx * cx, sy * cy, sz * cz)
                rx, ry, rz = _unit(dwy, -dwx, 0.0)
                wx, wy, wz = _unit(wx + 0.5 * rx, wy + 0.5 * ry, wz + 0.5 * rz)
                ax += mag * gx + mag_p * wx
                ay += mag * gy + mag_p * wy
                az += mag * gz + mag_p * wz
        out[i, 0] = fx + ax
        out[i, 1] = fy + ay
        out[i, 2] = fz + az
