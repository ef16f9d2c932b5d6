"""Artificial potential field for all agents at once: forces in, commanded velocities out.

Terms (all vectorized over agents and bodies):
- attraction to the goal, quadratic within ``quadratic_radius`` and conic beyond;
- repulsion from obstacle *surfaces* (true signed distances and their gradients),
  ``k_rep (1/rho - 1/rho0)`` inside the influence distance ``rho0``, scaled by the
  goal-distance factor ``min(1, d_goal/rho0)^n`` plus its companion term pulling towards
  the goal (Ge & Cui's modified APF) so a goal beside an obstacle stays reachable;
- the same from the terrain/ground (vertical clearance) and the faces of ``bounds``;
- moving obstacles and other agents: repulsion at the predicted closest approach within
  ``horizon`` seconds (relative-velocity term), with a right-hand bias that breaks
  head-on symmetry; agents use the ellipsoidal ``separation`` metric;
- arrived agents are ordinary spheres to the others.
The force's direction becomes the commanded velocity; its speed is the cruise speed, cut
so the agent can still brake before the goal and before any obstacle surface ahead.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass
from functools import cache
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.compiled import use_compiled
from swarmplan.geometry.vec3 import dot3, norm3

if TYPE_CHECKING:
    from swarmplan.world.model import World

_EPS = 1e-9


@dataclass(frozen=True)
class ApfGains:
    k_att: float
    k_rep: float
    influence: float
    k_agent: float
    quadratic_radius: float
    goal_power: float
    k_moving: float
    horizon: float

    @classmethod
    def from_world(cls, world: World) -> ApfGains:
        return cls(**{k: float(v) for k, v in world.planner["apf"].items()})


@dataclass
class FieldInputs:
    """Geometry seen by the active agents this step (computed by the simulation)."""

    obstacle_distance: np.ndarray  # (N, M) signed distance from agent centre to obstacle surface
    obstacle_gradient: np.ndarray  # (N, M, 3)
    obstacle_velocity: np.ndarray  # (M, 3), zero for static obstacles
    obstacle_moving: np.ndarray  # (M,) bool
    obstacle_radius: np.ndarray  # (M,) bounding radius (prediction of moving bodies)
    obstacle_center: np.ndarray  # (M, 3)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(norm3(v, keepdims=True), _EPS)


def _right_of(v: np.ndarray) -> np.ndarray:
    """Horizontal unit vector to the right of ``v`` (z up)."""
    r = np.stack([v[..., 1], -v[..., 0], np.zeros(v.shape[:-1])], axis=-1)
    return _unit(r)


def _rep_magnitude(rho: np.ndarray, rho0: float, k: float) -> np.ndarray:
    rho_c = np.maximum(rho, 0.05)
    return np.where(rho < rho0, k * (1.0 / rho_c - 1.0 / rho0), 0.0)


def apf_forces(
    world: World,
    params: AgentParams,
    gains: ApfGains,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    goal: np.ndarray,
    field: FieldInputs,
    all_pos: np.ndarray,
    all_vel: np.ndarray,
    target: np.ndarray | None = None,
    static_scale: np.ndarray | None = None,
    parked: np.ndarray | None = None,
) -> np.ndarray:
    """Total APF force on agents ``idx`` (rows of ``pos``/``vel``/``goal``), shape (n, 3).

    ``target`` (default ``goal``) is the point of attraction, e.g. the next waypoint of a
    route or segment; the goal-distance factor always uses the real ``goal``.
    ``static_scale`` (n,) scales the repulsion of static obstacles per agent.
    ``parked`` (all agents,) marks agents that no longer fly (arrived, stopped): they hover
    where they are like static obstacles, and like those their repulsion takes the goal-distance
    factor, or neighbours parked at goals inside the influence distance hold an agent off its
    own goal for good (swap worlds: 5 of 32 agents stalled 2.0-2.3 m out).
    Swarm-sized worlds (``geometry.compiled.COMPILED_FROM`` agents on) run the compiled
    kernel (:mod:`swarmplan.flight._apf_kernel`), the same formulas in one pass.
    """
    args = (world, params, gains, idx, pos, vel, goal, field, all_pos, all_vel, target, static_scale, parked)
    return (_apf_compiled if use_compiled(len(all_pos)) else _apf_numpy)(*args)


@cache
def _kernel() -> ModuleType:
    """:mod:`swarmplan.flight._apf_kernel`, imported (and numba with it) at the first swarm-sized step."""
    from swarmplan.flight import _apf_kernel

    return _apf_kernel


def _apf_compiled(
    world: World,
    params: AgentParams,
    gains: ApfGains,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    goal: np.ndarray,
    field: FieldInputs,
    all_pos: np.ndarray,
    all_vel: np.ndarray,
    target: np.ndarray | None,
    static_scale: np.ndarray | None,
    parked: np.ndarray | None,
) -> np.ndarray:
    """:func:`_apf_numpy` in one compiled pass (equal to rounding; tests/test_apf_compiled.py)."""
    n = len(idx)
    out = np.empty((n, 3))
    if n == 0:
        return out
    h = world.terrain_height(pos[:, :2])
    gh = world.terrain_gradient(pos[:, :2])
    h_goal = world.terrain_height(goal[:, :2])
    # A target equal to the goal is the same field as no target (the quadratic well included).
    tgt = goal if target is None else target
    scale = np.ones(n) if static_scale is None else static_scale
    _kernel().apf_forces(
        pos,
        vel,
        goal,
        tgt,
        np.asarray(scale, dtype=float),
        idx,
        params.radius,
        params.separation,
        params.min_altitude,
        field.obstacle_distance,
        field.obstacle_gradient,
        field.obstacle_moving,
        field.obstacle_center,
        field.obstacle_velocity,
        field.obstacle_radius,
        h,
        gh,
        h_goal,
        float(world.terrain_clearance) if world.peaks else 0.0,
        world.bounds_min,
        world.bounds_max,
        all_pos,
        all_vel,
        np.zeros(len(all_pos), dtype=bool) if parked is None else np.asarray(parked, dtype=bool),
        _current_reach(params, gains) * (1.0 + 1e-9) + 1e-9,
        tuple(float(v) for v in astuple(gains)),
        out,
    )
    return out


def _apf_numpy(
    world: World,
    params: AgentParams,
    gains: ApfGains,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    goal: np.ndarray,
    field: FieldInputs,
    all_pos: np.ndarray,
    all_vel: np.ndarray,
    target: np.ndarray | None,
    static_scale: np.ndarray | None,
    parked: np.ndarray | None,
) -> np.ndarray:
    """:func:`apf_forces` in numpy (worlds below ``COMPILED_FROM`` agents)."""
    n = len(idx)
    r = params.radius[idx]
    rho0 = gains.influence
    e = goal - pos
    dg = norm3(e)
    et = e if target is None else target - pos
    dt_ = norm3(et)
    # Attraction: quadratic near, conic far (continuous at quadratic_radius). Only the goal
    # itself gets the quadratic well: an intermediate waypoint (route, segment) keeps the full
    # conic pull up to it, or a close waypoint's weak pull would be swamped by the repulsion of
    # the ground or a wall it runs along, and the agent would crawl.
    dq = gains.quadratic_radius
    well = dt_ <= dq
    if target is not None:
        well &= np.all(np.abs(target - goal) <= 1e-9, axis=1)
    att = gains.k_att * np.where(well[:, None], et, dq * et / np.maximum(dt_, _EPS)[:, None])
    force = att.copy()
    goal_dir = _unit(e)
    npow = gains.goal_power
    gfac = np.minimum(1.0, dg / rho0) ** npow
    gfac_d = np.where(dg < rho0, npow * np.minimum(1.0, dg / rho0) ** (npow - 1) / rho0, 0.0)

    def add_surface(rho: np.ndarray, grad: np.ndarray, k: float | np.ndarray) -> None:
        """Repulsion from surfaces at clearance ``rho`` (n, K) with outward gradients (n, K, 3)."""
        mag = _rep_magnitude(rho, rho0, k)
        pot = np.where(rho < rho0, 0.5 * k * (1.0 / np.maximum(rho, 0.05) - 1.0 / rho0) ** 2 * rho0, 0.0)
        nonlocal force
        force = force + np.einsum("nk,nkd->nd", mag * gfac[:, None], grad)
        # Companion of the goal factor: pulls towards the goal as the goal gets close.
        force = force + (pot.sum(axis=1) * gfac_d)[:, None] * goal_dir

    m_static = ~field.obstacle_moving
    if field.obstacle_distance.shape[1]:
        rho = field.obstacle_distance - r[:, None]
        k_static = gains.k_rep if static_scale is None else gains.k_rep * static_scale[:, None]
        add_surface(rho[:, m_static], field.obstacle_gradient[:, m_static], k_static)
        mv = field.obstacle_moving
        if mv.any():
            add_surface(rho[:, mv], field.obstacle_gradient[:, mv], gains.k_rep)
            force = force + _predicted_repulsion(
                pos,
                vel,
                r,
                field.obstacle_center[mv],
                field.obstacle_velocity[mv],
                field.obstacle_radius[mv],
                gains,
                gains.k_rep * gains.k_moving,
            )

    # Terrain / ground: vertical clearance above the height field, normal of the surface.
    h = world.terrain_height(pos[:, :2])
    gh = world.terrain_gradient(pos[:, :2])
    normal = _unit(np.stack([-gh[:, 0], -gh[:, 1], np.ones(n)], axis=1))
    floor = np.maximum(params.min_altitude[idx], world.terrain_clearance if world.peaks else 0.0)
    rho_g = (pos[:, 2] - h) - r
    rho0_g = max(min(rho0, 3.0 * float(np.max(floor)) if len(floor) else rho0), 2.0)
    # The ground only pushes while it is not the way to the goal (goals may sit low).
    low_goal = goal[:, 2] - world.terrain_height(goal[:, :2]) < floor
    mag_g = np.where(rho_g < rho0_g, gains.k_rep * (1.0 / np.maximum(rho_g, 0.05) - 1.0 / rho0_g), 0.0)
    mag_g = np.where(low_goal, mag_g * gfac, mag_g)
    force = force + mag_g[:, None] * normal

    # Faces of the flight volume.
    lo, hi = world.bounds_min, world.bounds_max
    rb0 = min(rho0, 10.0)
    for axis in range(3):
        for sign, plane in ((1.0, lo[axis]), (-1.0, hi[axis])):
            if axis == 2 and sign > 0:
                continue  # the ground term handles the floor
            rho_b = sign * (pos[:, axis] - plane) - r
            mag = np.where(rho_b < rb0, gains.k_rep * (1.0 / np.maximum(rho_b, 0.05) - 1.0 / rb0), 0.0)
            force[:, axis] += sign * mag * gfac

    agents = _agent_repulsion_indexed if len(all_pos) > _INDEX_FROM else _agent_repulsion
    force = force + agents(params, gains, idx, pos, vel, all_pos, all_vel, parked, gfac)
    return force


#: From this many agents on, agent-agent repulsion goes through a k-d tree (below it the
#: all-pairs arrays are cheaper than building the tree).
_INDEX_FROM = 48


def _predicted_repulsion(
    pos: np.ndarray,
    vel: np.ndarray,
    r: np.ndarray,
    centers: np.ndarray,
    velocities: np.ndarray,
    radii: np.ndarray,
    gains: ApfGains,
    k: float,
) -> np.ndarray:
    """Repulsion at the predicted closest approach to bodies moving at constant velocity."""
    dp = pos[:, None, :] - centers[None, :, :]  # (n, K, 3)
    dv = vel[:, None, :] - velocities[None, :, :]
    a = dot3(dv, dv)
    tau = np.clip(-dot3(dp, dv) / np.maximum(a, _EPS), 0.0, gains.horizon)
    sep = dp + tau[..., None] * dv
    dist = norm3(sep)
    rho = dist - radii[None, :] - r[:, None]
    rho0 = gains.influence
    # Closer in time matters more; a collision course gets a sideways (right-hand) push.
    urgency = 1.0 - tau / (gains.horizon + _EPS)
    mag = _rep_magnitude(rho, rho0, k) * urgency * (tau > 0)
    direction = _unit(sep)
    head_on = dist < 0.25 * (radii[None, :] + r[:, None] + 1.0)
    right = _right_of(dv)
    direction = np.where(head_on[..., None], right, _unit(direction + 0.3 * right))
    return np.einsum("nk,nkd->nd", mag, direction)


def _agent_repulsion(
    params: AgentParams,
    gains: ApfGains,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    all_pos: np.ndarray,
    all_vel: np.ndarray,
    parked: np.ndarray | None = None,
    gfac: np.ndarray | None = None,
) -> np.ndarray:
    """Ellipsoidal separation repulsion from every other agent (current and predicted)."""
    n_all = len(all_pos)
    if n_all < 2:
        return np.zeros_like(pos)
    others = np.ones((len(idx), n_all), dtype=bool)
    others[np.arange(len(idx)), idx] = False
    sep = np.maximum(params.separation[idx][:, None, :], params.separation[None, :, :])
    rr = params.radius[idx][:, None] + params.radius[None, :]
    scale = sep + rr[..., None]  # ellipsoid semi-axes where contact-plus-separation begins
    dp = pos[:, None, :] - all_pos[None, :, :]
    q = dp / scale
    e = np.linalg.norm(q, axis=-1)  # < 1: separation violated
    grad = _unit(q / scale)
    e0 = 1.0 + gains.influence / np.maximum(np.linalg.norm(scale, axis=-1), _EPS)
    mag = np.where(
        others & (e < e0), gains.k_agent * (1.0 / np.maximum(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0
    )
    if parked is not None and parked.any():
        mag = np.where(parked[None, :], mag * gfac[:, None], mag)
    force = np.einsum("nk,nkd->nd", mag, grad)
    # Predicted closest approach in the scaled metric, with a right-hand bias.
    dv = (vel[:, None, :] - all_vel[None, :, :]) / scale
    a = np.sum(dv * dv, axis=-1)
    tau = np.clip(-np.sum(q * dv, axis=-1) / np.maximum(a, _EPS), 0.0, gains.horizon)
    qs = q + tau[..., None] * dv
    es = np.linalg.norm(qs, axis=-1)
    urgency = 1.0 - tau / (gains.horizon + _EPS)
    mag_p = (
        np.where(
            others & (es < e0) & (tau > 0),
            gains.k_agent * (1.0 / np.maximum(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)),
            0.0,
        )
        * urgency
    )
    if parked is not None and parked.any():
        mag_p = np.where(parked[None, :], mag_p * gfac[:, None], mag_p)
    direction = _unit(_unit(qs * scale) + 0.5 * _right_of(vel[:, None, :] - all_vel[None, :, :]))
    return force + np.einsum("nk,nkd->nd", mag_p, direction)


def agent_reach(params: AgentParams, gains: ApfGains, vel: np.ndarray, all_vel: np.ndarray) -> float:
    """Distance beyond which another agent adds exactly nothing to :func:`_agent_repulsion`.

    The current term needs e = |dp / scale| < e0, and e >= |dp| / max(scale), so
    |dp| < e0 max(scale), maximised over the pairs of agent kinds (separation, radius); the
    predicted one the same at dp + tau dv with tau <= horizon, |dv| <= max|v_i| + max|v_j|.
    """
    current = _current_reach(params, gains)
    vmax = float(
        np.linalg.norm(vel, axis=1).max(initial=0.0) + np.linalg.norm(all_vel, axis=1).max(initial=0.0)
    )
    # A relative margin covers the rounding of the tree's distances.
    return (current + gains.horizon * vmax) * (1.0 + 1e-9) + 1e-9


def _current_reach(params: AgentParams, gains: ApfGains) -> float:
    """Distance beyond which the *current* term of :func:`_agent_repulsion` is zero: e0 times
    the largest semi-axis, maximised over the pairs of agent kinds (see :func:`agent_reach`)."""
    rows = np.column_stack([params.separation, params.radius])
    # Usually every agent is of one kind; np.unique over rows costs more than the rest.
    kinds = rows[:1] if (rows == rows[0]).all() else np.unique(rows, axis=0)
    sep = np.maximum(kinds[:, None, :3], kinds[None, :, :3])
    scale = sep + (kinds[:, None, 3] + kinds[None, :, 3])[..., None]
    e0 = 1.0 + gains.influence / np.maximum(np.linalg.norm(scale, axis=-1), _EPS)
    return float((e0 * scale.max(axis=-1)).max())


def _agent_repulsion_indexed(
    params: AgentParams,
    gains: ApfGains,
    idx: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    all_pos: np.ndarray,
    all_vel: np.ndarray,
    parked: np.ndarray | None = None,
    gfac: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`_agent_repulsion` over the pairs within :func:`agent_reach` only (k-d tree):
    the same formula per pair; every other pair adds exactly zero (tests: equal to 1e-12)."""
    from scipy.spatial import cKDTree

    n = len(pos)
    if len(all_pos) < 2 or n == 0:
        return np.zeros_like(pos)
    reach = agent_reach(params, gains, vel, all_vel)
    others = cKDTree(all_pos)
    # Usually every agent flies: the same points, one tree for both sides.
    mine = others if n == len(all_pos) and np.array_equal(pos, all_pos) else cKDTree(pos)
    pairs = mine.sparse_distance_matrix(others, reach, output_type="ndarray")
    a, b = pairs["i"].astype(np.intp), pairs["j"].astype(np.intp)
    keep = b != idx[a]
    a, b = a[keep], b[keep]
    order = np.lexsort((b, a))  # row by row, others in index order (as the all-pairs sum)
    a, b = a[order], b[order]
    ia = idx[a]
    scale = (
        np.maximum(params.separation[ia], params.separation[b])
        + (params.radius[ia] + params.radius[b])[:, None]
    )
    q = (pos[a] - all_pos[b]) / scale
    e = norm3(q)
    e0 = 1.0 + gains.influence / np.maximum(norm3(scale), _EPS)
    dvw = vel[a] - all_vel[b]
    dv = dvw / scale
    aa = dot3(dv, dv)
    tau = np.clip(-dot3(q, dv) / np.maximum(aa, _EPS), 0.0, gains.horizon)
    qs = q + tau[..., None] * dv
    es = norm3(qs)
    # Most pairs within the reach add exactly zero (both magnitudes 0): the unit vectors are
    # computed for the others only. Leaving a zero out of the per-agent sums changes nothing
    # (they start at +0.0 and x + 0.0 == x).
    live = np.flatnonzero((e < e0) | ((es < e0) & (tau > 0)))
    a, e, e0, q, scale, qs, es, tau, dvw = (v[live] for v in (a, e, e0, q, scale, qs, es, tau, dvw))
    grad = _unit(q / scale)
    mag = np.where(e < e0, gains.k_agent * (1.0 / np.maximum(e - 0.5, 0.02) - 1.0 / (e0 - 0.5)), 0.0)
    if parked is not None and parked.any():
        mag = np.where(parked[b[live]], mag * gfac[a], mag)
    urgency = 1.0 - tau / (gains.horizon + _EPS)
    mag_p = (
        np.where(
            (es < e0) & (tau > 0),
            gains.k_agent * (1.0 / np.maximum(es - 0.5, 0.02) - 1.0 / (e0 - 0.5)),
            0.0,
        )
        * urgency
    )
    if parked is not None and parked.any():
        mag_p = np.where(parked[b[live]], mag_p * gfac[a], mag_p)
    direction = _unit(_unit(qs * scale) + 0.5 * _right_of(dvw))
    per_pair = mag[:, None] * grad + mag_p[:, None] * direction
    return np.stack([np.bincount(a, weights=per_pair[:, k], minlength=n) for k in range(3)], axis=1)


def commanded_velocity(
    params: AgentParams,
    idx: np.ndarray,
    force: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    clearance: np.ndarray,
    clearance_dir: np.ndarray,
) -> np.ndarray:
    """Velocity command from the force: cruise speed along it, slowed to brake before the goal
    and before the nearest surface ahead (``clearance`` (n,), outward normal ``clearance_dir``)."""
    amax = params.max_accel[idx]
    speed = params.speed_cruise[idx].copy()
    dg = norm3(goal - pos)
    speed = np.minimum(speed, np.sqrt(2.0 * 0.8 * amax * dg))
    v = _unit(force) * speed[:, None]
    # Component towards the nearest surface may not exceed what can still be braked.
    toward = -dot3(v, clearance_dir)
    allowed = np.sqrt(2.0 * 0.8 * amax * np.maximum(clearance - 0.5, 0.0))
    excess = np.maximum(toward - allowed, 0.0)
    return v + excess[:, None] * clearance_dir
