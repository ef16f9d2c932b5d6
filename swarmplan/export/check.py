"""``--check``: fly every exported trajectory again with the vehicle models of ``track`` (a
Crazyflie trajectory by the Crazyflie under its firmware's commander and Mellinger controller, a
mission by the quadrotor under its cascaded PID, a fixed wing under L1 guidance and its energy
loop), following the export and not the log, then look at the swarm together on the exported
timing.

Per agent: the largest distance between the flown vehicle and the planned position at the same
instant (the export's own timing), or for a multirotor mission (a path with speeds, flown
without a schedule) the largest distance to the planned path, against its limit:
max(5 m, 0.05 R_min) for a fixed wing (``track``'s bound), what the Crazyflie's controller
achieves on a Crazyflie trajectory (:func:`crazyflie_limit`), the export's accuracy bound for a
multirotor mission. For the swarm: the smallest
surface distance between two agents, any contact between two agents or with an obstacle (moving
ones where the log has them), the ground or terrain, and whether the separation was kept
(:func:`separation_kept`): each pair outside its separation ellipsoid, or, for a pair whose flight
itself came inside it, no deeper than the flight came less the two exports' accuracy bounds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarmplan.replay import Recording
from swarmplan.track.crazyflie import Crazyflie, Setpoints
from swarmplan.track.crazyflie import fly as fly_crazyflie
from swarmplan.track.fixed_wing import FixedWingConfig, aircraft_of, error_limit, fly
from swarmplan.track.quadrotor import simulate
from swarmplan.track.reference import Reference, build_reference
from swarmplan.world.tracker_config import TrackerConfig

from .clearance import body_distances, heights


@dataclass(frozen=True)
class Plan:
    """One agent's exported trajectory on its own timing: ``times`` (K,) from the log's t = 0,
    positions (K, 3); ``vel``/``acc`` when the export defines them (a polynomial), else None."""

    id: str
    model: str
    radius: float
    separation: tuple[float, float, float]
    times: np.ndarray
    pos: np.ndarray
    bound: float  # the export's accuracy bound (m)
    vel: np.ndarray | None = None
    acc: np.ndarray | None = None
    path_only: bool = False  # a mission: held to its path (no schedule), not to a timed position
    jerk: np.ndarray | None = None
    vehicle: str = ""  # "crazyflie": set-points every commander tick, flown by the Crazyflie


@dataclass(frozen=True)
class AgentCheck:
    id: str
    model: str
    max_deviation: float
    limit: float

    @property
    def ok(self) -> bool:
        return self.max_deviation <= self.limit


@dataclass(frozen=True)
class TightPair:
    """A pair whose flight (the log) came inside its separation ellipsoid: the smallest value
    of |dp / scale| (below 1: inside) in the flight and in the check, and the least the check
    may reach (:func:`separation_kept`)."""

    pair: str  # "a-b"
    flown: float
    checked: float
    allowed: float

    @property
    def ok(self) -> bool:
        return self.checked >= self.allowed


@dataclass
class CheckResult:
    agents: list[AgentCheck]
    min_separation: float | None  # m, smallest surface distance between two agents
    separation_entries: int  # grid steps with some pair inside its separation ellipsoid
    contacts: list[str] = field(default_factory=list)  # "agent-obstacle at t", "agent-agent at t"
    separation_lost: int = 0  # grid steps with some pair deeper inside than it may be
    tight_pairs: list[TightPair] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(a.ok for a in self.agents) and not self.contacts and self.separation_lost == 0

    def to_json(self) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "agents": {
                a.id: {
                    "model": a.model,
                    "max_deviation_m": round(a.max_deviation, 4),
                    "limit_m": round(a.limit, 4),
                }
                for a in self.agents
            },
            "min_separation_m": None if self.min_separation is None else round(self.min_separation, 4),
            "separation_entries": self.separation_entries,
            "separation_lost": self.separation_lost,
            "flight_inside_separation": {
                p.pair: {
                    "flown": round(p.flown, 4),
                    "checked": round(p.checked, 4),
                    "allowed": round(p.allowed, 4),
                    "ok": p.ok,
                }
                for p in self.tight_pairs
            },
            "contacts": list(self.contacts),
        }

    def lines(self) -> list[str]:
        out = [f"{'agent':<12} {'model':<11} {'max dev m':>10} {'limit m':>9} {'ok':>4}"]
        for a in self.agents:
            out.append(
                f"{a.id:<12} {a.model:<11} {a.max_deviation:10.4f} {a.limit:9.4f} "
                f"{'yes' if a.ok else 'NO':>4}"
            )
        sep = "-" if self.min_separation is None else f"{self.min_separation:.4f} m"
        for p in self.tight_pairs:
            out.append(
                f"{p.pair}: inside its separation ellipsoid in the flight itself (|dp/scale| "
                f"{p.flown:.4f}); flown again {p.checked:.4f}, at least {p.allowed:.4f} allowed: "
                + ("kept" if p.ok else "LOST")
            )
        out.append(
            f"swarm: min separation (surface to surface) {sep}; separation ellipsoid entered at "
            f"{self.separation_entries} instants, deeper than allowed at {self.separation_lost}; "
            f"contacts {len(self.contacts)}"
            + (
                f" ({'; '.join(self.contacts[:5])}{' ...' if len(self.contacts) > 5 else ''})"
                if self.contacts
                else ""
            )
        )
        out.append("check: " + ("OK" if self.ok else "LIMIT BROKEN"))
        return out


def _fly_multirotor(plan: Plan, cfg: TrackerConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flown positions on the plan's times (and the planned ones), quadrotor from hover."""
    dt = cfg.dt
    t = plan.times
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    if plan.vel is not None and plan.acc is not None:
        interp = lambda a: np.column_stack([np.interp(grid, t, a[:, j]) for j in range(3)])  # noqa: E731
        ref = Reference(grid, interp(plan.pos)[None], interp(plan.vel)[None], interp(plan.acc)[None])
    else:
        ref = build_reference(t, plan.pos[None], np.zeros((1, 2, 3)), dt, "velocity")
    # Hover at the end for the settle time: the stop belongs to the flight.
    n_hold = int(np.ceil(cfg.settle_time / dt))
    if n_hold:
        times = np.concatenate([ref.times, ref.times[-1] + dt * np.arange(1, n_hold + 1)])
        hold = lambda a, v: np.concatenate([a, np.repeat(v, n_hold, axis=1)], axis=1)  # noqa: E731
        ref = Reference(
            times,
            hold(ref.pos, ref.pos[:, -1:]),
            hold(ref.vel, np.zeros_like(ref.vel[:, -1:])),
            hold(ref.acc, np.zeros_like(ref.acc[:, -1:])),
        )
    flight = simulate(ref, cfg)
    return ref.times, flight.pos[0], ref.pos[0]


def _fly_crazyflies(
    plans: list[Plan], settle_time: float
) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Flown positions at the commander's ticks (and the planned ones) of Crazyflie plans, flown
    together when they start together; each holds its last set-point (at rest) after its end,
    until the last of them has ended and the settle time has passed."""
    cf = Crazyflie()
    out: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for t0 in sorted({float(p.times[0]) for p in plans}):
        group = [p for p in plans if float(p.times[0]) == t0]
        n = max(len(p.times) for p in group) + int(np.ceil(settle_time / cf.commander_dt))
        times = t0 + cf.commander_dt * np.arange(n)

        def held(a: np.ndarray | None, derivative: bool, n: int = n) -> np.ndarray:
            assert a is not None
            end = np.zeros(3) if derivative else a[-1]
            return np.concatenate([a, np.repeat(end[None], n - len(a), axis=0)])

        sp = Setpoints(
            times,
            np.stack([held(p.pos, False) for p in group]),
            np.stack([held(p.vel, True) for p in group]),
            np.stack([held(p.acc, True) for p in group]),
            np.stack([held(p.jerk, True) for p in group]),
        )
        flight = fly_crazyflie(sp, cf)
        for a, p in enumerate(group):
            out[p.id] = (times, flight.pos[a], sp.pos[a])
    return out


def crazyflie_limit(plan: Plan) -> float:
    """How far a Crazyflie may be from its trajectory: what its firmware's controller achieves
    on it, the lag at the trajectory's top speed and acceleration
    (:meth:`~swarmplan.track.crazyflie.Crazyflie.tracking_lag`). Farther means the vehicle could
    not follow the trajectory (a motor at its cap, body rates it cannot reach, a fall)."""
    assert plan.vel is not None and plan.acc is not None
    top = lambda a: float(np.linalg.norm(a, axis=1).max())  # noqa: E731
    return Crazyflie().tracking_lag(top(plan.vel), top(plan.acc))


def _fly_fixed_wing(
    plan: Plan, world: dict[str, Any], rec_dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    ac = aircraft_of(world, plan.id)
    flight = fly(plan.times, plan.pos, ac, FixedWingConfig(), rec_dt)
    return flight.times, flight.pos, flight.ref_pos, error_limit(ac)


def check(rec: Recording, plans: list[Plan], cfg: TrackerConfig) -> CheckResult:
    """Fly ``plans`` and check them one by one and together (module docstring)."""
    flown: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    agents: list[AgentCheck] = []
    crazyflies = _fly_crazyflies([p for p in plans if p.vehicle == "crazyflie"], cfg.settle_time)
    for plan in plans:
        if plan.id in crazyflies:
            times, pos, ref_pos = crazyflies[plan.id]
            limit = crazyflie_limit(plan)
        elif plan.model == "fixed_wing":
            times, pos, ref_pos, limit = _fly_fixed_wing(plan, rec.world, rec.dt)
        else:
            times, pos, ref_pos = _fly_multirotor(plan, cfg)
            limit = plan.bound
        if plan.path_only:
            dev = float(path_distance(pos, ref_pos).max())
        else:
            dev = float(np.linalg.norm(pos - ref_pos, axis=1).max())
        agents.append(AgentCheck(plan.id, plan.model, dev, limit))
        flown[plan.id] = (times, pos)
    radii = np.array([p.radius for p in plans])
    speeds = [np.linalg.norm(np.diff(p.pos, axis=0), axis=1) / np.diff(p.times) for p in plans]
    vmax = max(float(s.max()) if len(s) else 0.0 for s in speeds)
    # Contacts between samples: the grid moves an agent at most half its radius per step.
    step = min(rec.dt, float(radii.min()) / (2.0 * max(vmax, 1e-9)))
    end = max(float(flown[p.id][0][-1]) for p in plans)
    grid = np.arange(0.0, end + 0.5 * step, step)
    pos = np.stack(
        [np.column_stack([np.interp(grid, *_tp(flown[p.id], j)) for j in range(3)]) for p in plans]
    )  # (A, T, 3): before its start an agent is where it starts, after its end where it ends
    min_sep = None
    entries = lost = 0
    contacts: list[str] = []
    tight: list[TightPair] = []
    ids = [p.id for p in plans]
    if len(plans) >= 2:
        i, j = np.triu_indices(len(plans), 1)
        d = np.linalg.norm(pos[i] - pos[j], axis=2) - (radii[i] + radii[j])[:, None]
        min_sep = float(d.min())
        for k in np.flatnonzero((d < 0).any(axis=1)):
            contacts.append(f"{ids[i[k]]}-{ids[j[k]]} at t = {grid[int(np.argmax(d[k] < 0))]:.2f} s")
        depth, own, allowed = separation_kept(plans, pos, _log_positions(rec, ids, grid))
        entries = int((depth < 1.0).any(axis=0).sum())
        lost = int((depth < allowed[:, None]).any(axis=0).sum())
        for k in np.flatnonzero(own < 1.0):
            pair = f"{ids[i[k]]}-{ids[j[k]]}"
            tight.append(TightPair(pair, float(own[k]), float(depth[k].min()), float(allowed[k])))
    for oid, dist in body_distances(rec, ids, grid, pos, radii).items():
        hit = dist - radii[:, None] < 0
        for a in np.flatnonzero(hit.any(axis=1)):
            k = int(np.argmax(hit[a]))
            contacts.append(f"{ids[a]}-{oid} at t = {grid[k]:.2f} s")
    ground = heights(rec.world, pos)
    surface = "terrain" if (rec.world.get("terrain") or {}).get("peaks") else "ground"
    for a in np.flatnonzero((ground < radii[:, None]).any(axis=1)):
        k = int(np.argmax(ground[a] < radii[a]))
        contacts.append(f"{ids[a]}-{surface} at t = {grid[k]:.2f} s")
    return CheckResult(agents, min_sep, entries, contacts, lost, tight)


def ellipsoid_depth(plans: list[Plan], pos: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """|dp / scale| (P, T) of the pairs (i, j) of ``plans`` at positions ``pos`` (A, T, 3), scale
    their separation ellipsoid's semi-axes max(sep_i, sep_j) + r_i + r_j (as the simulator's near
    misses, :func:`~swarmplan.geometry.neighbours.separation_violations`): below 1 inside."""
    radii = np.array([p.radius for p in plans], float)
    sep = np.array([p.separation for p in plans], float)
    scale = np.maximum(sep[i], sep[j]) + (radii[i] + radii[j])[:, None]
    return np.linalg.norm((pos[i] - pos[j]) / scale[:, None, :], axis=2)


def separation_kept(
    plans: list[Plan], pos: np.ndarray, log: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The depth (P, T) of every pair (``np.triu_indices`` order) flown again at ``pos`` (A, T, 3),
    the least depth (P,) of the flight ``log`` on the same instants, and the least depth (P,)
    each pair may reach.

    A pair the flight kept outside its separation ellipsoid must stay outside (1). A pair the
    flight itself took inside it (the planner's law let it come that close: a near miss in the
    log) may come as deep as the flight did, less the two exports' accuracy bounds (each export
    may be that far from the flown path), measured across the ellipsoid's shortest semi-axis: an
    export that holds the flight's own closeness passes, one that comes closer than the flight
    and its bounds allow fails."""
    i, j = np.triu_indices(len(plans), 1)
    depth = ellipsoid_depth(plans, pos, i, j)
    flown = ellipsoid_depth(plans, log, i, j)
    own = np.where(np.isnan(flown), np.inf, flown).min(axis=1)
    radii = np.array([p.radius for p in plans], float)
    sep = np.array([p.separation for p in plans], float)
    shortest = (np.maximum(sep[i], sep[j]) + (radii[i] + radii[j])[:, None]).min(axis=1)
    bounds = np.array([p.bound for p in plans], float)
    allowed = np.where(own < 1.0, own - (bounds[i] + bounds[j]) / shortest, 1.0)
    return depth, own, allowed


def _log_positions(rec: Recording, ids: list[str], grid: np.ndarray) -> np.ndarray:
    """The flight's positions (A, T, 3) of agents ``ids`` at the instants ``grid``, straight
    between the log's samples (before the first where it starts, after the last where it ends)."""
    out = np.empty((len(ids), len(grid), 3))
    for a, aid in enumerate(ids):
        track = rec.positions[rec.agent_index(aid)]
        have = np.isfinite(track).all(axis=1)
        for k in range(3):
            out[a, :, k] = np.interp(grid, rec.times[have], track[have, k]) if have.any() else np.nan
    return out


def path_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance (N,) of each point to a densely drawn polyline (M, 3): to the two segments at the
    polyline's vertex nearest to it (never less than the distance to the whole polyline)."""
    from scipy.spatial import cKDTree

    _, j = cKDTree(polyline).query(points)
    out = np.linalg.norm(points - polyline[j], axis=1)
    for lo in (j - 1, j):
        lo = np.clip(lo, 0, len(polyline) - 2)
        a, b = polyline[lo], polyline[lo + 1]
        ab = b - a
        t = np.clip(
            np.einsum("ij,ij->i", points - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0, 1
        )
        out = np.minimum(out, np.linalg.norm(points - (a + t[:, None] * ab), axis=1))
    return out


def _tp(tp: tuple[np.ndarray, np.ndarray], j: int) -> tuple[np.ndarray, np.ndarray]:
    return tp[0], tp[1][:, j]
