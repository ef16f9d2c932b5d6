"""The potential field of ``swarmplan.flight.apf`` in numpy, for worlds below swarm size
(``swarmplan.geometry.compiled.use_compiled``): :func:`apf_forces` takes the arguments of
``swarmplan.flight._apf_kernel.apf_forces`` and writes the same bits.

Why a second implementation: the compiled one needs numba, whose import and the loading of the
kernel's cached machine code cost ~0.3 s of CPU per process, more than a small world's first
step may take (and than many whole small runs save). Bit for bit: every term follows the
kernel's formulas operation by operation (IEEE arithmetic is exact per operation, so the
same expression gives the same double whether numba or numpy evaluates it), and every sum the
kernel accumulates term by term is accumulated here in the same order by ``np.add.accumulate``
(sequential, never pairwise), a skipped term being ``-0.0``, the one double whose addition
changes nothing. Branches become masks that choose between the two branches' values. The
kernel's cheap test of every pair (the closest approach within the horizon beyond ``reach``)
selects the pairs the agent term is computed for, as in the kernel; below swarm size every
pair is at most 48 x 48. tests/test_apf_numpy.py checks the equality on random swarms.
"""

from __future__ import annotations

import math

import numpy as np

_EPS = 1e-9  # apf._EPS
_SKIP = -0.0  # x + (-0.0) == x for every double x, -0.0 included


def _unit(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.maximum(np.sqrt(x * x + y * y + z * z), _EPS)
    return x / n, y / n, z / n


def _pow1(x: float, p: float) -> float:
    try:
        return math.pow(x, p)
    except (ValueError, OverflowError):  # C's pow answers (inf, nan) where Python raises
        with np.errstate(all="ignore"):
            return float(np.power(x, p))


def _power(x: np.ndarray, p: float) -> np.ndarray:
    """The kernel's ``_power`` elementwise (numpy's fast paths, else C's ``pow``)."""
    if p == 2.0:
        return x * x
    if p == 1.0:
        return x.copy()
    if p == 0.5:
        return np.sqrt(x)
    if p == -1.0:
        return 1.0 / x
    if p == 0.0:
        return np.ones_like(x)
    return np.array([_pow1(float(v), p) for v in x.ravel()]).reshape(x.shape)


def _right(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's ``_right`` elementwise."""
    h2 = x * x + y * y
    zero = np.zeros_like(x)
    horizontal = _unit(y, -x, zero)
    about_x = _unit(zero, z, -y)
    side = h2 >= 0.04 * (h2 + z * z)
    return tuple(np.where(side, a, b) for a, b in zip(horizontal, about_x, strict=True))  # type: ignore[return-value]


def _sum_in_order(first: np.ndarray, terms: np.ndarray) -> np.ndarray:
    """``first[i] + terms[i, 0] + terms[i, 1] + ...`` added left to right (rows (n,), (n, k))."""
    if terms.shape[1] == 0:
        return first
    return np.add.accumulate(np.column_stack([first, terms]), axis=1)[:, -1]


def _face(
    offset: np.ndarray, sign: float, r: np.ndarray, rb0: float, k_rep: float, gfac: np.ndarray
) -> np.ndarray:
    rho_b = sign * offset - r
    mag = np.where(rho_b < rb0, k_rep * (1.0 / np.maximum(rho_b, 0.05) - 1.0 / rb0), 0.0)
    return sign * mag * gfac


def apf_forces(flyers, agents, bodies, ground, swarm, reach, gains, out) -> None:  # noqa: ANN001, PLR0915
    """``out[i]``: the force of ``apf.ApfField.forces`` on agent ``idx[i]``; the arguments of
    ``_apf_kernel.apf_forces``."""
    pos, vel, goal, target, static_scale, idx, reach_now = flyers
    radius, separation, min_altitude, stop_reach, can_stop = agents
    dist, grad, moving, o_center, o_vel, o_radius = bodies
    h, gh, h_goal, terrain_floor, lo, hi = ground
    all_pos, all_vel, parked, goal_dist, reach_all = swarm
    k_att, k_rep, rho0, k_agent, dq, npow, k_moving, horizon = gains
    n = pos.shape[0]
    if n == 0:
        return
    m = dist.shape[1]
    n_all = all_pos.shape[0]
    floor = np.maximum(min_altitude[idx], terrain_floor)
    fmax = float(floor.max())
    rho0_g = max(min(rho0, 3.0 * fmax), 2.0)
    rb0 = min(rho0, 10.0)
    k_mv = k_rep * k_moving
    px, py, pz = pos[:, 0], pos[:, 1], pos[:, 2]
    vx, vy, vz = vel[:, 0], vel[:, 1], vel[:, 2]
    ri = radius[idx]

    # Attraction (quadratic well only at the goal itself).
    ex, ey, ez = goal[:, 0] - px, goal[:, 1] - py, goal[:, 2] - pz
    dg = np.sqrt(ex * ex + ey * ey + ez * ez)
    tx, ty, tz = target[:, 0] - px, target[:, 1] - py, target[:, 2] - pz
    dt = np.sqrt(tx * tx + ty * ty + tz * tz)
    to_goal = (
        (np.abs(target[:, 0] - goal[:, 0]) <= 1e-9)
        & (np.abs(target[:, 1] - goal[:, 1]) <= 1e-9)
        & (np.abs(target[:, 2] - goal[:, 2]) <= 1e-9)
    )
    well = (dt <= dq) & to_goal
    mt = np.maximum(dt, _EPS)
    fx = np.where(well, k_att * tx, k_att * (dq * tx / mt))
    fy = np.where(well, k_att * ty, k_att * (dq * ty / mt))
    fz = np.where(well, k_att * tz, k_att * (dq * tz / mt))
    ux, uy, uz = _unit(ex, ey, ez)
    ratio = np.minimum(1.0, dg / rho0)
    gfac = _power(ratio, npow)
    gfac_d = np.where(dg < rho0, npow * _power(ratio, npow - 1.0) / rho0, 0.0)

    # Obstacle surfaces (static ones scaled per agent), the goal factor's companion term, the
    # turn along blocking bodies and the movers' predicted closest approach.
    bx = by = bz = np.zeros(n)
    hold = np.zeros(n)
    if m:
        fx, fy, fz, bx, by, bz, hold = _bodies(
            (px, py, pz, vx, vy, vz, ri, tx, ty, tz, dg, to_goal, gfac, gfac_d, ux, uy, uz, fx, fy, fz),
            (dist, grad, moving, o_center, o_vel, o_radius),
            (k_rep, rho0, k_mv, horizon),
            static_scale,
        )

    # Terrain / ground, pushing only while it is not the way to the goal.
    nx, ny, nz = _unit(-gh[:, 0], -gh[:, 1], np.ones(n))
    rho_g = (pz - h) - ri
    mag = np.where(rho_g < rho0_g, k_rep * (1.0 / np.maximum(rho_g, 0.05) - 1.0 / rho0_g), 0.0)
    mag = np.where(goal[:, 2] - h_goal < floor, mag * gfac, mag)
    fx, fy, fz = fx + mag * nx, fy + mag * ny, fz + mag * nz

    # Faces of the flight volume (the floor is the ground's).
    fx = fx + _face(px - lo[0], 1.0, ri, rb0, k_rep, gfac)
    fx = fx + _face(px - hi[0], -1.0, ri, rb0, k_rep, gfac)
    fy = fy + _face(py - lo[1], 1.0, ri, rb0, k_rep, gfac)
    fy = fy + _face(py - hi[1], -1.0, ri, rb0, k_rep, gfac)
    fz = fz + _face(pz - hi[2], -1.0, ri, rb0, k_rep, gfac)

    # Other agents.
    if n_all >= 2:
        terms = _agent_terms(
            (px, py, pz, vx, vy, vz, idx, reach_now, dg, gfac),
            (radius, separation, stop_reach, can_stop),
            (all_pos, all_vel, parked, goal_dist, reach_all),
            (reach, rho0, k_agent, horizon),
        )
        fx, fy, fz = (_sum_in_order(f, t) for f, t in zip((fx, fy, fz), terms, strict=True))
    # The turn along blocking bodies only where they hold the agent.
    pull = k_att * np.minimum(dt, dq)
    turned = ((bx != 0.0) | (by != 0.0) | (bz != 0.0)) & (pull + hold < 0.25 * pull)
    out[:, 0] = np.where(turned, fx + bx, fx)
    out[:, 1] = np.where(turned, fy + by, fy)
    out[:, 2] = np.where(turned, fz + bz, fz)


def _bodies(a, bodies, g, static_scale):  # noqa: ANN001, ANN202
    """The kernel's obstacle part (``if m:``) for every flyer: forces, the turn and the hold."""
    px, py, pz, vx, vy, vz, ri, tx, ty, tz, dg, to_goal, gfac, gfac_d, ux, uy, uz, fx, fy, fz = a
    dist, grad, moving, o_center, o_vel, o_radius = bodies
    k_rep, rho0, k_mv, horizon = g
    col = np.newaxis
    ks = k_rep * static_scale
    ax, ay, az = _unit(tx, ty, tz)
    turn = np.where(to_goal, np.minimum(1.0, np.maximum(0.0, dg / rho0 - 1.0)), 0.0)
    rho = dist - ri[:, col]
    active = rho < rho0
    static = active & ~moving[col, :]
    k = np.where(moving[col, :], k_rep, ks[:, col])
    x = 1.0 / np.maximum(rho, 0.05) - 1.0 / rho0
    w = k * x * gfac[:, col]
    pot = 0.5 * k * (x * x) * rho0
    nx, ny, nz = grad[..., 0], grad[..., 1], grad[..., 2]
    fx = _sum_in_order(fx, np.where(active, w * nx, _SKIP))
    fy = _sum_in_order(fy, np.where(active, w * ny, _SKIP))
    fz = _sum_in_order(fz, np.where(active, w * nz, _SKIP))
    pot_sum = _sum_in_order(np.zeros(len(fx)), np.where(active, pot, _SKIP))
    block = ax[:, col] * nx + ay[:, col] * ny + az[:, col] * nz
    hold = _sum_in_order(np.zeros(len(fx)), np.where(static, w * block, _SKIP))
    turning = static & (block < 0.0) & (turn[:, col] > 0.0)
    bx = by = bz = np.zeros(len(fx))
    if turning.any():
        sx, sy, sz = ax[:, col] - block * nx, ay[:, col] - block * ny, az[:, col] - block * nz
        square = sx * sx + sy * sy + sz * sz < 0.04
        cx, cy = px[:, col] - o_center[col, :, 0], py[:, col] - o_center[col, :, 1]
        d = cx * nx + cy * ny
        qx, qy, qz = cx - d * nx, cy - d * ny, -d * nz
        centre = qx * qx + qy * qy + qz * qz < 1e-12 * (1.0 + cx * cx + cy * cy)
        rx, ry, rz = _right(-nx, -ny, -nz)
        qx, qy, qz = np.where(centre, rx, qx), np.where(centre, ry, qy), np.where(centre, rz, qz)
        sx, sy, sz = _unit(np.where(square, qx, sx), np.where(square, qy, sy), np.where(square, qz, sz))
        wt = w * block * turn[:, col]
        bx = _sum_in_order(bx, np.where(turning, -(wt * sx), _SKIP))
        by = _sum_in_order(by, np.where(turning, -(wt * sy), _SKIP))
        bz = _sum_in_order(bz, np.where(turning, -(wt * sz), _SKIP))
    c = pot_sum * gfac_d
    fx, fy, fz = fx + c * ux, fy + c * uy, fz + c * uz
    mv = np.flatnonzero(moving)
    if len(mv):
        # Predicted closest approach to each mover, right-hand bias on collision course.
        dpx, dpy, dpz = (p[:, col] - o_center[col, mv, k] for k, p in enumerate((px, py, pz)))
        dvx, dvy, dvz = (v[:, col] - o_vel[col, mv, k] for k, v in enumerate((vx, vy, vz)))
        aa = dvx * dvx + dvy * dvy + dvz * dvz
        tau = np.minimum(
            np.maximum(-(dpx * dvx + dpy * dvy + dpz * dvz) / np.maximum(aa, _EPS), 0.0), horizon
        )
        spx, spy, spz = dpx + tau * dvx, dpy + tau * dvy, dpz + tau * dvz
        d = np.sqrt(spx * spx + spy * spy + spz * spz)
        r_o = o_radius[col, mv]
        rho_m = d - r_o - ri[:, col]
        rep = np.where(rho_m < rho0, k_mv * (1.0 / np.maximum(rho_m, 0.05) - 1.0 / rho0), 0.0)
        mag = rep * (1.0 - tau / (horizon + _EPS))
        live = (tau > 0.0) & (mag != 0.0)
        rx, ry, rz = _unit(dvy, -dvx, np.zeros_like(dvx))
        qx, qy, qz = _unit(spx, spy, spz)
        wx, wy, wz = _unit(qx + 0.3 * rx, qy + 0.3 * ry, qz + 0.3 * rz)
        head_on = d < 0.25 * (r_o + ri[:, col] + 1.0)
        wx, wy, wz = np.where(head_on, rx, wx), np.where(head_on, ry, wy), np.where(head_on, rz, wz)
        fx = _sum_in_order(fx, np.where(live, mag * wx, _SKIP))
        fy = _sum_in_order(fy, np.where(live, mag * wy, _SKIP))
        fz = _sum_in_order(fz, np.where(live, mag * wz, _SKIP))
    return fx, fy, fz, bx, by, bz, hold


def _agent_terms(f, agents, swarm, g):  # noqa: ANN001, ANN202
    """The other agents' terms on every flyer, (n, n_all) per axis in the kernel's order of
    agents, ``-0.0`` where the kernel adds nothing."""
    px, py, pz, vx, vy, vz, idx, reach_now, dg, gfac = f
    radius, separation, stop_reach, can_stop = agents
    all_pos, all_vel, parked, goal_dist, reach_all = swarm
    reach, rho0, k_agent, horizon = g
    col = np.newaxis
    n, n_all = len(px), len(all_pos)
    dx, dy, dz = px[:, col] - all_pos[:, 0], py[:, col] - all_pos[:, 1], pz[:, col] - all_pos[:, 2]
    wx, wy, wz = vx[:, col] - all_vel[:, 0], vy[:, col] - all_vel[:, 1], vz[:, col] - all_vel[:, 2]
    # The kernel's _near: pairs whose closest approach within the horizon may lie inside reach.
    r2 = reach * reach
    r2_end = r2 * (1.0 + 1e-9)
    dd = dx * dx + dy * dy + dz * dz
    bb = dx * wx + dy * wy + dz * wz
    a = wx * wx + wy * wy + wz * wz
    ex, ey, ez = dx + horizon * wx, dy + horizon * wy, dz + horizon * wz
    ee = ex * ex + ey * ey + ez * ez
    to_end = -bb >= a * horizon
    inside = -bb < a * horizon
    far = (dd >= r2) & (
        (bb >= 0.0) | (to_end & (ee >= r2_end)) | (inside & (dd * a - bb * bb >= r2 * a + 1e-9 * dd * a))
    )
    far[np.arange(n), idx] = True  # an agent and itself
    rows, b = np.nonzero(~far)
    terms = np.full((3, n, n_all), _SKIP)
    if len(rows) == 0:
        return terms
    ia = idx[rows]
    dpx, dpy, dpz = dx[rows, b], dy[rows, b], dz[rows, b]
    dwx, dwy, dwz = wx[rows, b], wy[rows, b], wz[rows, b]
    rr = radius[ia] + radius[b]
    cx = np.maximum(separation[ia, 0], separation[b, 0]) + rr
    cy = np.maximum(separation[ia, 1], separation[b, 1]) + rr
    cz = np.maximum(separation[ia, 2], separation[b, 2]) + rr
    qx, qy, qz = dpx / cx, dpy / cy, dpz / cz
    e = np.sqrt(qx * qx + qy * qy + qz * qz)
    stop_a, stop_b = can_stop[ia], can_stop[b]
    pair_reach = stop_reach[ia] + stop_reach[b]
    pair_reach = np.where(
        parked[b] & stop_a,
        reach_now[rows],
        np.where(stop_a & stop_b, np.minimum(pair_reach, reach_now[rows] + reach_all[b]), pair_reach),
    )
    e0 = 1.0 + np.minimum(pair_reach, rho0) / np.maximum(np.maximum(cx, cy), cz)
    dvx, dvy, dvz = dwx / cx, dwy / cy, dwz / cz
    aa = dvx * dvx + dvy * dvy + dvz * dvz
    tau = np.minimum(np.maximum(-(qx * dvx + qy * dvy + qz * dvz) / np.maximum(aa, _EPS), 0.0), horizon)
    sx, sy, sz = qx + tau * dvx, qy + tau * dvy, qz + tau * dvz
    es = np.sqrt(sx * sx + sy * sy + sz * sz)
    current = e < e0
    predicted = (es < e0) & (tau > 0)
    gx, gy, gz = _unit(qx / cx, qy / cy, qz / cz)
    mag = np.where(current, k_agent * (1.0 / np.maximum(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    urgency = 1.0 - tau / (horizon + _EPS)
    mag_p = np.where(predicted, k_agent * (1.0 / np.maximum(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    mag_p = mag_p * urgency
    # Priority: a parked agent, or one farther from its goal, repels with the goal factor.
    factored = stop_a & (parked[b] | (dg[rows] <= goal_dist[b]))
    mag = np.where(factored, mag * gfac[rows], mag)
    mag_p = np.where(factored, mag_p * gfac[rows], mag_p)
    ux, uy, uz = _unit(sx * cx, sy * cy, sz * cz)
    rx, ry, rz = _right(dwx, dwy, dwz)
    over = (2.0 * dwx + dwy) / (math.sqrt(5.0) * np.maximum(np.sqrt(dwx * dwx + dwy * dwy + dwz * dwz), _EPS))
    ux, uy, uz = _unit(ux + 0.5 * rx, uy + 0.5 * ry, uz + 0.5 * (rz + over))
    acts = current | predicted
    terms[0, rows, b] = np.where(acts, mag * gx + mag_p * ux, _SKIP)
    terms[1, rows, b] = np.where(acts, mag * gy + mag_p * uy, _SKIP)
    terms[2, rows, b] = np.where(acts, mag * gz + mag_p * uz, _SKIP)
    return terms
