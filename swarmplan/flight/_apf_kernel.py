"""The potential field of ``swarmplan.flight.apf`` compiled: every term of every agent in one
pass (the one implementation of the field; tests/apf_reference.py is its numpy reference).

Why numba: in numpy the field is ~60 array operations per step on (agents, bodies, 3) and
(pairs, 3) temporaries plus a neighbour index for the agent term, mostly per-call overhead and
memory traffic; here each agent's force is summed where its terms are computed.

The agent term visits every other agent, but a pair is dismissed with a few products (no
division) when the closest approach of the two centres within the prediction horizon stays
beyond ``reach``, the distance past which both of its terms are provably zero
(``apf.current_reach``): the scaled distances are at least the unscaled ones over the largest
semi-axis. With ``window`` (``apf.WINDOW_FROM`` agents on) a flyer tests only the agents
whose x lies within ``reach + horizon * (its speed + the swarm's top speed) + 1 m`` of its own
(the swarm sorted along x once per call): the others' relative motion cannot bring them within
``reach`` along x alone, so the test dismisses them anyway, with a metre to spare against
rounding; the agents kept are visited in index order, so the forces are summed in the same
order, to the same bits. A moving body is dismissed the same way before its closest approach is computed (two
divisions and a root per pair): when the centres are farther apart than the influence, both
radii and both speeds over the horizon, plus a metre, its term is provably zero.

Loaded at the first step through ``runtime.compiled.kernel_module``; every compiled function of the field is
in this file (numba's cache does not see changes of callees in other files).
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.geometry._sort_kernel import argsort, search_left, search_right
from swarmplan.runtime.compiled import njit

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
def _rep(rho, rho0, k, near):  # noqa: ANN001, ANN202
    """``field_law.repulsion`` of one value (``near``: the agent's ``field_law.nearest``)."""
    if rho < rho0:
        return k * (1.0 / max(rho, near) - 1.0 / rho0)
    return 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _hemmed(ux, uy, p, ri, need, dist_i, grad_i, moving, lo, hi):  # noqa: ANN001, ANN202
    """Whether a static surface lies within ``need`` of an agent of radius ``ri`` at ``p`` on
    its side ``(ux, uy)`` (horizontal, unit): a body whose outward normal there turns more than
    half against that side (``dist_i``, ``grad_i``: the agent's distances and gradients; a body
    at distance inf is not seen), or a face of the flight volume ``lo``..``hi`` across it."""
    for j in range(dist_i.shape[0]):
        if not moving[j] and dist_i[j] - ri < need and grad_i[j, 0] * ux + grad_i[j, 1] * uy < -0.5:
            return True
    return (
        (ux < -0.5 and p[0] - lo[0] - ri < need)
        or (ux > 0.5 and hi[0] - p[0] - ri < need)
        or (uy < -0.5 and p[1] - lo[1] - ri < need)
        or (uy > 0.5 and hi[1] - p[1] - ri < need)
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _face(offset, sign, r, rb0, k_rep, gfac, near):  # noqa: ANN001, ANN202
    """Force component from a face of ``bounds`` at ``offset = p - plane`` (sign +1: low face)."""
    rho_b = sign * offset - r
    mag = k_rep * (1.0 / max(rho_b, near) - 1.0 / rb0) if rho_b < rb0 else 0.0
    return sign * mag * gfac


@njit(cache=True, nogil=True, error_model="numpy")
def _near(p, v, at, vel, horizon, reach, near):  # noqa: ANN001, ANN202
    """``near[b]`` = False when ``|d + t w| >= reach[b]`` for every t in [0, horizon], d and w the
    position and velocity of the point ``p = (px, py, pz)`` moving at ``v = (vx, vy, vz)``
    relative to agent b, whose coordinates are ``at = (X, Y, Z)`` and ``vel = (VX, VY, VZ)``
    (a margin covers rounding): the closest approach of the segment from squared lengths only,
    no division and no branch, so the loop over the swarm is vectorized."""
    px, py, pz = p
    vx, vy, vz = v
    X, Y, Z = at
    VX, VY, VZ = vel
    for b in range(X.shape[0]):
        r2 = reach[b] * reach[b]
        r2_end = r2 * (1.0 + 1e-9)
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
def _index_order(rows, k, seen):  # noqa: ANN001, ANN202
    """``rows[:k]`` (distinct indexes) sorted in place: by insertion while short (a flyer's
    near agents, a few tens), else by marking them in ``seen`` (all False, and again on
    return) and reading it between the smallest and the largest (numba's sort of a few
    hundred costs more)."""
    if k > 64:
        lo, hi = rows[0], rows[0]
        for c in range(k):
            seen[rows[c]] = True
            lo, hi = min(lo, rows[c]), max(hi, rows[c])
        c = 0
        for b in range(lo, hi + 1):
            if seen[b]:
                rows[c] = b
                c += 1
                seen[b] = False
        return
    for c in range(1, k):
        b = rows[c]
        t = c
        while t > 0 and rows[t - 1] > b:
            rows[t] = rows[t - 1]
            t -= 1
        rows[t] = b


@njit(cache=True, nogil=True, error_model="numpy")
def _right(x, y, z):  # noqa: ANN001, ANN202
    """Unit vector to the right of the relative velocity (x, y, z): horizontal (z up) while the
    motion has a horizontal part of at least a fifth of its speed, else about the x axis (the
    right-hand rule still breaks the symmetry of vertical head-on encounters)."""
    h2 = x * x + y * y
    if h2 >= 0.04 * (h2 + z * z):
        return _unit(y, -x, 0.0)
    return _unit(0.0, z, -y)


@njit(cache=True, nogil=True, error_model="numpy")
def _over(x, y, z):  # noqa: ANN001, ANN202
    """Vertical part of the way past another agent, from the relative velocity (x, y, z): up
    for one of the two, down for the other (the relative velocity changes sign between them),
    by a fixed horizontal direction (2, 1, 0) / sqrt(5), so that agents also pass over and under
    each other where there is no room beside (a doorway)."""
    n = max(math.sqrt(x * x + y * y + z * z), _EPS)
    return (2.0 * x + y) / (math.sqrt(5.0) * n)


@njit(cache=True, nogil=True, error_model="numpy")
def apf_forces(flyers, agents, bodies, ground, swarm, reach, gains, out, window=False):  # noqa: ANN001, ANN201, PLR0915
    """``out[i]``: the force of ``apf.ApfField.forces`` on agent ``idx[i]``.

    ``flyers``: (pos, vel, goal, target, static_scale, idx, reach at the current speed, field
    scale) of the agents computed (the scale multiplies the influence, the quadratic radius and
    ``k_agent``, its square ``k_rep``: ``kinematics.field_scales``);
    ``agents``: per agent of the world (radius, separation, min_altitude, stopping reach,
    can stop); ``bodies``: (distance, gradient, moving, centre, velocity, bounding radius);
    ``ground``: (terrain height and gradient under each flyer, height under its goal, the
    terrain clearance (0 without peaks), bounds min, bounds max); ``swarm``: (positions,
    velocities, parked, distance to the goal, reach at the current speed) of every agent, and
    a view (flyers, agents) of row numbers into those arrays, -1 for an agent the flyer does
    not know of (each flyer's own beliefs of the others), or an empty (0, 0) view: row b is
    agent b for every flyer; with a view, each row's doubt (m: how far the agent may be from
    where it is believed), which widens the pair's separation ellipsoid on every axis and
    ``reach`` (the distance between centres beyond which a pair's terms are zero) by as much;
    ``gains``: (k_att, k_rep, influence, k_agent, quadratic_radius, goal_power, k_moving, horizon);
    ``window``: test only the agents within each flyer's window along x (the same forces)."""
    pos, vel, goal, target, static_scale, idx, reach_now, length = flyers
    radius, separation, min_altitude, stop_reach, can_stop = agents
    dist, grad, moving, o_center, o_vel, o_radius = bodies
    h, gh, h_goal, terrain_floor, lo, hi = ground
    all_pos, all_vel, parked, goal_dist, reach_all, view, doubt, yields = swarm
    viewed = view.shape[0] > 0
    k_att, k_rep_w, rho0_w, k_agent_w, dq_w, npow, k_moving, horizon = gains
    n = pos.shape[0]
    m = dist.shape[1]
    n_all = view.shape[1] if viewed else all_pos.shape[0]
    any_moving = False
    m_speed = np.zeros(m)  # each mover's speed (the bound that dismisses far movers)
    for j in range(m):
        if moving[j]:
            any_moving = True
            m_speed[j] = math.sqrt(
                o_vel[j, 0] * o_vel[j, 0] + o_vel[j, 1] * o_vel[j, 1] + o_vel[j, 2] * o_vel[j, 2]
            )
    # The swarm by coordinate (contiguous columns for the vectorized pair test).
    if viewed:  # filled per flyer from its view
        X, Y, Z, VX, VY, VZ = (np.zeros(n_all), np.zeros(n_all), np.zeros(n_all),
                               np.zeros(n_all), np.zeros(n_all), np.zeros(n_all))  # fmt: skip
    else:
        X, Y, Z = all_pos[:, 0].copy(), all_pos[:, 1].copy(), all_pos[:, 2].copy()
        VX, VY, VZ = all_vel[:, 0].copy(), all_vel[:, 1].copy(), all_vel[:, 2].copy()
    near = np.empty(n_all, dtype=np.bool_)
    # Each agent's reach: ``reach``, with a view widened by the doubt of the row held (the row
    # each coordinate holds is kept: most flyers hold the same rows, so few entries change).
    R = np.full(n_all, reach)
    held = np.full(n_all, -1, dtype=np.int64)
    rows = np.empty(n_all, dtype=np.int64)
    seen = np.zeros(n_all, dtype=np.bool_)
    wanted = np.empty(n_all if viewed else 0, dtype=np.int64)  # with a view: each flyer's row per agent
    changed = np.empty(n_all + 1 if viewed else 0, dtype=np.int64)
    # With ``window``: the swarm sorted along x, and its top speed, for each flyer's window.
    v_all = 0.0
    finite = True  # a NaN anywhere: every agent is tested, as without the window
    for b in range(n_all):
        v_all = max(v_all, math.sqrt(VX[b] * VX[b] + VY[b] * VY[b] + VZ[b] * VZ[b]))
        finite = finite and math.isfinite(X[b] + Y[b] + Z[b] + VX[b] + VY[b] + VZ[b])
    window = window and not viewed and n_all >= 2 and finite
    window = window and math.isfinite(v_all) and 0.0 <= horizon < np.inf
    order = argsort(X) if window else np.arange(n_all)
    XS, YS, ZS = X[order], Y[order], Z[order]
    VXS, VYS, VZS = VX[order], VY[order], VZ[order]
    for i in range(n):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        ri = radius[idx[i]]
        sc = length[i]  # the agent's own field: the world's scaled (kinematics.field_scales)
        rho0, k_rep, dq, k_agent = sc * rho0_w, k_rep_w * (sc * sc), sc * dq_w, sc * k_agent_w
        rb_stop, rb_fly = 0.25 * rho0, min(rho0, 10.0)  # field_law.bounds_range: multirotors, fixed wings
        k_mv = k_rep * k_moving
        closest = 0.1 * ri  # field_law.nearest: the clearance below which the pushes stop growing
        rb0 = rb_stop if can_stop[idx[i]] else rb_fly
        # field_law.ground_range: the clearance at the agent's floor lowered to its goal's
        # height, at least its radius (multirotors); the influence down to three floors, at
        # least a quarter of it (fixed wings).
        fl = max(min_altitude[idx[i]], terrain_floor)
        if can_stop[idx[i]]:
            rho0_g = max(min(fl, goal[i, 2] - h_goal[i]) - ri, ri)
        else:
            rho0_g = max(min(rho0, 3.0 * fl), 0.25 * rho0)
        # Attraction (quadratic well only at the goal itself).
        ex, ey, ez = goal[i, 0] - px, goal[i, 1] - py, goal[i, 2] - pz
        dg = math.sqrt(ex * ex + ey * ey + ez * ez)
        tx, ty, tz = target[i, 0] - px, target[i, 1] - py, target[i, 2] - pz
        dt = math.sqrt(tx * tx + ty * ty + tz * tz)
        to_goal = (
            abs(target[i, 0] - goal[i, 0]) <= 1e-9
            and abs(target[i, 1] - goal[i, 1]) <= 1e-9
            and abs(target[i, 2] - goal[i, 2]) <= 1e-9
        )
        well = dt <= dq and to_goal
        if well:
            fx, fy, fz = k_att * tx, k_att * ty, k_att * tz
        else:
            mt = max(dt, _EPS)
            fx, fy, fz = k_att * (dq * tx / mt), k_att * (dq * ty / mt), k_att * (dq * tz / mt)
        ratio = min(1.0, dg / rho0)
        gfac = _power(ratio, npow)
        gfac_d = npow * _power(ratio, npow - 1.0) / rho0 if dg < rho0 else 0.0

        # Obstacle surfaces (static ones scaled per agent), and the goal factor's companion
        # term pulling towards the goal with the sum of their potentials.
        bx = by = bz = 0.0  # the turn along blocking bodies (added if they hold the agent)
        hold = 0.0  # the static bodies' push along the pull
        if m:
            ks = k_rep * static_scale[i]
            pot_sum = 0.0
            ax, ay, az = _unit(tx, ty, tz)
            # The turn along blocking bodies fades in from one to two influence distances from
            # the goal (a goal beside a body is reached through the goal factor instead), and
            # only on the way to the goal itself: a route or segment already chose the way round.
            turn = min(1.0, max(0.0, dg / rho0 - 1.0)) if to_goal else 0.0
            for j in range(m):
                rho = dist[i, j] - ri
                if rho < rho0:
                    k = k_rep if moving[j] else ks
                    x = 1.0 / max(rho, closest) - 1.0 / rho0
                    w = k * x * gfac
                    if not moving[j]:  # the companion term's: the static bodies' potentials
                        pot_sum += 0.5 * k * (x * x) * rho0
                    nx, ny, nz = grad[i, j, 0], grad[i, j, 1], grad[i, j, 2]
                    fx += w * nx
                    fy += w * ny
                    fz += w * nz
                    block = ax * nx + ay * ny + az * nz
                    if not moving[j]:
                        hold += w * block
                    if block < 0.0 and turn > 0.0 and not moving[j]:
                        # The way on lies behind a static body: the part of the push that
                        # opposes the pull turns along its surface, the way the pull leans
                        # along it, or when the pull is nearly square to it (under a fifth)
                        # towards its nearer side (horizontally: from its centre), right-hand
                        # when dead centre.
                        sx, sy, sz = ax - block * nx, ay - block * ny, az - block * nz
                        if sx * sx + sy * sy + sz * sz < 0.04:
                            cx, cy = px - o_center[j, 0], py - o_center[j, 1]
                            d = cx * nx + cy * ny
                            sx, sy, sz = cx - d * nx, cy - d * ny, -d * nz
                            if sx * sx + sy * sy + sz * sz < 1e-12 * (1.0 + cx * cx + cy * cy):
                                sx, sy, sz = _right(-nx, -ny, -nz)
                        sx, sy, sz = _unit(sx, sy, sz)
                        wt = w * block * turn
                        bx -= wt * sx
                        by -= wt * sy
                        bz -= wt * sz
            # The companion term (of the static bodies: a mover's push is a threat's, not a
            # surface's beside the goal) pulls along the agent's way, towards its point of
            # attraction (the goal itself, or the waypoint or the guide's point on the way round
            # a body between it and the goal: pulled straight at a goal behind a body, it pinned
            # the agent to that body's surface).
            c = pot_sum * gfac_d
            fx, fy, fz = fx + c * ax, fy + c * ay, fz + c * az
            if any_moving:
                # Predicted closest approach to each mover, right-hand bias on collision course,
                # with the goal factor (a goal beside a mover's way stays reachable; once there,
                # the arrived agent's evasion keeps it out of the mover's way): the agent flies
                # on at its speed towards its point of attraction (its way, not its last step:
                # a prediction from its own velocity reversed the push each step it reversed
                # the agent, which then hovered in place).
                vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
                speed = math.sqrt(vx * vx + vy * vy + vz * vz)
                vx, vy, vz = speed * ax, speed * ay, speed * az
                for j in range(m):
                    if not moving[j] or not math.isfinite(dist[i, j]):  # inf: a mover it does not see
                        continue
                    # From the centre of a ball of the mover's bounding radius that touches it at
                    # its surface point nearest the agent from behind, carried at its velocity:
                    # the push starts from the true clearance, along the surface's normal (a
                    # bounding sphere about a tall pole's middle pushed an agent flying by its
                    # foot down into the ground), and the ball is as large as the body.
                    core = dist[i, j] + o_radius[j]
                    dpx, dpy, dpz = grad[i, j, 0] * core, grad[i, j, 1] * core, grad[i, j, 2] * core
                    # A mover farther than the influence, both radii and both motions over the
                    # horizon (plus a metre against rounding) cannot come within the influence
                    # (its term is zero): dismissed before the divisions.
                    far = rho0 + o_radius[j] + ri + horizon * (speed + m_speed[j]) + 1.0
                    if dpx * dpx + dpy * dpy + dpz * dpz > far * far * (1.0 + 1e-9):
                        continue
                    dvx, dvy, dvz = vx - o_vel[j, 0], vy - o_vel[j, 1], vz - o_vel[j, 2]
                    a = dvx * dvx + dvy * dvy + dvz * dvz
                    tau = min(max(-(dpx * dvx + dpy * dvy + dpz * dvz) / max(a, _EPS), 0.0), horizon)
                    if tau <= 0.0:
                        continue
                    spx, spy, spz = dpx + tau * dvx, dpy + tau * dvy, dpz + tau * dvz
                    d = math.sqrt(spx * spx + spy * spy + spz * spz)
                    # The goal factor only for a mover whose way keeps off the goal by the
                    # agent's body and one more (an agent waiting there is safe): one bound
                    # through the goal keeps the agent off it at full strength.
                    gqx, gqy, gqz = goal[i, 0] - (px - dpx), goal[i, 1] - (py - dpy), goal[i, 2] - (pz - dpz)
                    ox, oy, oz = o_vel[j, 0], o_vel[j, 1], o_vel[j, 2]
                    tg = min(
                        max((gqx * ox + gqy * oy + gqz * oz) / max(ox * ox + oy * oy + oz * oz, _EPS), 0.0),
                        horizon,
                    )
                    gqx, gqy, gqz = gqx - tg * ox, gqy - tg * oy, gqz - tg * oz
                    clear = math.sqrt(gqx * gqx + gqy * gqy + gqz * gqz) >= o_radius[j] + 2.0 * ri
                    fade = gfac if clear else 1.0
                    soon = 1.0 - tau / (horizon + _EPS)
                    mag = _rep(d - o_radius[j] - ri, rho0, k_mv, closest) * soon * fade
                    if mag == 0.0:
                        continue
                    rx, ry, rz = _unit(dvy, -dvx, 0.0)
                    need = o_radius[j] + ri
                    stops = can_stop[idx[i]]  # a fixed wing's way round is the turn-ahead guard's
                    qx, qy, qz = _unit(spx, spy, spz)
                    wx, wy, wz = _unit(qx + 0.3 * rx, qy + 0.3 * ry, qz + 0.3 * rz)
                    wh = math.sqrt(wx * wx + wy * wy)
                    if d < 0.25 * (o_radius[j] + ri + 1.0) or (
                        # on a collision course with the side away from it hemmed in: as head-on
                        stops
                        and d < need
                        and wh > 0.0
                        and _hemmed(wx / wh, wy / wh, pos[i], ri, need - d, dist[i], grad[i], moving, lo, hi)
                    ):
                        # Head-on: out of the mover's way to the right, or where a static
                        # surface hems that side in (within the mover's radius and the agent's
                        # own) a multirotor goes to the left, or over both (pressed to a body's
                        # edge by a mover on its right, one was pinned there until struck; and
                        # pushed at a pole, then to the right, one reversed each step until struck).
                        wx, wy, wz = rx, ry, rz
                        if stops and _hemmed(rx, ry, pos[i], ri, need, dist[i], grad[i], moving, lo, hi):
                            if _hemmed(-rx, -ry, pos[i], ri, need, dist[i], grad[i], moving, lo, hi):
                                wx, wy, wz = 0.0, 0.0, 1.0
                            else:
                                wx, wy, wz = -rx, -ry, -rz
                    fx += mag * wx
                    fy += mag * wy
                    fz += mag * wz

        # Terrain / ground, with the goal factor (a goal near the ground stays reachable),
        # scaled as the static bodies (a guided agent's way already keeps off every static
        # surface: the ground and the flight volume's faces as the bodies).
        kg = k_rep * static_scale[i]
        nx, ny, nz = _unit(-gh[i, 0], -gh[i, 1], 1.0)
        rho_g = (pz - h[i]) - ri
        mag = kg * (1.0 / max(rho_g, closest) - 1.0 / rho0_g) if rho_g < rho0_g else 0.0
        mag = mag * gfac
        fx, fy, fz = fx + mag * nx, fy + mag * ny, fz + mag * nz

        # Faces of the flight volume (the floor is the ground's).
        fx += _face(px - lo[0], 1.0, ri, rb0, kg, gfac, closest)
        fx += _face(px - hi[0], -1.0, ri, rb0, kg, gfac, closest)
        fy += _face(py - lo[1], 1.0, ri, rb0, kg, gfac, closest)
        fy += _face(py - hi[1], -1.0, ri, rb0, kg, gfac, closest)
        fz += _face(pz - hi[2], -1.0, ri, rb0, kg, gfac, closest)

        # Other agents: ellipsoidal separation, current and predicted, out to the pair's
        # stopping reach beyond the ellipsoid (at most the influence distance).
        if n_all >= 2:
            ia = idx[i]
            yields_self = yields[view[i, ia]] if viewed else yields[ia]
            vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
            k = 0
            half = (reach + horizon * (math.sqrt(vx * vx + vy * vy + vz * vz) + v_all) + 1.0) * (1.0 + 1e-6)
            if window and math.isfinite(half) and math.isfinite(px):
                w_lo = search_left(XS, px - half)
                w_hi = search_right(XS, px + half)
                w = w_hi - w_lo
                sl = slice(w_lo, w_hi)
                _near((px, py, pz), (vx, vy, vz), (XS[sl], YS[sl], ZS[sl]), (VXS[sl], VYS[sl], VZS[sl]),
                      horizon, R[sl], near)  # fmt: skip
                for c in range(w):
                    if near[c]:
                        rows[k] = order[w_lo + c]
                        k += 1
                _index_order(rows, k, seen)  # the full scan's order of the sums
            else:
                if viewed:  # this flyer's beliefs of the others (an unknown one: where it is itself)
                    # The coordinates whose row differs from the last flyer's, found without a
                    # branch (written at ``changes`` whatever they are, kept by moving it on),
                    # then changed.
                    own_row = view[i, ia]
                    changes = 0
                    for b in range(n_all):
                        rb = view[i, b]
                        rb = rb if rb >= 0 else own_row
                        wanted[b] = rb
                        changed[changes] = b
                        changes += rb != held[b]
                    for c in range(changes):
                        b = changed[c]
                        rb = wanted[b]
                        held[b] = rb
                        X[b], Y[b], Z[b] = all_pos[rb, 0], all_pos[rb, 1], all_pos[rb, 2]
                        VX[b], VY[b], VZ[b] = all_vel[rb, 0], all_vel[rb, 1], all_vel[rb, 2]
                        R[b] = reach + doubt[rb]
                    _near((px, py, pz), (vx, vy, vz), (X, Y, Z), (VX, VY, VZ), horizon, R, near)
                    for b in range(n_all):  # (no branch: written whatever it is, kept by moving k on)
                        rows[k] = b
                        k += near[b]
                else:
                    _near((px, py, pz), (vx, vy, vz), (X, Y, Z), (VX, VY, VZ), horizon, R, near)
                    for b in range(n_all):
                        if near[b]:
                            rows[k] = b
                            k += 1
            for c in range(k):
                b = rows[c]
                rb = view[i, b] if viewed else b
                if b == ia or rb < 0:
                    continue
                dpx, dpy, dpz = px - all_pos[rb, 0], py - all_pos[rb, 1], pz - all_pos[rb, 2]
                dwx, dwy, dwz = vx - all_vel[rb, 0], vy - all_vel[rb, 1], vz - all_vel[rb, 2]
                rr = radius[ia] + radius[b]
                if viewed:  # where the other may be, beyond where it is believed
                    rr = rr + doubt[rb]
                cx = max(separation[ia, 0], separation[b, 0]) + rr
                cy = max(separation[ia, 1], separation[b, 1]) + rr
                cz = max(separation[ia, 2], separation[b, 2]) + rr
                qx, qy, qz = dpx / cx, dpy / cy, dpz / cz
                e = math.sqrt(qx * qx + qy * qy + qz * qz)
                # Each agent of the pair needs its braking distance from its *current* speed
                # (a step of reaction, then a stop) to be out of the other's way: two agents
                # that can stop reach the sum of the two, at most the sum from cruise speed; a
                # parked agent is at rest, only the flyer's braking counts. A fixed wing (it
                # cannot stop) keeps the full range from cruise speed.
                pair_reach = stop_reach[ia] + stop_reach[b]
                if parked[rb] and can_stop[ia]:
                    pair_reach = reach_now[i]
                elif can_stop[ia] and can_stop[b]:
                    pair_reach = min(pair_reach, reach_now[i] + reach_all[rb])
                e0 = 1.0 + min(pair_reach, rho0) / max(cx, cy, cz)
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
                # Less room under the agent than the pair's vertical semi-axis: the other's
                # push drives it aside, not down (pressed to the ground under another it stayed
                # there, the two held for good), and its way past goes over or beside, not under.
                low = rho_g < cz
                if low and gz < 0.0:
                    gx, gy, gz = _unit(gx, gy, 0.0)
                mag = k_agent * (1.0 / max(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)) if current else 0.0
                soon = 1.0 - tau / (horizon + _EPS)
                urgency = soon * soon  # field_law.urgency
                mag_p = k_agent * (1.0 / max(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)) if predicted else 0.0
                mag_p = mag_p * urgency
                # Priority: a parked agent, or one farther from its goal, repels as a static
                # body does (with the goal factor): near its goal an agent that can stop goes
                # on through the crowd and the others give way; an agent that yields (a fixed
                # wing loitering about its goal) gives way to every flyer that does not.
                if (can_stop[ia] and (parked[rb] or dg <= goal_dist[rb])) or (yields[rb] and not yields_self):
                    mag = mag * gfac
                    mag_p = mag_p * gfac
                wx, wy, wz = _unit(sx * cx, sy * cy, sz * cz)
                rx, ry, rz = _right(dwx, dwy, dwz)
                uz = _over(dwx, dwy, dwz)
                wz = wz + 0.5 * (rz + uz)
                if low and wz < 0.0:
                    wz = 0.0
                wx, wy, wz = _unit(wx + 0.5 * rx, wy + 0.5 * ry, wz)
                fx += mag * gx + mag_p * wx
                fy += mag * gy + mag_p * wy
                fz += mag * gz + mag_p * wz
        # The turn along blocking bodies only where they hold the agent: the pull and their
        # push together make less than a quarter of the pull's way towards the goal (a wall
        # square across the way, a pillar dead ahead), not while it flies on past a body's edge.
        if bx != 0.0 or by != 0.0 or bz != 0.0:
            pull = k_att * min(dt, dq)
            if pull + hold < 0.25 * pull:
                fx, fy, fz = fx + bx, fy + by, fz + bz
        out[i, 0] = fx
        out[i, 1] = fy
        out[i, 2] = fz


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _maximum(a, b):  # noqa: ANN001, ANN202
    """``np.maximum`` of two values (NaN wins; of two equal values, the second)."""
    return a if a > b or a != a else b


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _minimum(a, b):  # noqa: ANN001, ANN202
    """``np.minimum`` of two values (NaN wins; of two equal values, the second)."""
    return a if a < b or a != a else b


@njit(cache=True, nogil=True, error_model="numpy")
def commanded_velocity(amax, cruise, floor, standoff, force, pos, goal, clearance, normal, dt, out):  # noqa: ANN001, ANN201
    """``apf.commanded_velocity_numpy`` row by row into ``out`` (its operations in its order;
    ``floor`` the agents' slowest commands, ``standoff`` their safety margins, ``dt`` the step)."""
    for i in range(force.shape[0]):
        a = amax[i]
        gx, gy, gz = goal[i, 0] - pos[i, 0], goal[i, 1] - pos[i, 1], goal[i, 2] - pos[i, 2]
        dg = math.sqrt(gx * gx + gy * gy + gz * gz)
        speed = _maximum(_minimum(cruise[i], math.sqrt(2.0 * 0.8 * a * dg)), floor[i])
        fx, fy, fz = force[i, 0], force[i, 1], force[i, 2]
        f = _maximum(math.sqrt(fx * fx + fy * fy + fz * fz), _EPS)
        vx, vy, vz = fx / f * speed, fy / f * speed, fz / f * speed
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        toward = -(vx * nx + vy * ny + vz * nz)
        gap = _maximum(clearance[i] - standoff[i], 0.0)
        allowed = math.sqrt(2.0 * 0.8 * a * gap)
        if floor[i] == 0.0 and gap < speed * dt:  # within a step of it: a stop along the command fits
            tx, ty, tz = vx + toward * nx, vy + toward * ny, vz + toward * nz
            c = math.sqrt(tx * tx + ty * ty + tz * tz) / (2.0 * a) + dt
            stop = 2.0 * gap / (math.sqrt(c * c + 2.0 * gap / a) + c)
            allowed = _minimum(allowed, _maximum(stop, allowed * (gap / (speed * dt))))
        if dg < clearance[i]:  # a goal nearer than the surface: its own cap stops the agent short of it
            allowed = _maximum(allowed, speed)
        excess = _maximum(toward - allowed, 0.0)
        out[i, 0] = vx + excess * nx
        out[i, 1] = vy + excess * ny
        out[i, 2] = vz + excess * nz
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def reach_at_speed(vel, idx, denominator, dt, out):  # noqa: ANN001, ANN201
    """``apf.ApfField._reach_at_speed`` of multirotors (``denominator``: every agent's
    ``2 max(max_accel, eps)``; ``idx`` the rows of ``vel``'s agents, or empty for the first
    ``len(vel)`` agents in order): ``v dt + v^2 / denominator`` into ``out``."""
    for i in range(vel.shape[0]):
        x, y, z = vel[i, 0], vel[i, 1], vel[i, 2]
        v = math.sqrt(x * x + y * y + z * z)
        k = idx[i] if len(idx) else i
        out[i] = v * dt + v * v / denominator[k]
    return out
