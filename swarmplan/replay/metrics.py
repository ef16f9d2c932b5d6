"""Metrics recomputed from the recorded states alone, and their comparison with /summary.

Everything here uses the positions in ``/agents/state`` (and obstacle poses from
``/obstacles/state``), never the planner's own bookkeeping, so it is an independent audit
of the recorded ``/summary``.

Conventions
-----------
* An agent is measured at every recorded step, whatever its mode: an arrived one hovers at
  its goal (and may leave it to get out of a mover's way), a failed or collided one stays where
  it stopped. Path length, clearance, curvature and collisions use every step; a contact
  with an arrived agent is a collision as any other.
* Arrival: first step whose mode is ``arrived`` or whose position is within
  ``sim.goal_tolerance`` of the goal (``arrived``: the agent reached its goal).
* Clearance to an obstacle: analytic signed distance to its surface (sphere, box,
  cylinder, capsule, with rotation and the recorded pose of moving obstacles; meshes by
  trimesh proximity on the inlined vertices/faces) minus the agent radius. To another
  agent: centre distance minus both radii. ``min_clearance`` is the minimum of both.
* Curvature: turning angle between consecutive steps divided by the mean length of the
  two steps, after dropping steps shorter than 1 mm. A vertex turning by more than 150°
  is a *cusp* (stop and reverse), and so is a turning vertex where the agent stood still
  for a step or more (a dropped step right after it: stop and turn): counted in ``cusps``
  and left out of ``max_curvature``.
  ``curvature_limit`` is the model's, from ``/world``: max_accel / cruise² (multirotor,
  paper 004 eq 34 at cruise) or 1 / min_turn_radius (fixed wing).
* Lateral acceleration: ``v² κ`` at the same vertices (cusps left out), in its one-step form
  ``2 v sin(θ/2) / dt`` (θ the turn, ``v`` the mean length of the two steps over ``dt``: the
  velocity change the turn needs, equal to ``v² κ`` for small turns); a multirotor's limit
  is ``max_accel`` at any speed (a slow turn may be tighter than ``curvature_limit`` and
  still legal). ``curvature_violation``: a fixed
  wing's max curvature above 1.05 / min_turn_radius, or a multirotor's max lateral
  acceleration above 1.05 max_accel.
* Collisions: number of contact episodes (maximal runs of consecutive active steps with
  penetration deeper than ``contact_tol``) per agent and body (obstacle, other agent,
  terrain), plus episodes of mode ``collided`` that start without a geometric contact.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .geometry import MeshDistance, euler_deg_to_matrix, primitive_distance, quat_to_matrix, terrain_height
from .recording import Recording

MIN_STEP = 1e-3  # m: steps shorter than this are ignored for curvature
CUSP_DEG = 150.0  # a turn sharper than this between consecutive steps is a cusp
CONTACT_TOL = 1e-3  # m: penetration deeper than this is a contact
VIOLATION_FACTOR = 1.05  # a curvature / lateral acceleration this far over its limit breaks the model
POSITION_QUANTUM = 1e-6  # m: the recorded positions' rounding (6 decimals, docs/log-format.md)


@dataclass
class AgentMetrics:
    id: str
    arrived: bool
    arrival_time: float | None
    path_length: float
    min_clearance: float | None
    min_obstacle_clearance: float | None
    min_agent_clearance: float | None
    closest_body: str | None
    min_terrain_clearance: float | None
    max_curvature: float
    collisions: int
    max_curvature_rounding: float = 0.0  # 1/m: what rounding the positions can make at its vertex
    cusps: int = 0
    curvature_limit: float | None = None
    max_lateral_accel: float = 0.0
    lateral_accel_limit: float | None = None
    curvature_violation: bool = False
    collision_bodies: list[str] = field(default_factory=list)
    escapes: int = 0
    stuck_events: int = 0
    final_goal_distance: float = math.nan
    threat_time: float | None = None  # s inside some threat's r_max (worlds with threats)
    threat_core_time: float | None = None  # s inside some threat's r_min
    threat_closest: float | None = None  # m, closest approach to a threat's centre

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Tolerances:
    arrival_time_steps: float = 1.01  # in units of the step dt
    path_length_abs: float = 0.1  # m
    path_length_rel: float = 0.01
    clearance_abs: float = 0.05  # m
    clearance_rel: float = 0.02
    curvature_abs: float = 1e-3  # 1/m
    curvature_rel: float = 0.10
    lateral_accel_abs: float = 0.05  # m/s^2
    lateral_accel_rel: float = 0.10


# ---------------------------------------------------------------------- helpers


def _episodes(mask: np.ndarray) -> int:
    """Number of maximal runs of True."""
    m = np.asarray(mask, bool)
    if not m.size:
        return 0
    return int(m[0]) + int(np.count_nonzero(m[1:] & ~m[:-1]))


def active_end(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """(arrival step index or -1, last active step index) per agent."""
    tol = rec.goal_tolerance
    arrival = np.full(rec.n_agents, -1, int)
    end = np.full(rec.n_agents, rec.n_steps - 1, int)
    for i in range(rec.n_agents):
        d = np.linalg.norm(rec.positions[i] - rec.goals[i], axis=1)
        hit = (rec.modes[i] == "arrived") | (np.nan_to_num(d, nan=np.inf) <= tol + 1e-6)
        idx = np.flatnonzero(hit)
        if len(idx):
            arrival[i] = end[i] = int(idx[0])
        else:
            present = np.flatnonzero(np.isfinite(rec.positions[i, :, 0]))
            end[i] = int(present[-1]) if len(present) else -1
    return arrival, end


def active_mask(rec: Recording) -> np.ndarray:
    """The steps at which each agent is measured (A, T): every recorded one."""
    return np.isfinite(rec.positions[:, :, 0])


def path_length(points: np.ndarray) -> float:
    p = points[np.isfinite(points[:, 0])]
    if len(p) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def curvature_series(
    points: np.ndarray, times: np.ndarray, min_step: float = MIN_STEP, cusps: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """(times, curvature) at the interior points of the path, sub-``min_step`` steps dropped;
    cusps (turns over ``CUSP_DEG``) are left out unless ``cusps`` is True."""
    t, curv, cusp = curvature_cusps(points, times, min_step)
    return (t, curv) if cusps else (t[~cusp], curv[~cusp])


def curvature_cusps(
    points: np.ndarray, times: np.ndarray, min_step: float = MIN_STEP
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, curvature, cusp mask) at the interior points of the path, sub-``min_step`` steps dropped."""
    t, curv, cusp, _, _ = _turns(points, times, min_step)
    return t, curv, cusp


def rounding_curvature(points: np.ndarray, times: np.ndarray, min_step: float = MIN_STEP) -> np.ndarray:
    """Per interior point of :func:`curvature_cusps`: the curvature the positions' rounding alone
    can make there (``POSITION_QUANTUM``): each point off by up to half of it on every axis moves
    the vertex off the line of its neighbours by up to ``2 d`` (``d`` = that offset's length), a
    curvature of ``2 (2 d) / (a b)`` for steps of lengths ``a`` and ``b``. A straight flight's
    short steps, a slow drone's, show that much."""
    *_, steps = _turns(points, times, min_step)
    d = 0.5 * POSITION_QUANTUM * math.sqrt(3.0)
    return 4.0 * d / np.maximum(steps, 1e-300)


def curvature_over(
    points: np.ndarray, times: np.ndarray, window: float, min_step: float = MIN_STEP
) -> tuple[np.ndarray, np.ndarray]:
    """(times, curvature over ``window`` seconds) at the non-cusp interior points: the turn flown
    in the ``window`` round each point (after ``t - window / 2``, up to ``t + window / 2``: a
    whole number of steps) over the distance flown there (sum of turn angles over sum of mean
    steps). A path that turns at its limit every other step and straight between has half that
    curvature at this scale, which is what it flies."""
    t, curv, cusp, mean, _ = _turns(points, times, min_step)
    t, mean = t[~cusp], mean[~cusp]
    turn = np.concatenate([[0.0], np.cumsum(curv[~cusp] * mean)])
    run = np.concatenate([[0.0], np.cumsum(mean)])
    edge = 1e-9 * max(window, 1.0)  # times are rounded: a point on the edge is on it
    lo = np.searchsorted(t, t - 0.5 * window + edge, side="left")
    hi = np.searchsorted(t, t + 0.5 * window + edge, side="right")
    return t, (turn[hi] - turn[lo]) / (run[hi] - run[lo])


def lateral_accel(points: np.ndarray, times: np.ndarray, dt: float, min_step: float = MIN_STEP) -> float:
    """Max lateral acceleration (m/s²) over the non-cusp vertices: ``v² κ`` in its one-step
    form ``2 v sin(θ / 2) / dt`` (θ the turn, ``v`` = mean length of the two steps / ``dt``)."""
    _, curv, cusp, mean, _ = _turns(points, times, min_step)
    ok = ~cusp
    if not ok.any():
        return 0.0
    # One-step form of v^2 kappa: the velocity change 2 v sin(theta / 2) a turn by theta needs.
    theta = curv[ok] * mean[ok]
    return float((2.0 * (mean[ok] / dt) * np.sin(0.5 * theta) / dt).max())


def _turns(
    points: np.ndarray, times: np.ndarray, min_step: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(times, curvature, cusp mask, mean step length, product of the two steps' lengths) at
    the interior points of the path."""
    ok = np.isfinite(points[:, 0])
    p, t = points[ok], times[ok]
    empty = (np.zeros(0), np.zeros(0), np.zeros(0, bool), np.zeros(0), np.zeros(0))
    if len(p) < 3:
        return empty
    keep = [0]
    for k in range(1, len(p)):
        if np.linalg.norm(p[k] - p[keep[-1]]) >= min_step:
            keep.append(k)
    p, t = p[keep], t[keep]
    if len(p) < 3:
        return empty
    a = p[1:-1] - p[:-2]
    b = p[2:] - p[1:-1]
    la = np.linalg.norm(a, axis=1)
    lb = np.linalg.norm(b, axis=1)
    cos = np.einsum("ij,ij->i", a, b) / (la * lb)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    mean = (la + lb) / 2.0
    # Stood still after the vertex (a dropped step): a stop, then a turn of any size.
    still = (np.diff(np.asarray(keep))[1:] > 1) & (angle > 1e-9)
    return t[1:-1], angle / mean, (angle > math.radians(CUSP_DEG)) | still, mean, la * lb


def obstacle_distances(rec: Recording, mesh_cache: dict | None = None) -> dict[str, np.ndarray]:
    """Signed distance (A, T) from every agent centre to every obstacle surface (NaN if unknown).

    For meshes, only active steps are evaluated and entries far from the minimum are
    lower bounds (see MeshDistance); each agent's minimum and every contact (<= 0) are exact.
    """
    mesh_cache = {} if mesh_cache is None else mesh_cache
    A, T = rec.n_agents, rec.n_steps
    P = rec.positions.reshape(-1, 3)
    out: dict[str, np.ndarray] = {}
    for obst in rec.obstacles:
        oid = str(obst.get("id"))
        moving = bool(obst.get("motion")) and oid in rec.obstacle_tracks
        if moving:
            c, q = rec.obstacle_poses(oid)  # (T,3), (T,4)
            R = quat_to_matrix(q)  # (T,3,3)
        else:
            c = np.asarray(obst.get("position", [0, 0, 0]), float)
            R = euler_deg_to_matrix(obst.get("rotation") or [0, 0, 0])
        if obst.get("shape") == "mesh":
            if "vertices" not in obst or "faces" not in obst:
                continue
            if oid not in mesh_cache:
                mesh_cache[oid] = MeshDistance(obst["vertices"], obst["faces"])
            md = mesh_cache[oid]
            pts = rec.positions.copy()
            if moving:
                # vertices are the pose at t=0: map each point into that pose
                c0 = np.asarray(obst.get("position", [0, 0, 0]), float)
                R0 = euler_deg_to_matrix(obst.get("rotation") or [0, 0, 0])
                local = np.einsum("atj,tji->ati", pts - c[None], R)  # R^T (p - c)
                pts = local @ R0.T + c0
            d = np.full((A, T), np.nan)
            act = active_mask(rec)
            for i in range(A):  # prune per agent: each agent's minimum must be exact
                ok = np.isfinite(pts[i, :, 0]) & act[i]
                d[i, ok] = md.distances_pruned(pts[i, ok])
            out[oid] = d
            continue
        if moving:
            local = np.einsum("atj,tji->ati", rec.positions - c[None], R)
        else:
            local = (P - c) @ R
        d = primitive_distance(local.reshape(-1, 3), obst)
        if d is not None:
            out[oid] = d.reshape(A, T)
    return out


# ---------------------------------------------------------------------- main entry


def compute_metrics(rec: Recording, contact_tol: float = CONTACT_TOL) -> list[AgentMetrics]:
    A, T = rec.n_agents, rec.n_steps
    arrival, _end = active_end(rec)
    active = active_mask(rec)
    radii = rec.radii
    obst_d = obstacle_distances(rec)

    # agent-agent distances minus radii at every step, to every other agent: one that has
    # arrived (or stopped) still hovers where it is, as in the simulation's own metrics
    # (Simulation.step: Obstacles.agent_clearance over all agents)
    agent_clear = np.full((A, T), np.inf)
    agent_closest = np.full((A, T), -1, int)
    contacts: dict[int, dict[str, np.ndarray]] = {i: {} for i in range(A)}
    for i in range(A):
        if A < 2:
            break
        diff = np.linalg.norm(rec.positions - rec.positions[i][None], axis=2) - radii[:, None] - radii[i]
        diff = np.where(active[i][None, :], diff, np.inf)
        diff[i] = np.inf
        agent_clear[i] = diff.min(axis=0)
        agent_closest[i] = diff.argmin(axis=0)
        for j in range(A):
            if j != i:
                m = diff[j] < -contact_tol
                if m.any():
                    contacts[i][rec.agent_ids[j]] = m

    terrain = None
    if (rec.world.get("terrain") or {}).get("peaks"):
        h = terrain_height(rec.world, rec.positions.reshape(-1, 3)[:, :2]).reshape(A, T)
        terrain = rec.positions[:, :, 2] - h - radii[:, None]

    event_counts: dict[tuple[str, str], int] = {}
    for e in rec.events:
        key = (str(e.agent), e.kind)
        event_counts[key] = event_counts.get(key, 0) + 1

    exposure = threat_exposure(rec)
    result = []
    for i, aid in enumerate(rec.agent_ids):
        act = active[i]
        # obstacles
        best_obst, best_obst_id = math.inf, None
        for oid, d in obst_d.items():
            di = np.where(act, d[i] - radii[i], np.inf)
            di = np.nan_to_num(di, nan=np.inf)
            if di.size and di.min() < best_obst:
                best_obst, best_obst_id = float(di.min()), oid
            m = di < -contact_tol
            if m.any():
                contacts[i][oid] = m
        ac = float(agent_clear[i].min()) if T else math.inf
        ac_id = None
        if math.isfinite(ac):
            ac_id = rec.agent_ids[int(agent_closest[i, int(agent_clear[i].argmin())])]
        min_terr = None
        if terrain is not None:
            ti = np.where(act, terrain[i], np.inf)
            if np.isfinite(ti).any():
                min_terr = float(ti.min())
                m = ti < -contact_tol
                if m.any():
                    contacts[i]["terrain"] = m
        # collisions: contact episodes per body, plus 'collided' episodes without contact
        n_coll = sum(_episodes(m) for m in contacts[i].values())
        bodies = sorted(contacts[i])
        any_contact = np.zeros(T, bool)
        for m in contacts[i].values():
            any_contact |= m
        coll_mode = rec.modes[i] == "collided"
        starts = np.flatnonzero(coll_mode & ~np.concatenate([[False], coll_mode[:-1]]))
        for k in starts:
            lo, hi = max(0, k - 1), min(T, k + 2)
            if not any_contact[lo:hi].any():
                n_coll += 1
                if "(mode collided)" not in bodies:
                    bodies.append("(mode collided)")

        pts = np.where(act[:, None], rec.positions[i], np.nan)
        _, curv, cusp = curvature_cusps(pts, rec.times)
        max_curv = float(curv[~cusp].max()) if (~cusp).any() else 0.0
        # the rounding's curvature at the vertex of that maximum (how far it may be off)
        noise = (
            float(rounding_curvature(pts, rec.times)[~cusp][np.argmax(curv[~cusp])]) if (~cusp).any() else 0.0
        )
        lat = lateral_accel(pts, rec.times, rec.dt)
        limit = _curvature_limit(rec, i)
        lat_limit = _lateral_accel_limit(rec, i)
        if lat_limit is None:
            violation = limit is not None and max_curv > VIOLATION_FACTOR * limit
        else:
            violation = lat > VIOLATION_FACTOR * lat_limit
        clear_vals = [v for v in (best_obst, ac) if math.isfinite(v)]
        min_clear = min(clear_vals) if clear_vals else None
        closest = None
        if min_clear is not None:
            closest = best_obst_id if best_obst <= ac else ac_id
        escapes = event_counts.get((aid, "escape_start"))
        if escapes is None:
            escapes = _episodes(rec.modes[i] == "escape")
        last = np.flatnonzero(np.isfinite(rec.positions[i, :, 0]))
        fgd = float(np.linalg.norm(rec.positions[i, last[-1]] - rec.goals[i])) if len(last) else math.nan
        result.append(
            AgentMetrics(
                id=aid,
                arrived=bool(arrival[i] >= 0),
                arrival_time=float(rec.times[arrival[i]]) if arrival[i] >= 0 else None,
                path_length=path_length(pts),
                min_clearance=min_clear,
                min_obstacle_clearance=best_obst if math.isfinite(best_obst) else None,
                min_agent_clearance=ac if math.isfinite(ac) else None,
                closest_body=closest,
                min_terrain_clearance=min_terr,
                max_curvature=max_curv,
                max_curvature_rounding=noise,
                collisions=int(n_coll),
                cusps=int(cusp.sum()),
                curvature_limit=limit,
                max_lateral_accel=lat,
                lateral_accel_limit=lat_limit,
                curvature_violation=bool(violation),
                collision_bodies=bodies,
                escapes=int(escapes),
                stuck_events=int(event_counts.get((aid, "stuck"), 0)),
                final_goal_distance=fgd,
                **(exposure[i] if exposure else {}),
            )
        )
    return result


def threat_exposure(rec: Recording) -> list[dict[str, float | None]] | None:
    """Per agent: seconds inside some threat's ``r_max`` and ``r_min`` and the closest approach to
    a threat's centre (3D distance), over the recorded steps it flew (it had not arrived,
    collided or failed at the step before); None without threats."""
    threats = [t for t in rec.world.get("threats") or [] if isinstance(t, dict) and t.get("position")]
    if not threats or rec.n_steps < 2:
        return None
    done = np.isin(rec.modes[:, :-1].astype(str), ["arrived", "collided", "failed"])
    flying = ~done  # (A, T-1): the interval ending at step t + 1
    span = np.diff(rec.times)[None, :]
    ends = rec.positions[:, 1:]
    in_range = np.zeros(flying.shape, bool)
    in_core = np.zeros(flying.shape, bool)
    closest = np.full(rec.n_agents, np.inf)
    for th in threats:
        d = np.linalg.norm(ends - np.asarray(th["position"], float), axis=2)
        d = np.nan_to_num(d, nan=np.inf)
        in_range |= flying & (d < float(th.get("r_max") or 0.0))
        in_core |= flying & (d < float(th.get("r_min") or 0.0))
        closest = np.minimum(closest, np.where(flying, d, np.inf).min(axis=1))
    return [
        {
            "threat_time": float((span * in_range)[i].sum()),
            "threat_core_time": float((span * in_core)[i].sum()),
            "threat_closest": float(closest[i]) if np.isfinite(closest[i]) else None,
        }
        for i in range(rec.n_agents)
    ]


def _curvature_limit(rec: Recording, i: int) -> float | None:
    """The model's curvature limit from the ``/world`` agent entry (None when it lacks the fields)."""
    by_id = {str(a.get("id")): a for a in rec.world.get("agents") or [] if isinstance(a, dict)}
    a = by_id.get(rec.agent_ids[i], {})
    try:
        if a.get("model") == "fixed_wing":
            return 1.0 / float(a["min_turn_radius"])
        return float(a["max_accel"]) / float(a["speed"]["cruise"]) ** 2
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None


def fixed_wing_turn_limit(rec: Recording, i: int) -> float | None:
    """Agent ``i``'s curvature limit (1/min_turn_radius) when it is a fixed wing, else None (a
    multirotor's limit on a turn is its lateral acceleration: the slower, the tighter)."""
    return _curvature_limit(rec, i) if _lateral_accel_limit(rec, i) is None else None


def _lateral_accel_limit(rec: Recording, i: int) -> float | None:
    """A multirotor's lateral acceleration limit (its max_accel); None for a fixed wing (its
    limit is the curvature) or when the entry lacks the field."""
    by_id = {str(a.get("id")): a for a in rec.world.get("agents") or [] if isinstance(a, dict)}
    a = by_id.get(rec.agent_ids[i], {})
    if a.get("model") == "fixed_wing":
        return None
    try:
        return float(a["max_accel"])
    except (KeyError, TypeError, ValueError):
        return None


# ---------------------------------------------------------------------- comparison


def _close(a, b, abs_tol, rel_tol) -> bool:
    if a is None or b is None:
        return a is None and b is None
    try:
        a, b = float(a), float(b)
    except (TypeError, ValueError):
        return False
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= max(abs_tol, rel_tol * max(abs(a), abs(b)))


def compare_with_summary(
    rec: Recording, metrics: list[AgentMetrics], tol: Tolerances | None = None
) -> tuple[list[str], int]:
    """Disagreements between the recomputed metrics and the recorded /summary.

    Returns (list of messages, number of values compared).
    """
    tol = tol or Tolerances()
    summ = rec.summary
    if not summ:
        return [], 0
    rows = {str(a.get("id")): a for a in summ.get("agents") or []}
    dt = rec.dt
    problems: list[str] = []
    n = 0
    for m in metrics:
        row = rows.get(m.id)
        if row is None:
            problems.append(f"{m.id}: missing from /summary")
            continue
        checks = [
            ("arrived", m.arrived, row.get("arrived"), None),
            (
                "arrival_time",
                m.arrival_time,
                row.get("arrival_time"),
                (tol.arrival_time_steps * dt + 1e-6, 0),
            ),
            (
                "path_length",
                m.path_length,
                row.get("path_length"),
                (tol.path_length_abs, tol.path_length_rel),
            ),
            (
                "min_clearance",
                m.min_clearance,
                row.get("min_clearance"),
                (tol.clearance_abs, tol.clearance_rel),
            ),
            (
                "max_curvature",
                m.max_curvature,
                row.get("max_curvature"),
                (tol.curvature_abs + m.max_curvature_rounding, tol.curvature_rel),
            ),
            ("cusps", m.cusps, row.get("cusps"), None),
            (
                "curvature_limit",
                m.curvature_limit,
                row.get("curvature_limit"),
                (1e-6, 1e-6),
            ),
            (
                "max_lateral_accel",
                m.max_lateral_accel,
                row.get("max_lateral_accel"),
                (tol.lateral_accel_abs, tol.lateral_accel_rel),
            ),
            ("lateral_accel_limit", m.lateral_accel_limit, row.get("lateral_accel_limit"), (1e-6, 1e-6)),
            ("curvature_violation", m.curvature_violation, row.get("curvature_violation"), None),
            ("collisions", m.collisions, row.get("collisions"), None),
            ("escapes", m.escapes, row.get("escapes"), None),
            ("stuck_events", m.stuck_events, row.get("stuck_events"), None),
            ("threat_time", m.threat_time, row.get("threat_time"), (2.01 * dt, 0.02)),
            ("threat_core_time", m.threat_core_time, row.get("threat_core_time"), (2.01 * dt, 0.02)),
            ("threat_closest", m.threat_closest, row.get("threat_closest"), (0.01, 1e-4)),
        ]
        for key, mine, theirs, t in checks:
            if key not in row:
                continue
            n += 1
            if t is None:
                ok = (bool(mine) == bool(theirs)) if key == "arrived" else (mine == theirs)
            else:
                if key == "arrival_time" and not m.arrived and theirs is None:
                    ok = True
                else:
                    ok = _close(mine, theirs, *t)
            if not ok:
                problems.append(f"{m.id}: {key} recomputed {_fmt(mine)} vs recorded {_fmt(theirs)}")
    for aid in rows:
        if aid not in {m.id for m in metrics}:
            problems.append(f"{aid}: in /summary but not in /agents/state")
    if "success" in summ:
        n += 1
        ok = all(m.arrived for m in metrics) and not any(m.collisions for m in metrics)
        if bool(summ["success"]) != ok:
            problems.append(f"success: recomputed {ok} vs recorded {bool(summ['success'])}")
    if "sim_time" in summ and rec.n_steps and summ["sim_time"] is not None:
        n += 1
        if not _close(rec.times[-1], summ["sim_time"], 1.01 * dt + 1e-6, 0):
            problems.append(f"sim_time: last step {rec.times[-1]:.3f} vs recorded {summ['sim_time']}")
    return problems, n


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return repr(v)
