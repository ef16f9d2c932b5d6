"""Compiled potential field of swarm-sized worlds (``apf.apf_forces`` from ``COMPILED_FROM``
agents on): every term of every agent in one pass.

Why numba: in numpy the field is ~60 array operations per step on (agents, bodies, 3) and
(pairs, 3) temporaries plus a k-d tree for the agent term (3.8 ms per step at 256 agents,
2.1 ms at 64 with 32 movers), mostly per-call overhead and memory traffic; here each agent's
force is summed where its terms are computed. The formulas, their order and the order of
the terms are those of ``apf.py`` (tests/test_apf_compiled.py holds the two together): the
agent term is bit for bit the indexed numpy one (same per-pair values, summed in the same
order); the obstacle terms differ from ``np.einsum``'s sums by rounding, ~1e-16 relative.

The agent term visits every other agent, but a pair is dismissed with a few products (no
division) when the closest approach of the two centres within the prediction horizon stays
beyond ``reach``, the distance past which both of its terms are provably zero
(``apf.agent_reach``'s bound without the speed part): the scaled distances are at least the
unscaled ones over the largest semi-axis. At 256 agents that is ~65k cheap tests per step;
a spatial index would pay off only for swarms several times larger.

Imported lazily (:func:`swarmplan.apf._kernel`); every compiled function of the field is
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
def _far_apart(dx, dy, dz, vx, vy, vz, horizon, reach):  # noqa: ANN001, ANN202
    """True when ``|d + t v| >= reach`` for every t in [0, horizon] (with a margin for rounding):
    the closest approach of the segment, from squared lengths only."""
    r2 = reach * reach
    dd = dx * dx + dy * dy + dz * dz
    if dd < r2:
        return False
    b = dx * vx + dy * vy + dz * vz
    if b >= 0.0:
        return True  # moving apart: the start is the closest point
    a = vx * vx + vy * vy + vz * vz
    if -b >= a * horizon:  # still approaching at the horizon: the end is the closest point
        ex = dx + horizon * vx
        ey = dy + horizon * vy
        ez = dz + horizon * vz
        return ex * ex + ey * ey + ez * ez >= r2 * (1.0 + 1e-9)
    # Interior minimum dd - b^2 / a >= r2, without the division; the difference cancels when
    # d and v are nearly parallel, hence the margin relative to dd * a.
    return dd * a - b * b >= r2 * a + 1e-9 * dd * a


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
            sx = sy = sz = ps = 0.0
            mx = my = mz = pm = 0.0
            for j in range(m):
                rho = dist[i, j] - ri
                if rho < rho0:
                    k = k_rep if moving[j] else ks
                    x = 1.0 / max(rho, 0.05) - 1.0 / rho0
                    w = k * x * gfac
                    pot = 0.5 * k * (x * x) * rho0
                    if moving[j]:
                        mx += w * grad[i, j, 0]
                        my += w * grad[i, j, 1]
                        mz += w * grad[i, j, 2]
                        pm += pot
                    else:
                        sx += w * grad[i, j, 0]
                        sy += w * grad[i, j, 1]
                        sz += w * grad[i, j, 2]
                        ps += pot
            fx, fy, fz = fx + sx, fy + sy, fz + sz
            c = ps * gfac_d
            fx, fy, fz = fx + c * ux, fy + c * uy, fz + c * uz
            if any_moving:
                fx, fy, fz = fx + mx, fy + my, fz + mz
                c = pm * gfac_d
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
            for b in range(n_all):
                if b == ia:
                    continue
                dpx, dpy, dpz = px - all_pos[b, 0], py - all_pos[b, 1], pz - all_pos[b, 2]
                dwx, dwy, dwz = vx - all_vel[b, 0], vy - all_vel[b, 1], vz - all_vel[b, 2]
                if _far_apart(dpx, dpy, dpz, dwx, dwy, dwz, horizon, reach):
                    continue
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
