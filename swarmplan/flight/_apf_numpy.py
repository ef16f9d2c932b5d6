"""The potential field of ``swarmplan.flight.apf`` in numpy, for the first calls of a world
below swarm size (``swarmplan.runtime.compiled.field_numpy_calls``): :func:`apf_forces` takes
the arguments of ``swarmplan.flight._apf_kernel.apf_forces`` and writes the same bits.

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

from swarmplan.flight.field_law import (
    bounds_range,
    goal_factor,
    ground_range,
    nearest,
    power,
    repulsion,
    urgency,
)

_EPS = 1e-9  # apf._EPS
_SKIP = -0.0  # x + (-0.0) == x for every double x, -0.0 included
_UP = np.array([0.0, 0.0, 1.0])


def _sq(v: np.ndarray) -> np.ndarray:
    """``x*x + y*y + z*z`` over the last axis, in the kernel's order."""
    return v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.sqrt(_sq(v)), _EPS)[..., None]


def _vec(x: np.ndarray, y: np.ndarray, z: np.ndarray | float) -> np.ndarray:
    v = np.empty((*x.shape, 3))
    v[..., 0], v[..., 1], v[..., 2] = x, y, z
    return v


def _across(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The kernel's ``_unit(y, -x, 0.0)`` (its norm's sum ``y*y + x*x + 0.0`` is ``x*x + y*y``)."""
    n = np.maximum(np.sqrt(x * x + y * y), _EPS)
    return _vec(y / n, -x / n, 0.0)


def _right(v: np.ndarray) -> np.ndarray:
    """The kernel's ``_right`` of each vector of ``v`` (..., 3): ``_unit(y, -x, 0.0)`` or
    ``_unit(0.0, z, -y)``, whose norms' sums drop their exact ``+ 0.0``."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    h2 = x * x + y * y
    side = h2 >= 0.04 * (h2 + z * z)
    n1 = np.maximum(np.sqrt(h2), _EPS)
    n2 = np.maximum(np.sqrt(z * z + y * y), _EPS)
    return _vec(np.where(side, y / n1, 0.0), np.where(side, -x / n1, z / n2), np.where(side, 0.0, -y / n2))


def _sum_in_order(first: np.ndarray, terms: np.ndarray) -> np.ndarray:
    """``first + terms[:, 0] + terms[:, 1] + ...`` added left to right (first (n, k), terms
    (n, j, k))."""
    if terms.shape[1] == 0:
        return first
    return np.add.accumulate(np.concatenate([first[:, None], terms], axis=1), axis=1)[:, -1]


def _faces(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray, r: np.ndarray, rb0: np.ndarray, k_rep: np.ndarray,
           gfac: np.ndarray) -> np.ndarray:  # fmt: skip
    """The kernel's ``_face`` terms, (n, 2, 3): row 0 the low faces (x, y; the floor is the
    ground's, a ``-0.0``), row 1 the high ones."""
    sign = np.array([[1.0], [-1.0]])
    offset = np.stack([pos - lo, pos - hi], axis=1)
    rho_b = sign * offset - r[:, None, None]
    mag = repulsion(rho_b, k_rep, rb0, nearest(r)[:, None, None])
    terms = sign * mag * gfac[:, None, None]
    terms[:, 0, 2] = _SKIP
    return terms


def apf_forces(flyers, agents, bodies, ground, swarm, reach, gains, out, window=False) -> None:  # noqa: ANN001, ARG001
    """``out[i]``: the force of ``apf.ApfField.forces`` on agent ``idx[i]``; the arguments of
    ``_apf_kernel.apf_forces`` (``window``, a way of the kernel to skip pair tests without
    changing the forces, changes nothing here: every pair is tested)."""
    pos, vel, goal, target, static_scale, idx, reach_now, length = flyers
    radius, separation, min_altitude, stop_reach, can_stop = agents
    h, gh, h_goal, terrain_floor, lo, hi = ground
    k_att, k_rep_w, rho0_w, k_agent_w, dq_w, npow, k_moving, horizon = gains
    n = pos.shape[0]
    if n == 0:
        return
    # Each agent's own field: the world's scaled (the kernel's per-flyer values, one per row).
    rho0, k_rep, dq, k_agent = length * rho0_w, k_rep_w * (length * length), length * dq_w, length * k_agent_w
    floor = np.maximum(min_altitude[idx], terrain_floor)
    rb0 = bounds_range(rho0, can_stop[idx])
    ri = radius[idx]
    rho0_g = ground_range(rho0, floor, goal[:, 2] - h_goal, ri, can_stop[idx])

    # Attraction (quadratic well only at the goal itself).
    e = goal - pos
    dg = np.sqrt(_sq(e))
    t = target - pos
    dt = np.sqrt(_sq(t))
    to_goal = (np.abs(target - goal) <= 1e-9).all(axis=1)
    well = (dt <= dq) & to_goal
    f = np.where(well[:, None], k_att * t, k_att * (dq[:, None] * t / np.maximum(dt, _EPS)[:, None]))
    ratio = np.minimum(1.0, dg / rho0)
    gfac = goal_factor(dg, rho0, npow)
    gfac_d = np.where(dg < rho0, npow * power(ratio, npow - 1.0) / rho0, 0.0)

    # Obstacle surfaces (static ones scaled per agent), the goal factor's companion term, the
    # turn along blocking bodies and the movers' predicted closest approach.
    turn = hold = None
    if bodies[0].shape[1]:
        f, turn, hold = _bodies(
            (pos, vel, goal, ri, t, dg, to_goal, gfac, gfac_d, f),
            bodies,
            (k_rep, rho0, k_rep * k_moving, horizon),
            static_scale,
            (lo, hi),
            can_stop[idx],
        )

    # Terrain / ground, with the goal factor (a goal near the ground stays reachable), scaled
    # as the static bodies; so are the faces.
    kg = k_rep * static_scale
    normal = _unit(_vec(-gh[:, 0], -gh[:, 1], np.ones(n)))
    rho_g = (pos[:, 2] - h) - ri
    mag = repulsion(rho_g, kg, rho0_g, nearest(ri))
    mag = mag * gfac
    f = f + mag[:, None] * normal

    # Faces of the flight volume (the floor is the ground's).
    faces = _faces(pos, lo, hi, ri, rb0[:, None, None], kg[:, None, None], gfac)
    f = f + faces[:, 0] + faces[:, 1]  # per axis: the low face, then the high one

    # Other agents.
    view = swarm[5]
    if (view.shape[1] if view.shape[0] else swarm[0].shape[0]) >= 2:
        terms = _agent_terms(
            (pos, vel, idx, reach_now, dg, gfac, rho_g),
            (radius, separation, stop_reach, can_stop),
            swarm,
            (reach, rho0, k_agent, horizon),
        )
        f = _sum_in_order(f, terms)
    # The turn along blocking bodies only where they hold the agent.
    if turn is not None:
        pull = k_att * np.minimum(dt, dq)
        turned = (turn != 0.0).any(axis=1) & (pull + hold < 0.25 * pull)
        f = np.where(turned[:, None], f + turn, f)
    out[:] = f


def _hemmed(u, pos, ri, need, dist, grad, moving, bounds):  # noqa: ANN001, ANN202
    """The kernel's ``_hemmed`` for every side ``u`` (n, k, 3) of every flyer (``need`` (n, k)),
    (n, k): a static body within ``need`` whose normal turns more than half against the side,
    or a face of the flight volume (``bounds``: lo, hi) across it."""
    lo, hi = bounds
    ux, uy = u[..., 0], u[..., 1]
    static = ~moving[None, None, :]
    near = (dist - ri[:, None])[:, None, :] < need[..., None]
    facing = grad[:, None, :, 0] * ux[..., None] + grad[:, None, :, 1] * uy[..., None] < -0.5
    body = (static & near & facing).any(axis=2)
    px, py, r = pos[:, 0, None], pos[:, 1, None], ri[:, None]
    face = (
        ((ux < -0.5) & (px - lo[0] - r < need))
        | ((ux > 0.5) & (hi[0] - px - r < need))
        | ((uy < -0.5) & (py - lo[1] - r < need))
        | ((uy > 0.5) & (hi[1] - py - r < need))
    )
    return body | face


def _bodies(a, bodies, g, static_scale, bounds, can_stop):  # noqa: ANN001, ANN202
    """The kernel's obstacle part (``if m:``) for every flyer: the forces, the turn along
    blocking bodies and their hold."""
    pos, vel, goal, ri, t, dg, to_goal, gfac, gfac_d, f = a
    dist, grad, moving, o_center, o_vel, o_radius = bodies
    k_rep, rho0, k_mv, horizon = g
    n, m = dist.shape
    ax = _unit(t)[:, None, :]
    turn = np.where(to_goal, np.minimum(1.0, np.maximum(0.0, dg / rho0 - 1.0)), 0.0)
    rho = dist - ri[:, None]
    active = rho < rho0[:, None]
    static = active & ~moving
    k = np.where(moving, k_rep[:, None], (k_rep * static_scale)[:, None])
    # the law's terms (field_law.repulsion)
    x = 1.0 / np.maximum(rho, nearest(ri)[:, None]) - 1.0 / rho0[:, None]
    w = k * x * gfac[:, None]
    block = _dot(ax, grad)
    terms = np.empty((n, m, 5))
    terms[..., :3] = np.where(active[..., None], w[..., None] * grad, _SKIP)
    terms[..., 3] = np.where(static, 0.5 * k * (x * x) * rho0[:, None], _SKIP)
    terms[..., 4] = np.where(static, w * block, _SKIP)
    sums = _sum_in_order(np.concatenate([f, np.zeros((n, 2))], axis=1), terms)
    f, pot_sum, hold = sums[:, :3], sums[:, 3], sums[:, 4]
    turning = static & (block < 0.0) & (turn[:, None] > 0.0)
    bend = np.zeros((n, 3))
    if turning.any():
        s = ax - block[..., None] * grad
        square = _sq(s) < 0.04
        cx, cy = pos[:, None, 0] - o_center[:, 0], pos[:, None, 1] - o_center[:, 1]
        nx, ny, nz = grad[..., 0], grad[..., 1], grad[..., 2]
        d = cx * nx + cy * ny
        q = _vec(cx - d * nx, cy - d * ny, -d * nz)
        centre = _sq(q) < 1e-12 * (1.0 + cx * cx + cy * cy)
        q = np.where(centre[..., None], _right(-grad), q)
        s = _unit(np.where(square[..., None], q, s))
        wt = w * block * turn[:, None]
        bend = _sum_in_order(bend, np.where(turning[..., None], -(wt[..., None] * s), _SKIP))
    f = f + (pot_sum * gfac_d)[:, None] * ax[:, 0, :]  # along the way (the kernel's comment)
    mv = np.flatnonzero(moving)
    if len(mv):
        # Predicted closest approach to each mover, right-hand bias on collision course.
        core = np.where(np.isfinite(dist[:, mv]), dist[:, mv], 0.0) + o_radius[mv]
        dp = grad[:, mv] * core[..., None]  # from the ball touching the mover (the kernel's comment)
        own = np.sqrt(_sq(vel))[:, None, None] * ax  # its speed towards its point of attraction
        dv = own - o_vel[mv]
        tau = np.minimum(np.maximum(-_dot(dp, dv) / np.maximum(_sq(dv), _EPS), 0.0), horizon)
        sp = dp + tau[..., None] * dv
        d = np.sqrt(_sq(sp))
        r_o = o_radius[mv]
        rho_m = d - r_o - ri[:, None]
        rep = repulsion(rho_m, k_mv[:, None], rho0[:, None], nearest(ri)[:, None])
        # The goal factor for movers whose way keeps off the goal.
        gq = goal[:, None, :] - (pos[:, None, :] - dp)
        u = o_vel[mv]
        tg = np.minimum(np.maximum(_dot(gq, u) / np.maximum(_sq(u), _EPS), 0.0), horizon)
        gq = gq - tg[..., None] * u
        clear = np.sqrt(_sq(gq)) >= r_o + 2.0 * ri[:, None]
        fade = np.where(clear, gfac[:, None], 1.0)
        mag = rep * (1.0 - tau / (horizon + _EPS)) * fade
        right = _across(dv[..., 0], dv[..., 1])
        way = _unit(_unit(sp) + 0.3 * right)
        # Head-on: to the right, or to the left where a static surface hems the right in, or
        # over both (the kernel's comment).
        need = r_o + ri[:, None]
        stops = can_stop[:, None]  # multirotors (a fixed wing's way round is the turn-ahead guard's)
        right_hemmed = stops & _hemmed(right, pos, ri, need, dist, grad, moving, bounds)
        left_hemmed = _hemmed(-right, pos, ri, need, dist, grad, moving, bounds)
        side = np.where(right_hemmed[..., None], np.where(left_hemmed[..., None], _UP, -right), right)
        # ... and on a collision course with the way away from the mover's path hemmed in
        h = np.sqrt(way[..., 0] * way[..., 0] + way[..., 1] * way[..., 1])
        h_safe = np.where(h > 0.0, h, 1.0)
        across = _vec(way[..., 0] / h_safe, way[..., 1] / h_safe, 0.0)
        hemmed_away = _hemmed(across, pos, ri, need - d, dist, grad, moving, bounds)
        pinned = stops & (d < need) & (h > 0.0) & hemmed_away
        way = np.where(((d < 0.25 * (r_o + ri[:, None] + 1.0)) | pinned)[..., None], side, way)
        live = (tau > 0.0) & (mag != 0.0) & np.isfinite(dist[:, mv])  # inf: a mover it does not see
        f = _sum_in_order(f, np.where(live[..., None], mag[..., None] * way, _SKIP))
    return f, bend, hold


def _agent_terms(fl, agents, swarm, g):  # noqa: ANN001, ANN202
    """The other agents' terms on every flyer, (n, n_all, 3) in the kernel's order of agents,
    ``-0.0`` where the kernel adds nothing."""
    pos, vel, idx, reach_now, dg, gfac, rho_g = fl
    radius, separation, stop_reach, can_stop = agents
    all_pos, all_vel, parked, goal_dist, reach_all, view, doubt, yields = swarm
    reach, rho0, k_agent, horizon = g
    n = len(pos)
    viewed = view.shape[0] > 0
    if viewed:  # each flyer's own rows (an unknown agent: its own row, and not tested)
        known = view >= 0
        rows_of = np.where(known, view, view[np.arange(n), idx][:, None])
        all_pos, all_vel = all_pos[rows_of], all_vel[rows_of]
        parked, goal_dist, reach_all = parked[rows_of], goal_dist[rows_of], reach_all[rows_of]
        yields = yields[rows_of]
        doubt = doubt[rows_of]
    else:  # every flyer's row b is agent b
        known = np.ones((n, len(all_pos)), dtype=bool)
        shared = (parked, goal_dist, reach_all, yields)
        parked, goal_dist, reach_all, yields = (np.broadcast_to(a, (n, len(a))) for a in shared)
    n_all = known.shape[1]
    dp = pos[:, None, :] - all_pos
    dw = vel[:, None, :] - all_vel
    # The kernel's _near: pairs whose closest approach within the horizon may lie inside reach
    # (widened by the doubt of the row held).
    r2 = (reach + doubt) ** 2 if viewed else reach * reach
    dd, bb, a = _sq(dp), _dot(dp, dw), _sq(dw)
    ee = _sq(dp + horizon * dw)
    far = (dd >= r2) & (
        (bb >= 0.0)
        | ((-bb >= a * horizon) & (ee >= r2 * (1.0 + 1e-9)))
        | ((-bb < a * horizon) & (dd * a - bb * bb >= r2 * a + 1e-9 * dd * a))
    )
    far[np.arange(n), idx] = True  # an agent and itself
    far |= ~known
    rows, b = np.nonzero(~far)
    terms = np.full((n, n_all, 3), _SKIP)
    if len(rows) == 0:
        return terms
    ia = idx[rows]
    dp, dw = dp[rows, b], dw[rows, b]
    rr = radius[ia] + radius[b]
    if viewed:  # where the other may be, beyond where it is believed
        rr = rr + doubt[rows, b]
    c = np.maximum(separation[ia], separation[b]) + rr[:, None]
    q = dp / c
    e = np.sqrt(_sq(q))
    stop_a, stop_b = can_stop[ia], can_stop[b]
    pair_reach = stop_reach[ia] + stop_reach[b]
    pair_reach = np.where(
        parked[rows, b] & stop_a,
        reach_now[rows],
        np.where(stop_a & stop_b, np.minimum(pair_reach, reach_now[rows] + reach_all[rows, b]), pair_reach),
    )
    e0 = 1.0 + np.minimum(pair_reach, rho0[rows]) / np.maximum(np.maximum(c[:, 0], c[:, 1]), c[:, 2])
    dv = dw / c
    tau = np.minimum(np.maximum(-_dot(q, dv) / np.maximum(_sq(dv), _EPS), 0.0), horizon)
    s = q + tau[:, None] * dv
    es = np.sqrt(_sq(s))
    current = e < e0
    predicted = (es < e0) & (tau > 0)
    mag = np.where(current, k_agent[rows] * (1.0 / np.maximum(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    mag_p = np.where(predicted, k_agent[rows] * (1.0 / np.maximum(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    mag_p = mag_p * urgency(tau, horizon)
    # Priority: a parked agent, or one farther from its goal, repels with the goal factor; so
    # does an agent that yields, for every flyer that does not.
    yields_self = yields[np.arange(n), idx]
    factored = stop_a & (parked[rows, b] | (dg[rows] <= goal_dist[rows, b]))
    factored = factored | (yields[rows, b] & ~yields_self[rows])
    mag = np.where(factored, mag * gfac[rows], mag)
    mag_p = np.where(factored, mag_p * gfac[rows], mag_p)
    side = _right(dw)
    side[:, 2] = side[:, 2] + (2.0 * dw[:, 0] + dw[:, 1]) / (
        math.sqrt(5.0) * np.maximum(np.sqrt(_sq(dw)), _EPS)
    )
    # Less room under the agent than the pair's vertical semi-axis: pushed aside, not down, and
    # no way under.
    low = rho_g[rows] < c[:, 2]
    away = _unit(q / c)
    flat = away.copy()
    flat[:, 2] = 0.0
    away = np.where((low & (away[:, 2] < 0.0))[:, None], _unit(flat), away)
    way = _unit(s * c)
    way[:, 2] = way[:, 2] + 0.5 * side[:, 2]
    way[:, 2] = np.where(low & (way[:, 2] < 0.0), 0.0, way[:, 2])
    way[:, :2] = way[:, :2] + 0.5 * side[:, :2]
    way = _unit(way)
    acts = (current | predicted)[:, None]
    terms[rows, b] = np.where(acts, mag[:, None] * away + mag_p[:, None] * way, _SKIP)
    return terms
