"""Per-agent run metrics (path length, clearance, curvature, arrival, event counts) and the
summary report built from them.

Curvature is honest at cusps: a stop-and-reverse point (the flown direction turns by more
than 150° between consecutive steps, after dropping steps under 1 mm) is counted in
``cusps`` and left out of ``max_curvature`` / ``mean_curvature`` (its discrete "curvature"
is only 1/step length). ``curvature_limit`` is the model's (see :func:`curvature_limit`).

A multirotor may turn more tightly the slower it flies: what its model bounds is the lateral
acceleration ``v^2 kappa`` (``max_lateral_accel``, with ``v`` the mean speed of the two steps
at a vertex, cusps left out), reported beside ``max_accel``. ``curvature_violation`` flags a
real breach of the model: a fixed wing's curvature over 1.05 / min_turn_radius, a multirotor's
lateral acceleration over 1.05 max_accel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from swarmplan.core import Event, SwarmState
from swarmplan.geometry.polyline import curvature_with_cusps, curvatures_with_cusps
from swarmplan.geometry.vec3 import norm3
from swarmplan.sim.threats import exposure

if TYPE_CHECKING:
    from swarmplan.world.model import World


COUNTERS = (
    "collisions",
    "escapes",
    "stuck_events",
    "near_misses",
    "emergency_stops",
    "hard_stops",
    "guard_steps",
    "evasions",
)
"""The per-agent event counters of :class:`RunMetrics` a :class:`Tally` may add to."""


@dataclass(frozen=True)
class Tally:
    """What one part of a step changed besides the swarm state: the events it raised (in order)
    and what it adds to the run's per-agent metrics. The simulation merges it: the events into the
    step's events, the rest into :class:`RunMetrics` (:meth:`RunMetrics.merge`)."""

    events: tuple[Event, ...] = ()
    counts: tuple[tuple[str, int], ...] = ()
    """(counter of ``COUNTERS``, agent index): one more, once per entry."""
    arrivals: tuple[tuple[int, float], ...] = ()
    """(agent index, time): the agent arrived then."""
    contacts: tuple[tuple[int, str], ...] = ()
    """(agent index, what it touched: an obstacle id, an agent id or 'bounds')."""

    def __add__(self, other: Tally) -> Tally:
        return Tally(
            self.events + other.events,
            self.counts + other.counts,
            self.arrivals + other.arrivals,
            self.contacts + other.contacts,
        )


NOTHING = Tally()
"""The tally of a part of a step that changed nothing."""


class RunMetrics:
    """Accumulates what ``/summary`` reports, step by step."""

    def __init__(self, ids: tuple[str, ...], n_obstacles: int):
        n = len(ids)
        self.ids = ids
        self.path_length = np.zeros(n)
        self.min_clearance = np.full(n, np.inf)
        self.min_agent_clearance = np.full(n, np.inf)
        self.min_terrain_clearance = np.full(n, np.inf)
        self.arrival_time = np.full(n, np.nan)
        self.collisions = np.zeros(n, dtype=int)
        self.collided_with: list[list[str]] = [[] for _ in range(n)]
        self.escapes = np.zeros(n, dtype=int)
        self.escape_ms: list[list[float]] = [[] for _ in range(n)]
        self.optimizer_runs = np.zeros(n, dtype=int)
        self.stuck_events = np.zeros(n, dtype=int)
        self.near_misses = np.zeros(n, dtype=int)
        self.emergency_stops = np.zeros(n, dtype=int)
        self.hard_stops = np.zeros(n, dtype=int)  # stops within one step beyond max_accel (sim/safety.py)
        self.guard_steps = np.zeros(n, dtype=int)  # fixed-wing steps flown by the turn-ahead guard
        self.evasions = np.zeros(n, dtype=int)  # take-offs from a reached goal out of a threat's way
        self.positions: list[np.ndarray] = []  # per step (N, 3), for curvature
        self.flying: list[np.ndarray] = []  # per step (N,): who flew it (threat exposure)

    def measure_start(self, obstacle: np.ndarray, agent: np.ndarray, terrain: np.ndarray) -> None:
        """The clearances at t = 0 (to the obstacles, the other agents, the terrain) count too."""
        self.min_clearance = np.minimum(self.min_clearance, obstacle)
        self.min_agent_clearance = np.minimum(self.min_agent_clearance, agent)
        self.min_terrain_clearance = np.minimum(self.min_terrain_clearance, terrain)

    def add_step(
        self,
        pos0: np.ndarray,
        pos1: np.ndarray,
        active: np.ndarray,
        obstacle_clearance: np.ndarray,
        agent_clearance: np.ndarray,
        terrain_clearance: np.ndarray,
        flying: np.ndarray | None = None,
    ) -> None:
        """One step of every agent from ``pos0`` to ``pos1``: path length and clearances of the
        ``active`` (measured) agents; ``flying`` (default ``active``) marks those that flew it
        (not yet arrived), for the threat exposure."""
        if active.all():  # every agent measured (the simulation's case): no selection to make
            self.path_length += norm3(pos1 - pos0)
            self.min_clearance = np.minimum(self.min_clearance, obstacle_clearance)
            self.min_agent_clearance = np.minimum(self.min_agent_clearance, agent_clearance)
            self.min_terrain_clearance = np.minimum(self.min_terrain_clearance, terrain_clearance)
        else:
            self.path_length += np.where(active, norm3(pos1 - pos0), 0.0)
            self.min_clearance = np.where(
                active, np.minimum(self.min_clearance, obstacle_clearance), self.min_clearance
            )
            self.min_agent_clearance = np.where(
                active, np.minimum(self.min_agent_clearance, agent_clearance), self.min_agent_clearance
            )
            self.min_terrain_clearance = np.where(
                active, np.minimum(self.min_terrain_clearance, terrain_clearance), self.min_terrain_clearance
            )
        self.positions.append(pos1.copy())
        self.flying.append((active if flying is None else flying).copy())

    def merge(self, tally: Tally) -> None:
        """Add what one part of a step counted (its events go to the step, not here)."""
        for counter, i in tally.counts:
            if counter not in COUNTERS:
                raise ValueError(f"unknown run counter {counter!r} (known: {', '.join(COUNTERS)})")
            getattr(self, counter)[i] += 1
        for i, t in tally.arrivals:
            self.arrival_time[i] = t
        for i, other in tally.contacts:
            self.collided_with[i].append(other)

    def curvature(self, i: int, until: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(curvature, cusp mask) of agent ``i``'s flown path (see ``curvature_with_cusps``)."""
        pts = np.array([p[i] for p in self.positions[:until]])
        return curvature_with_cusps(pts)

    def lateral_accel(self, i: int, dt: float) -> float:
        """Max lateral acceleration (m/s^2) over agent ``i``'s non-cusp vertices (see
        :func:`lateral_accel_of`)."""
        pts = np.array([p[i] for p in self.positions])
        return max_lateral_accel(*curvature_with_cusps(pts, with_steps=True), dt)

    def curvatures(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per agent: (curvature, cusp mask, mean step, pace) of its flown path, all agents at once
        (``curvatures_with_cusps``; what :meth:`curvature` gives, with the steps)."""
        if not self.positions:
            return curvatures_with_cusps(np.zeros((0, len(self.ids), 3)))
        return curvatures_with_cusps(np.array(self.positions))


def max_lateral_accel(
    curv: np.ndarray, cusp: np.ndarray, mean_step: np.ndarray, pace: np.ndarray, dt: float
) -> float:
    """The largest lateral acceleration over the non-cusp vertices (0 without any)."""
    if not (~cusp).any():
        return 0.0
    return float(lateral_accel_of(curv[~cusp], mean_step[~cusp], pace[~cusp], dt).max())


def lateral_accel_of(curv: np.ndarray, mean_step: np.ndarray, pace: np.ndarray, dt: float) -> np.ndarray:
    """Lateral acceleration at vertices of curvature ``curv`` between steps of mean length
    ``mean_step``: ``v^2 kappa`` in its one-step form ``2 v sin(theta / 2) / dt``, the velocity
    change a turn by ``theta = kappa * mean_step`` at speed ``v = mean_step / dt`` needs (the
    two agree for small turns; for a sharp turn at low speed ``v^2 kappa`` overstates it),
    times the vertex's ``pace`` (``polyline.curvature_with_cusps``): a slow agent's steps merged
    over several sampling intervals are flown at their length over those intervals, and turn
    over their mean count of them."""
    v = mean_step / dt
    return 2.0 * v * np.sin(0.5 * curv * mean_step) / dt * pace


def curvature_limit(agent) -> float:
    """The model's curvature limit (1/m): 1/ρ with ρ = v²/a at cruise for a multirotor (paper 004
    eq 34; at speed v the limit is a/v², larger when slower), 1/min_turn_radius for a fixed wing."""
    if agent.model == "fixed_wing":
        return 1.0 / max(float(agent.min_turn_radius), 1e-9)
    return float(agent.max_accel) / max(float(agent.speed_cruise), 1e-9) ** 2


VIOLATION_MARGIN = 1.05
"""A curvature (fixed wing) or lateral acceleration (multirotor) counts as a breach of the model
above this factor of its limit."""


def curvature_violation(agent, max_curvature: float, max_lateral_accel: float) -> bool:
    """Whether the flown path breaks the model: a fixed wing turning tighter than its minimum
    radius, a multirotor turning with more lateral acceleration than ``max_accel`` (+5 %)."""
    if agent.model == "fixed_wing":
        return bool(max_curvature > VIOLATION_MARGIN * curvature_limit(agent))
    return bool(max_lateral_accel > VIOLATION_MARGIN * float(agent.max_accel))


def summary_report(
    world: World,
    s: SwarmState,
    metrics: RunMetrics,
    *,
    seed: int,
    optimizer: str,
    wall_time: float,
    interrupted: bool = False,
) -> dict[str, Any]:
    """Per-agent and overall metrics for ``/summary`` and the CLI table."""
    m = metrics
    n = len(m.ids)
    agents = []
    for i, (aid, (all_curv, cusp, mean_step, pace)) in enumerate(zip(m.ids, m.curvatures(), strict=True)):
        curv = all_curv[~cusp]  # a cusp has no finite curvature: counted apart
        agent = world.agents[i]
        max_curv = float(curv.max()) if len(curv) else 0.0
        lateral = max_lateral_accel(all_curv, cusp, mean_step, pace, world.dt)
        violation = curvature_violation(agent, max_curv, lateral)
        start = world.agents[i].start
        straight = float(np.linalg.norm(world.agents[i].goal - start))
        agents.append(
            {
                "id": aid,
                "arrived": not math.isnan(m.arrival_time[i]),
                "final_mode": str(s.mode[i]),
                "arrival_time": None if math.isnan(m.arrival_time[i]) else round(float(m.arrival_time[i]), 9),
                "path_length": round(float(m.path_length[i]), 6),
                "straight_line": round(straight, 6),
                "length_ratio": round(float(m.path_length[i]) / straight, 6) if straight > 0 else None,
                "min_clearance": _finite(min(m.min_clearance[i], m.min_agent_clearance[i])),
                "min_obstacle_clearance": _finite(m.min_clearance[i]),
                "min_agent_clearance": _finite(m.min_agent_clearance[i]),
                "min_terrain_clearance": _finite(m.min_terrain_clearance[i]),
                "max_curvature": round(float(curv.max()), 6) if len(curv) else 0.0,
                "mean_curvature": round(float(curv.mean()), 6) if len(curv) else 0.0,
                "cusps": int(cusp.sum()),
                "curvature_limit": round(curvature_limit(agent), 6),
                "max_lateral_accel": round(lateral, 6),
                "lateral_accel_limit": None
                if agent.model == "fixed_wing"
                else round(float(agent.max_accel), 6),
                "curvature_violation": violation,
                "collisions": int(m.collisions[i]),
                "collided_with": m.collided_with[i],
                "escapes": int(m.escapes[i]),
                "escape_planning_ms": [round(x, 3) for x in m.escape_ms[i]],
                "stuck_events": int(m.stuck_events[i]),
                "near_misses": int(m.near_misses[i]),
                "emergency_stops": int(m.emergency_stops[i]),
                "hard_stops": int(m.hard_stops[i]),
                "guard_steps": int(m.guard_steps[i]),
                "evasions": int(m.evasions[i]),
            }
        )
    if m.flying:  # threat exposure, in worlds with threats (sim/threats.py)
        exposed = exposure(world, np.array(m.positions[-len(m.flying) :]), np.array(m.flying))
        for a, e in zip(agents, exposed or [], strict=False):
            a.update(e)
    arrived = sum(a["arrived"] for a in agents)
    collisions = sum(a["collisions"] for a in agents)
    return {
        "t": round(s.t, 9),
        "world": world.name,
        "seed": seed,
        "optimizer": optimizer,
        "interrupted": interrupted,
        "success": bool(arrived == n and collisions == 0 and not interrupted),
        "sim_time": round(s.t, 9),
        "wall_time": round(wall_time, 6),
        "steps": s.step,
        "arrived": arrived,
        "agents_total": n,
        "collisions": collisions,
        "agents": agents,
    }


def _finite(x: float) -> float | None:
    return round(float(x), 6) if math.isfinite(x) else None
