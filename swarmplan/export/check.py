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
surface distance between two agents, whether any pair came inside its separation ellipsoid,
and any contact with an obstacle (moving ones where the log has them), the ground or terrain.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarmplan.geometry.neighbours import separation_violations
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


@dataclass
class CheckResult:
    agents: list[AgentCheck]
    min_separation: float | None  # m, smallest surface distance between two agents
    separation_entries: int  # grid steps with some pair inside its separation ellipsoid
    contacts: list[str] = field(default_factory=list)  # "agent-obstacle at t"

    @property
    def ok(self) -> bool:
        return all(a.ok for a in self.agents) and not self.contacts and self.separation_entries == 0

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
        out.append(
            f"swarm: min separation (surface to surface) {sep}; separation ellipsoid entered at "
            f"{self.separation_entries} instants; contacts {len(self.contacts)}"
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
    entries = 0
    if len(plans) >= 2:
        i, j = np.triu_indices(len(plans), 1)
        d = np.linalg.norm(pos[i] - pos[j], axis=2) - (radii[i] + radii[j])[:, None]
        min_sep = float(d.min())
        sep = np.array([p.separation for p in plans], float)
        active = np.ones(len(plans), bool)
        for k in range(len(grid)):
            pi, _ = separation_violations(pos[:, k], sep, radii, active)
            entries += int(len(pi) > 0)
    contacts: list[str] = []
    ids = [p.id for p in plans]
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
    return CheckResult(agents, min_sep, entries, contacts)


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
