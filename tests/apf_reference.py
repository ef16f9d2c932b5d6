"""The potential field of ``swarmplan.flight.apf`` in plain numpy over every pair: the reference
the compiled field (the product's one implementation) is tested against. Same formulas, array
by array; sums in another order, so the two agree to rounding (tests use 1e-9 relative)."""

from __future__ import annotations

import numpy as np

from swarmplan.flight.apf import FieldInputs, Flyers, Swarm, stopping_reach
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.vec3 import dot3, norm3

_EPS = 1e-9


def _unit(v):
    return v / np.maximum(norm3(v, keepdims=True), _EPS)


def _right_of(v):
    """Right of ``v`` (z up) while its horizontal part is at least a fifth of it, else about x."""
    h2 = v[..., 0] ** 2 + v[..., 1] ** 2
    zero = np.zeros(v.shape[:-1])
    horizontal = np.stack([v[..., 1], -v[..., 0], zero], axis=-1)
    about_x = np.stack([zero, v[..., 2], -v[..., 1]], axis=-1)
    return _unit(np.where((h2 >= 0.04 * (h2 + v[..., 2] ** 2))[..., None], horizontal, about_x))


def _rep(rho, rho0, k, near):
    """The push at clearance ``rho`` (it stops growing below ``near``, a tenth of the radius)."""
    return np.where(rho < rho0, k * (1.0 / np.maximum(rho, near) - 1.0 / rho0), 0.0)


def _hemmed(side, pos, r, need, field: FieldInputs, world):
    """Per flyer and side (n, k): a static body within ``need`` (n, k) of the flyer's surface
    whose outward normal turns more than half against the side, or a face of the bounds across it."""
    rho = field.obstacle_distance - r[:, None]  # (n, m)
    facing = np.einsum("nkd,nmd->nkm", side[..., :2], field.obstacle_gradient[..., :2]) < -0.5
    static = ~field.obstacle_moving[None, None, :]
    body = (static & facing & (rho[:, None, :] < need[..., None])).any(axis=2)
    lo, hi = world.bounds_min, world.bounds_max
    face = np.zeros(side.shape[:-1], dtype=bool)
    for axis in range(2):
        u = side[..., axis]
        face |= (u < -0.5) & ((pos[:, axis] - lo[axis] - r)[:, None] < need)
        face |= (u > 0.5) & ((hi[axis] - pos[:, axis] - r)[:, None] < need)
    return body | face


def _own_scale(params: AgentParams, idx: np.ndarray) -> np.ndarray:
    """Each agent's field scale (``kinematics.field_scales``; 1 without)."""
    return np.ones(len(idx)) if params.field_scale is None else params.field_scale[idx]


def reference_forces(
    world, params: AgentParams, flyers: Flyers, field: FieldInputs, swarm: Swarm, gains=None
):
    """The field's force on every flyer, shape (n, 3)."""
    g = world.planner_config.apf if gains is None else gains
    idx, pos, vel, goal = flyers.idx, flyers.pos, flyers.vel, flyers.goal
    target, static_scale = flyers.target, flyers.static_scale
    n = len(idx)
    r = params.radius[idx]
    own = _own_scale(params, idx)  # each agent's field: the world's at its own scale
    rho0 = g.influence * own
    k_rep = g.k_rep * own**2
    e = goal - pos
    dg = norm3(e)
    et = e if target is None else target - pos
    dt_ = norm3(et)
    dq = g.quadratic_radius * own
    well = dt_ <= dq
    if target is not None:
        well &= np.all(np.abs(target - goal) <= 1e-9, axis=1)
    force = g.k_att * np.where(well[:, None], et, dq[:, None] * et / np.maximum(dt_, _EPS)[:, None])
    npow = g.goal_power
    gfac = np.minimum(1.0, dg / rho0) ** npow
    gfac_d = np.where(dg < rho0, npow * np.minimum(1.0, dg / rho0) ** (npow - 1) / rho0, 0.0)

    turn_force = np.zeros_like(force)
    hold = np.zeros(n)
    if field.obstacle_distance.shape[1]:
        rho = field.obstacle_distance - r[:, None]
        scale = np.ones(n) if static_scale is None else static_scale
        k = np.where(field.obstacle_moving[None, :], k_rep[:, None], (k_rep * scale)[:, None])
        r0 = rho0[:, None]
        mag = _rep(rho, r0, k, 0.1 * r[:, None])
        static_pot = ~field.obstacle_moving[None, :] & (rho < r0)  # movers: no companion pull
        x = 1.0 / np.maximum(rho, 0.1 * r[:, None]) - 1.0 / r0
        pot = np.where(static_pot, 0.5 * k * x**2 * r0, 0.0)
        grad = field.obstacle_gradient
        force = force + np.einsum("nk,nkd->nd", mag * gfac[:, None], grad)
        # Blocked by a static body: the opposing part of its push turns along its surface,
        # the way the pull leans along it, or when the pull is nearly square to it towards the
        # body's nearer side horizontally (right-hand when dead centre); only where the static
        # bodies hold the agent (below).
        pull = _unit(et)
        block = np.einsum("nd,nkd->nk", pull, grad)
        c = pos[:, None, :] - field.obstacle_center[None, :, :]
        c[..., 2] = 0.0
        nearer = c - dot3(c, grad)[..., None] * grad
        tiny = dot3(nearer, nearer) < 1e-12 * (1.0 + dot3(c, c))
        nearer = np.where(tiny[..., None], _right_of(-grad), nearer)
        along = pull[:, None, :] - block[..., None] * grad  # the pull's part along the surface
        side = np.where((dot3(along, along) < 0.04)[..., None], nearer, along)
        static = ~field.obstacle_moving[None, :] & (rho < r0)
        hold = np.where(static, mag * gfac[:, None] * block, 0.0).sum(axis=1)
        on = (block < 0) & static
        # fades in from one to two influences off the goal; only on the way to the goal itself
        turn = np.clip(dg / rho0 - 1.0, 0.0, 1.0)
        if target is not None:
            turn = np.where(np.all(np.abs(target - goal) <= 1e-9, axis=1), turn, 0.0)
        w = np.where(on, mag * (gfac * turn)[:, None] * block, 0.0)
        turn_force = -np.einsum("nk,nkd->nd", w, _unit(side))
        force = force + (pot.sum(axis=1) * gfac_d)[:, None] * _unit(et)  # along the way
        mv = field.obstacle_moving
        if mv.any():
            radii = field.obstacle_radius[mv]  # from the ball of this radius touching it at the nearest point
            seen = np.isfinite(field.obstacle_distance[:, mv])
            core = np.where(seen, field.obstacle_distance[:, mv], 0.0) + radii[None, :]
            dp = field.obstacle_gradient[:, mv] * core[..., None]
            own = norm3(vel)[:, None] * _unit(et)  # its speed towards its point of attraction
            dv = own[:, None, :] - field.obstacle_velocity[mv][None]
            a = dot3(dv, dv)
            tau = np.clip(-dot3(dp, dv) / np.maximum(a, _EPS), 0.0, g.horizon)
            sep = dp + tau[..., None] * dv
            dist = norm3(sep)
            rr = dist - radii[None, :] - r[:, None]
            urgency = (1.0 - tau / (g.horizon + _EPS)) * (tau > 0)
            u = field.obstacle_velocity[mv][None]
            gq = goal[:, None, :] - (pos[:, None, :] - dp)
            tg = np.clip(dot3(gq, u) / np.maximum(dot3(u, u), _EPS), 0.0, g.horizon)
            goal_clear = norm3(gq - tg[..., None] * u) >= radii[None, :] + 2.0 * r[:, None]
            m = (
                _rep(rr, r0, (k_rep * g.k_moving)[:, None], 0.1 * r[:, None])
                * urgency
                * np.where(goal_clear, gfac[:, None], 1.0)
            )
            right = _unit(np.stack([dv[..., 1], -dv[..., 0], np.zeros(dv.shape[:-1])], axis=-1))
            head_on = dist < 0.25 * (radii[None, :] + r[:, None] + 1.0)
            # Head-on: right, else left where a static surface hems the right in, else up.
            need = radii[None, :] + r[:, None]
            hem_r = ~params.fixed_wing[idx][:, None] & _hemmed(right, pos, r, need, field, world)
            hem_l = _hemmed(-right, pos, r, need, field, world)
            up = np.array([0.0, 0.0, 1.0])
            side = np.where(hem_r[..., None], np.where(hem_l[..., None], up, -right), right)
            away = _unit(_unit(sep) + 0.3 * right)
            # On a collision course with the side away from the mover's path hemmed in: as head-on.
            level = np.linalg.norm(away[..., :2], axis=-1)
            flat = np.concatenate(
                [away[..., :2] / np.where(level > 0, level, 1.0)[..., None], 0 * away[..., 2:]], -1
            )
            stops = ~params.fixed_wing[idx][:, None]
            pinned = stops & (dist < need) & (level > 0) & _hemmed(flat, pos, r, need - dist, field, world)
            direction = np.where((head_on | pinned)[..., None], side, away)
            force = force + np.einsum("nk,nkd->nd", m, direction)

    h = world.terrain_height(pos[:, :2])
    gh = world.terrain_gradient(pos[:, :2])
    normal = _unit(np.stack([-gh[:, 0], -gh[:, 1], np.ones(n)], axis=1))
    floor = np.maximum(params.min_altitude[idx], world.terrain_clearance if world.peaks else 0.0)
    rho_g = (pos[:, 2] - h) - r
    # The clearance at the floor lowered to the goal's height, at least the radius
    # (multirotors); the influence down to three floors, at least a quarter of it (fixed wings).
    low = np.minimum(floor, goal[:, 2] - world.terrain_height(goal[:, :2]))
    fly = np.maximum(np.minimum(rho0, 3.0 * floor), 0.25 * rho0)
    rho0_g = np.where(params.fixed_wing[idx], fly, np.maximum(low - r, r))
    static = np.ones(n) if flyers.static_scale is None else flyers.static_scale  # the ground's, faces' too
    mag_g = _rep(rho_g, rho0_g, k_rep * static, 0.1 * r)
    force = force + (mag_g * gfac)[:, None] * normal

    lo, hi = world.bounds_min, world.bounds_max
    rb0 = np.where(~params.fixed_wing[idx], 0.25 * rho0, np.minimum(rho0, 10.0))  # multirotors, fixed wings
    for axis in range(3):
        for sign, plane in ((1.0, lo[axis]), (-1.0, hi[axis])):
            if axis == 2 and sign > 0:
                continue
            rho_b = sign * (pos[:, axis] - plane) - r
            force[:, axis] += sign * _rep(rho_b, rb0, k_rep * static, 0.1 * r) * gfac
    force = force + agent_term(world, params, g, flyers, swarm, gfac)
    # The turn only where the static bodies hold the agent (the pull and their push along it
    # under a quarter of the pull).
    pull_size = g.k_att * np.minimum(dt_, dq)
    held = pull_size + hold < 0.25 * pull_size
    return force + np.where(held[:, None], turn_force, 0.0)


def agent_term(world, params: AgentParams, g, flyers: Flyers, swarm: Swarm, gfac=None):
    """The other agents' repulsion on every flyer (every pair, no index)."""
    idx, pos, vel = flyers.idx, flyers.pos, flyers.vel
    all_pos, all_vel = swarm.pos, swarm.vel
    n_all = len(all_pos)
    if gfac is None:
        gfac = np.ones(len(idx))
    if n_all < 2:
        return np.zeros_like(pos)
    reach = stopping_reach(params, world.dt)
    others = np.ones((len(idx), n_all), dtype=bool)
    others[np.arange(len(idx)), idx] = False
    sep = np.maximum(params.separation[idx][:, None, :], params.separation[None, :, :])
    rr = params.radius[idx][:, None] + params.radius[None, :]
    scale = sep + rr[..., None]
    dp = pos[:, None, :] - all_pos[None, :, :]
    q = dp / scale
    e = norm3(q)
    grad = _unit(q / scale)
    # Less room under the agent than the pair's vertical semi-axis: pushed aside, not down, and
    # no way under.
    clear = pos[:, 2] - world.terrain_height(pos[:, :2]) - params.radius[idx]
    low = clear[:, None] < scale[..., 2]
    flat = grad.copy()
    flat[..., 2] = 0.0
    grad = np.where((low & (grad[..., 2] < 0.0))[..., None], _unit(flat), grad)
    parked = np.zeros(n_all, dtype=bool) if swarm.parked is None else swarm.parked
    # A parked agent is at rest: the pair's reach is the flyer's braking from its speed.
    speed = norm3(vel)
    now = speed * world.dt + speed * speed / (2.0 * np.maximum(params.max_accel[idx], _EPS))
    stops = parked[None, :] & ~params.fixed_wing[idx][:, None]
    pair = reach[idx][:, None] + reach[None, :]
    # Two multirotors: each one's braking from its current speed (at most the cruise sum).
    other = norm3(all_vel)
    now_b = other * world.dt + other * other / (2.0 * np.maximum(params.max_accel, _EPS))
    both = ~params.fixed_wing[idx][:, None] & ~params.fixed_wing[None, :]
    pair = np.where(both, np.minimum(pair, now[:, None] + now_b[None, :]), pair)
    pair = np.where(stops, now[:, None], pair)
    own = _own_scale(params, idx)[:, None]
    e0 = 1.0 + np.minimum(pair, g.influence * own) / scale.max(axis=-1)
    k_agent = g.k_agent * own
    mag = np.where(others & (e < e0), k_agent * (1.0 / np.maximum(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    dvw = vel[:, None, :] - all_vel[None, :, :]
    dv = dvw / scale
    a = dot3(dv, dv)
    tau = np.clip(-dot3(q, dv) / np.maximum(a, _EPS), 0.0, g.horizon)
    qs = q + tau[..., None] * dv
    es = norm3(qs)
    urgency = (1.0 - tau / (g.horizon + _EPS)) ** 2  # flat at the horizon: field_law.urgency
    live = others & (es < e0) & (tau > 0)
    mag_p = np.where(live, k_agent * (1.0 / np.maximum(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0) * urgency
    farther = np.zeros((len(idx), n_all), dtype=bool)
    if swarm.goal_distance is not None:
        farther = norm3(flyers.goal - pos)[:, None] <= swarm.goal_distance[None, :]
    factored = (parked[None, :] | farther) & ~params.fixed_wing[idx][:, None]
    if swarm.yields is not None:
        factored = factored | (swarm.yields[None, :] & ~swarm.yields[idx][:, None])
    mag = np.where(factored, mag * gfac[:, None], mag)
    mag_p = np.where(factored, mag_p * gfac[:, None], mag_p)
    over = (2.0 * dvw[..., 0] + dvw[..., 1]) / (np.sqrt(5.0) * np.maximum(norm3(dvw), _EPS))
    up = np.zeros_like(dvw)
    up[..., 2] = over
    direction = _unit(qs * scale) + 0.5 * (_right_of(dvw) + up)
    direction[..., 2] = np.where(low & (direction[..., 2] < 0.0), 0.0, direction[..., 2])
    direction = _unit(direction)
    return np.einsum("nk,nkd->nd", mag, grad) + np.einsum("nk,nkd->nd", mag_p, direction)
