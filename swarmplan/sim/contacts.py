"""Contacts and arrivals: where a crashing agent stops, collisions, goals reached, and near
misses between agents."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.core import Event, Mode, SwarmState
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.collision import first_hits, segment_segment_min_distance
from swarmplan.geometry.neighbours import agent_contacts_indexed, separation_violations
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module, read_only, use_compiled_checks
from swarmplan.sim.metrics import NOTHING, Tally
from swarmplan.sim.modes import PARKED, mode_in
from swarmplan.sim.obstacles import Obstacles
from swarmplan.sim.safety import StepWindow
from swarmplan.world.motion import poses_at

CRASH_DEPTH = 0.02
"""Metres a crashed agent is recorded past its first contact (see :func:`crash_point`)."""

CONTACT_TOL = 1e-3
"""Metres of penetration that make a contact (the replay's audit uses the same)."""


def crash_point(
    obstacles: Obstacles, radius: np.float64, p0: np.ndarray, p1: np.ndarray, t0: float, dt: float
) -> np.ndarray:
    """Where the agent strikes on the step ``p0 → p1``: it stops there instead of flying on.

    Bisection on the swept check finds the first contact; the crash is recorded
    ``CRASH_DEPTH`` past it (bodies overlap in a crash), so an audit from positions alone
    sees the contact, and an agent never appears on the far side of a thin obstacle.
    """
    mv = obstacles.moving_mask
    r = radius
    step = p1 - p0
    length = float(np.linalg.norm(step))
    if length < 1e-12:
        return p1.copy()

    def hits(s: float) -> bool:
        qa = poses_at(obstacles.world.obstacles, t0)[0][mv]
        qb = poses_at(obstacles.world.obstacles, t0 + s * dt)[0][mv]
        return (
            first_hits(obstacles.collision, p0[None], (p0 + s * step)[None], r[None], qa, qb)[0] is not None
        )

    lo, hi = 0.0, 1.0
    if not hits(hi):  # a contact only another check saw (e.g. agent-agent): keep the step
        return p1.copy()
    while (hi - lo) * length > 1e-4:
        mid = 0.5 * (lo + hi)
        if hits(mid):
            hi = mid
        else:
            lo = mid
    return p0 + min(1.0, hi + CRASH_DEPTH / length) * step


def collide(s: SwarmState, ids: tuple[str, ...], i: int, other: str, t1: float) -> Tally:
    """Agent ``i`` touched ``other`` (an obstacle id, an agent id or 'bounds'): it stops flying.
    Returns the collision (nothing when the agent had already collided)."""
    if s.mode[i] == Mode.COLLIDED:
        return NOTHING
    s.mode[i] = Mode.COLLIDED
    s.segment[i] = None
    return Tally(
        events=(Event(t1, ids[i], "collision", {"other": other}),),
        counts=(("collisions", i),),
        contacts=((i, other),),
    )


def parked_contacts(
    s: SwarmState, ids: tuple[str, ...], clearance: np.ndarray, nearest: Callable[[int], str], t1: float
) -> Tally:
    """Agents that no longer fly, failed ones (they stay where they gave up, in the air) and
    arrived ones (they hover at their goals), touched by an obstacle at the committed step:
    ``clearance`` (N,) is every agent's obstacle clearance at its position, ``nearest(i)`` the
    id of the obstacle nearest agent ``i`` (asked only of the agents touched). Such a contact
    is a collision, as the replay's audit counts it (a penetration deeper than 1 mm at a
    recorded step)."""
    out = NOTHING
    parked = mode_in(s.mode, PARKED)
    for i in np.flatnonzero(parked & (clearance < -CONTACT_TOL)).tolist():
        out += collide(s, ids, i, nearest(i), t1)
    return out


def arrivals(
    s: SwarmState,
    ids: tuple[str, ...],
    pos0: np.ndarray,
    pos1: np.ndarray,
    vel1: np.ndarray,
    tolerance: float,
    t1: float,
    stop_speed: np.ndarray,
    active: np.ndarray | None = None,
    compiled: bool | None = None,
) -> Tally:
    """Agents whose step passed within ``tolerance`` of their goal, slowly enough to stop there,
    have arrived (and stop: their mode and their row of ``vel1`` change). Returns the arrivals.

    An arrived agent is frozen: its next step is zero. A multirotor may only change its velocity
    by ``max_accel * dt`` per step, so it counts as arrived only once its speed is at most that
    (``stop_speed``, per agent; ``inf`` for fixed wings, which never hover and keep the plain
    tolerance rule). The goal braking of ``SafetyFilter.braking_margin`` makes multirotors enter
    the tolerance at that speed, so they arrive where they first enter it (the replay's audit
    convention); should one enter faster, it keeps flying under the goal attraction, whose
    speed profile ``sqrt(2 * 0.8 * max_accel * d)`` (``swarmplan.flight.apf.commanded_velocity``)
    brings it to rest at the goal, and arrives once slow enough. ``active``: ``s.active`` when
    the caller has it at hand; ``compiled``: whether the world runs its checks compiled (None: by its
    size, ``runtime.compiled.use_compiled_checks``).
    """
    active = s.active if active is None else active
    if not (use_compiled_checks(len(ids)) if compiled is None else compiled):
        # Below swarm size: numpy (the same answers as the kernel).
        flying = np.flatnonzero(active)
        d = segment_segment_min_distance(pos0[flying], pos1[flying], s.goal[flying], s.goal[flying])
        arrive = (d <= tolerance) & (norm3(vel1[flying]) <= stop_speed[flying] * (1.0 + 1e-9))
        rows, dmins = flying[arrive], d[arrive]
    else:
        # Compiled: segment_segment_min_distance to the goal and the speed test, term for term.
        rows, dmins = kernel_module("swarmplan.geometry.swept_kernels").arrivals(
            np.ascontiguousarray(pos0, dtype=float),
            np.ascontiguousarray(pos1, dtype=float),
            np.ascontiguousarray(s.goal, dtype=float),
            np.ascontiguousarray(vel1, dtype=float),
            np.ascontiguousarray(active, dtype=bool),
            read_only(np.ascontiguousarray(stop_speed, dtype=float)),
            float(tolerance),
        )
    if not len(rows):
        return NOTHING
    events = []
    for i, dmin in zip(rows.tolist(), dmins.tolist(), strict=True):
        s.mode[i] = Mode.ARRIVED
        vel1[i] = 0.0
        s.segment[i] = None
        events.append(Event(t1, ids[i], "arrived", {"distance": round(dmin, 6)}))
    return Tally(events=tuple(events), arrivals=tuple((i, t1) for i in rows.tolist()))


class NearMisses:
    """Pairs of agents inside each other's separation ellipsoid, remembered between steps."""

    def __init__(self, params: AgentParams):
        self.params = params
        self._n = len(params.ids)
        self._compiled = use_compiled_checks(self._n, bool(params.fixed_wing.any()))
        # The pairs inside at the last update, as sorted keys i * n + j (i < j).
        self._near = np.zeros(0, dtype=np.int64)
        self._separation = np.ascontiguousarray(params.separation, dtype=float)
        self._radius = np.ascontiguousarray(params.radius, dtype=float)

    def update(self, pos: np.ndarray, active: np.ndarray, t1: float) -> Tally:
        """A pair entering each other's separation ellipsoid is a near miss (reported once per
        entry). Returns the near misses of this step."""
        if len(pos) < 2:
            return NOTHING
        # The pairs of ``separation_violations`` (sorted keys i * n + j, i.e. the all-pairs
        # row-major order: same events, same order), from a compiled sweep and prune at swarm size.
        if not self._compiled:
            pi, pj = separation_violations(pos, self.params.separation, self.params.radius, active)
            keys = pi.astype(np.int64) * self._n + pj
        else:
            keys = kernel_module("swarmplan.geometry.swept_kernels").separation_keys(
                np.ascontiguousarray(pos, dtype=float),
                self._separation,
                self._radius,
                np.ascontiguousarray(active, dtype=bool),
            )
        # Both key arrays are sorted and unique: membership by binary search.
        near = self._near
        self._near = keys
        if len(near):
            at = np.searchsorted(near, keys)
            new = near[np.minimum(at, len(near) - 1)] != keys
            if not new.any():
                return NOTHING
            keys = keys[new]
        if not len(keys):
            return NOTHING
        pi, pj = keys // self._n, keys % self._n
        events, counts = [], []
        for i, j in zip(pi.tolist(), pj.tolist(), strict=True):
            dist = float(np.linalg.norm(pos[i] - pos[j]))
            counts += [("near_misses", i), ("near_misses", j)]
            events.append(
                Event(
                    t1,
                    self.params.ids[i],
                    "near_miss",
                    {"other": self.params.ids[j], "distance": round(dist, 6)},
                )
            )
        return Tally(events=tuple(events), counts=tuple(counts))


def agent_collisions(
    s: SwarmState,
    ids: tuple[str, ...],
    pos0: np.ndarray,
    pos1: np.ndarray,
    radius: np.ndarray,
    active: np.ndarray,
    t1: float,
    compiled: bool | None = None,
) -> Tally:
    """The collisions of agents whose steps ``pos0`` -> ``pos1`` touch (``active``: who flew; an
    arrived agent touched is a collision too), each agent of a pair ended in turn; ``compiled``
    as for :func:`arrivals`."""
    tally = NOTHING
    for i, j in agent_contacts_indexed(pos0, pos1, radius, active, compiled=compiled):
        for a, b in ((i, j), (j, i)):
            if s.mode[a] != Mode.COLLIDED:
                tally = tally + collide(s, ids, a, ids[b], t1)
    return tally


def committed_hits(
    obstacles: Obstacles,
    s: SwarmState,
    ids: tuple[str, ...],
    check: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    velocity: np.ndarray,
    window: StepWindow,
) -> tuple[Tally, bool]:
    """Contact on the committed steps ``start`` -> ``end`` of agents ``check`` (those the safety
    filter did not clear with a margin) ends them: each stops at its crash point (``end`` and
    ``velocity`` changed in place). The collisions, and whether any step touched."""
    if not len(check):
        return NOTHING, False
    radius, mv, dt = obstacles.params.radius, obstacles.moving_mask, obstacles.world.dt
    hits = first_hits(
        obstacles.collision, start[check], end[check], radius[check], window.q0[mv], window.q1[mv]
    )
    tally, touched = NOTHING, False
    for i, hit in zip(check, hits, strict=True):
        if hit is not None:
            touched = True
            tally = tally + collide(s, ids, i, hit, window.t1)
            end[i] = crash_point(obstacles, radius[i], start[i], end[i], window.t0, dt)
            velocity[i] = 0.0
    return tally, touched
