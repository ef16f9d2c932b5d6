"""Escape planning: a short optimized segment out of a local minimum of the potential field.

When the simulation reports an agent stuck (``Planner.on_stuck``):

1. a **sub-goal** is chosen on the ray to the goal: past the obstacles that block the ray
   (the first point beyond them with the required clearance), at least ``horizon`` metres
   out, or the goal itself when it is nearer;
2. the segment ``agent → K free waypoints → sub-goal`` is optimized with the world's
   optimizer (``planner.optimizer``: name, population, iterations → max_evals =
   population × iterations, params) using the simulation's seeded stream for that purpose
   and agent (``sim.rng_for``); the cost
   (:mod:`swarmplan.planner.segment_cost`) scores the whole population in one call;
3. the best segment is **validated with FCL**: every leg swept with the agent radius plus
   a margin against the static obstacles, terrain and bounds; if it touches something
   the search is retried with a larger horizon and budget (``retries`` times);
4. the valid segment is shortcut (FCL) and its corners are turned into paper 004's arcs
   (§6, radius v²/a at cruise or the fixed wing's minimum turn radius); a corner whose arc
   does not fit or touches something keeps its corner (004's "special broken point"); a
   fixed wing's is made a Dubins chain from its own pose (``EscapePlanner.fillet``).

Deadlocks between agents (two stuck agents close together, e.g. at a narrow gap) are
resolved by priority: the agent with the higher index steps aside (a yield segment to a
point off the other's path, optimized the same way), the other one goes through.

Every optimizer run is logged with ``sim.record_optimizer(i, "escape", name, result)``.

Settings (``planner.escape``, all optional): ``waypoints`` (K, 4), ``horizon`` (m, default
2 × apf influence), ``margin`` (m of clearance beyond the radius, influence / 10),
``fcl_margin`` (m, 3 % of the influence), ``retries`` (2), ``growth`` (1.5, horizon and budget factor per
retry), ``max_escapes`` (per agent before it holds, 25), ``rounds`` (3: planning rounds in a
row, each with its retries, that find no valid segment before the agent holds; between
rounds the agent holds on under APF — other agents and moving obstacles move on, so a later
round may find a way — and an ``escape_deferred`` event is logged).

No giving up: after ``rounds`` failed rounds, or ``max_escapes`` escapes, the agent holds
(:mod:`swarmplan.planner.hold`) and plans again wider; a fixed wing with no room to loiter
flies towards free volume (or on under the field) and plans again. This planner never answers
``failed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan import optimizers
from swarmplan.core import (
    SEGMENT_REPULSION_SCALE,
    Mode,
    PlannedSegment,
    PlanningContext,
    StuckOutcome,
)
from swarmplan.flight.apf import current_reach, stopping_reach
from swarmplan.flight.field_law import clearance_at, ground_range
from swarmplan.geometry.polyline import dubins_chain, fillet_path
from swarmplan.planner.cores import polyline_core_hit, static_leg_hit
from swarmplan.planner.escape_gates import (
    CROWD,
    StandDowns,
    held_by,
    held_by_obstacles,
)
from swarmplan.planner.hold import holding_pattern
from swarmplan.planner.movers import EscapeClock, moving_clearance, moving_leg_hit, predicted_window
from swarmplan.planner.segment_cost import Flyer, Intent, SegmentCost, SegmentEncoding, agent_intents


def escape_settings(world) -> dict:
    """``planner.escape`` of ``world`` merged over the defaults (validated by the world parser)."""
    return dict(world.planner_config.escape)


def model_turn_radius(sim: PlanningContext, i: int) -> float:
    """Minimum turn radius of agent ``i``: ``min_turn_radius`` (fixed wing) or v²/a (paper 004 eq 34)."""
    p = sim.params
    if p.fixed_wing[i]:
        return float(p.min_turn_radius[i])
    return float(p.speed_cruise[i]) ** 2 / max(float(p.max_accel[i]), 1e-9)


CHAIN_RADIUS_FACTOR = 1.25  # a fixed wing's segments turn at this x its minimum radius (fillet)

# An escape around a blocker is about this many times longer than the straight ray to the
# sub-goal: movers are looked at until the agent would get there on such a detour.
DETOUR = 2.0


def static_clearance(sim: PlanningContext, pts: np.ndarray, radius: float) -> np.ndarray:
    """Clearance (surface distance minus ``radius``) of ``pts`` to static obstacles, floor and bounds."""
    w = sim.world
    pts = np.atleast_2d(pts)
    clear = pts[:, 2] - w.terrain_height(pts[:, :2]) - radius
    clear = np.minimum(clear, (np.minimum(pts - w.bounds_min, w.bounds_max - pts) - radius).min(axis=1))
    static = ~sim.moving_mask
    if static.any():
        d, _ = sim.distances.query(pts)
        clear = np.minimum(clear, d[:, static].min(axis=1) - radius)
    return clear


def predicted_clearance(
    sim: PlanningContext, pts: np.ndarray, radius: float, t_lo: np.ndarray, t_hi: np.ndarray, cap: float
) -> np.ndarray:
    """:func:`static_clearance` of ``pts``, lowered by the moving obstacles wherever they are
    predicted in each point's time window ``t_lo``..``t_hi`` (exact up to ``cap``)."""
    clear = static_clearance(sim, pts, radius)
    return np.minimum(clear, moving_clearance(sim, pts, radius, t_lo, t_hi, cap=cap))


def choose_subgoal(
    sim: PlanningContext, i: int, horizon: float, need: float, squeeze: float | None = None
) -> np.ndarray:
    """Point on the ray to the goal past whatever blocks it, at least ``horizon`` out, or the
    goal when that is nearer. A blocker is a stretch of the ray with clearance below ``need``
    that somewhere falls below ``squeeze`` (default: the escape ``margin``); the sub-goal is
    the first point past the first blocker with ``need``.

    Moving obstacles block the ray where they are predicted while the agent would get there
    (:mod:`swarmplan.planner.movers`: from flying the ray straight to flying ``DETOUR`` times
    as far, plus the timing slack): a parked mover is a blocker like a static one."""
    s = sim.state
    p, g = s.position[i], s.goal[i]
    guide = getattr(sim, "guide", None)  # guided: the way round static obstacles, not through them
    if guide is not None and guide.guided[i]:
        g = guide.way_point(p, g, horizon)
    d = g - p
    dist = float(np.linalg.norm(d))
    if dist <= horizon:
        return g.copy()
    u = d / dist
    step = max(0.5, dist / 400)
    ts = np.arange(0.0, dist, step)
    t_lo, t_hi = predicted_window(EscapeClock.of(sim, i), ts, DETOUR)
    clear = predicted_clearance(sim, p + ts[:, None] * u, float(sim.params.radius[i]), t_lo, t_hi, need)
    blocked = np.flatnonzero(clear < need)
    blocked = blocked[ts[blocked] > 0.5]
    t_end = horizon
    runs = np.split(blocked, np.flatnonzero(np.diff(blocked) > 1) + 1) if len(blocked) else []
    # A stretch that keeps ``squeeze`` only grazes something (the ray runs along a corridor's
    # wall): the agent can fly it, so it does not block. Treating it as the blocker put the
    # sub-goal in front of the mover parked across the corridor (parked_mover_corridor).
    squeeze = float(escape_settings(sim.world)["margin"]) if squeeze is None else squeeze
    runs = [run for run in runs if clear[run].min() < squeeze]
    if runs:
        # Only the first blocking stretch matters; later ones are for later escapes.
        after = np.flatnonzero((np.arange(len(ts)) > runs[0][-1]) & (clear >= need))
        first_free = ts[after[0]] + need if len(after) else dist
        t_end = max(horizon, first_free)
    if t_end >= dist - 1e-9:
        return g.copy()
    return p + t_end * u


def mover_leg_hit(
    sim: PlanningContext, i: int, a: np.ndarray, b: np.ndarray, s_a: float, margin: float
) -> str | None:
    """Id of a moving obstacle that agent ``i`` (radius + ``margin``) would touch on the escape leg
    ``a`` → ``b`` starting ``s_a`` metres into the escape (FCL, at the movers' predicted poses
    with the timing slack of :mod:`swarmplan.planner.movers`), else None.

    On the first leg the margin is what the agent has from the movers now (it may be stuck
    closer than ``margin`` to a parked one): the leg must not get closer, then must clear."""
    if not sim.moving_mask.any():
        return None
    r = float(sim.params.radius[i])
    if s_a <= 0.0:
        now = float(moving_clearance(sim, sim.state.position[i], r, sim.state.t, sim.state.t)[0])
        margin = min(margin, max(0.0, 0.5 * now))
    return moving_leg_hit(sim, EscapeClock.of(sim, i), a, b, s_a, r + margin)


@dataclass
class EscapeOutcome:
    waypoints: np.ndarray | None  # (K+1, 3) without the start, or None when nothing valid was found
    attempts: int
    costs: list[float]


class EscapePlanner:
    """Plans escape and yield segments for one simulation (holds the optimizer and settings)."""

    def __init__(self, world, optimizer_name: str):
        self.world = world
        self.name = optimizer_name
        self.cfg = escape_settings(world)
        opt = world.planner_config.optimizer
        self.population = opt.population
        self.iterations = opt.iterations
        params = dict(opt.params)
        # The params are the world's for this algorithm (``run.apply_overrides`` clears them when
        # --optimizer names another one); wrong ones were reported by the world parser.
        self.optimizer = optimizers.make(optimizer_name, population=self.population, **params)
        self.escapes: dict[int, int] = {}
        self.pending: dict[int, object] = {}  # yield segments planned for other agents
        self.failures: dict[int, int] = {}  # planning rounds in a row without a valid segment
        self.holds: dict[int, int] = {}  # holding patterns flown, per agent (each widens the search)
        self._agent_reach: float | None = None  # of the field's agent term (only_agents_around)
        self._escaped_at: dict[int, float] = {}  # distance to the goal at the last escape
        self.stand_downs = StandDowns()  # which stuck agents the field is left to free

    # ------------------------------------------------------------------ validation

    def segment_hit(
        self, sim: PlanningContext, i: int, polyline: np.ndarray, start_clearance: float
    ) -> str | None:
        """What the first leg of ``polyline`` touching something (static, terrain, bounds) hits, else None.

        Each leg is swept with radius + ``fcl_margin``; the first leg starts at the agent,
        which may already be closer than that, so its margin is what the agent has."""
        col = sim.collision
        r = float(sim.params.radius[i])
        m = float(self.cfg["fcl_margin"])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(polyline, axis=0), axis=1))])
        for k in range(len(polyline) - 1):
            a, b = polyline[k], polyline[k + 1]
            rr = r + (min(m, max(0.0, 0.5 * start_clearance)) if k == 0 else m)
            hit = col.sweep_bounds(b) and "bounds"
            hit = hit or col.sweep_terrain(a, b, rr) or col.sweep_static(a, b, rr)
            hit = hit or mover_leg_hit(sim, i, a, b, float(arc[k]), m)
            if hit:
                return hit
        return None

    def shortcut(self, sim: PlanningContext, i: int, poly: np.ndarray, start_clearance: float) -> np.ndarray:
        """Greedy shortcutting: from each kept point jump to the farthest later one whose straight
        leg keeps the full clearance (radius + ``margin``, FCL) and enters no avoided threat core
        (:mod:`swarmplan.planner.cores`). Fewer, farther waypoints are also followed more
        firmly: the field's attraction grows with the target's distance."""
        r = float(sim.params.radius[i])
        m = float(self.cfg["margin"])
        kept = [0]
        j = 0
        arc = 0.0  # along the kept polyline, for the movers' predicted poses
        while j < len(poly) - 1:
            nxt = j + 1
            for k in range(len(poly) - 1, j + 1, -1):
                rr = r + (min(m, max(0.0, 0.5 * start_clearance)) if j == 0 else m)
                a, b = poly[j], poly[k]
                if not (static_leg_hit(sim, a, b, rr) or mover_leg_hit(sim, i, a, b, arc, m)):
                    nxt = k
                    break
            kept.append(nxt)
            arc += float(np.linalg.norm(poly[nxt] - poly[j]))
            j = nxt
        return poly[kept]

    def fillet(self, sim: PlanningContext, i: int, poly: np.ndarray) -> np.ndarray:
        """``poly`` (from the agent) with its corners turned into arcs of the agent's turn radius
        (paper 004 §6, :func:`~swarmplan.geometry.polyline.fillet_path`). An arc that FCL finds
        within radius + ``fcl_margin`` of something, that enters an avoided threat core, or that
        does not fit, keeps its corner.

        A fixed wing cannot stop at a corner: it gets a Dubins chain (:func:`dubins_chain`) from
        its pose straight to the end, or else through every point: the first FCL finds clear."""
        out = self._fillet(sim, i, poly)
        if not sim.params.fixed_wing[i] or len(out) < 2:
            return out
        # Wider than R_min: the waypoint follower has room to correct a lag.
        R = CHAIN_RADIUS_FACTOR * model_turn_radius(sim, i)
        r, v = float(sim.params.radius[i]), sim.state.velocity[i]
        clear = float(static_clearance(sim, out[0], r)[0])
        for chain in (dubins_chain(out[0], v, out[-1:], R), dubins_chain(out[0], v, out[1:], R)):
            if self.segment_hit(sim, i, chain, clear) is None and not polyline_core_hit(sim.world, chain, r):
                return chain
        return out

    def _fillet(self, sim: PlanningContext, i: int, poly: np.ndarray) -> np.ndarray:
        col = sim.collision
        m = float(self.cfg["fcl_margin"])
        rr = float(sim.params.radius[i]) + m
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))])

        def hits(arc: np.ndarray) -> bool:
            # Distance flown when the arc starts (for the movers' predicted poses): the arc
            # replaces the corner nearest its middle, starting one tangent length before it.
            k = int(np.argmin(np.linalg.norm(poly - arc[len(arc) // 2], axis=1)))
            flown = max(0.0, float(cum[k]) - float(np.linalg.norm(poly[k] - arc[0])))
            steps = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(arc, axis=0), axis=1))])
            return any(
                col.sweep_bounds(b)
                or static_leg_hit(sim, a, b, rr)
                or mover_leg_hit(sim, i, a, b, flown + float(s0), m)
                for a, b, s0 in zip(arc[:-1], arc[1:], steps[:-1], strict=True)
            )

        return fillet_path(poly, model_turn_radius(sim, i), collision_check=hits).points

    # ------------------------------------------------------------------ planning

    def make_cost(
        self,
        sim,
        i: int,
        margin: float,
        extra: dict[int, Intent] | None = None,
        ignore: set[int] | None = None,
    ) -> SegmentCost:
        s, p = sim.state, sim.params
        r = float(p.radius[i])
        start_clear = float(static_clearance(sim, s.position[i], r)[0])
        v = s.velocity[i]
        intents = [it for j, it in self._intents(sim, i, extra).items() if not ignore or j not in ignore]
        speed, climb, floor = float(p.speed_cruise[i]), float(p.max_climb[i]), float(p.min_altitude[i])
        flyer = Flyer(r, speed, model_turn_radius(sim, i), climb, floor, bool(p.fixed_wing[i]))
        return SegmentCost(
            sim.world,
            flyer,
            t0=s.t,
            margin=margin,
            heading=v if np.linalg.norm(v) > 0.5 else None,
            start_clearance=start_clear,
            intents=intents,
            vertex_clearance=self.vertex_clearance(sim),
        )

    @staticmethod
    def vertex_clearance(sim: PlanningContext) -> float:
        """Clearance a waypoint needs so the agent can reach it: the static repulsion the
        simulation keeps along a segment (the field's law with SEGMENT_REPULSION_SCALE k_rep)
        must not exceed the attraction k_att * 1.5 m at the waypoint (reached within ~2 m)."""
        apf = sim.world.planner_config.apf
        return clearance_at(1.5 * apf.k_att, SEGMENT_REPULSION_SCALE * apf.k_rep, apf.influence)

    def _intents(self, sim: PlanningContext, i: int, extra: dict[int, Intent] | None) -> dict[int, Intent]:
        others = [j for j in range(sim.n) if j != i and sim.state.mode[j] not in (Mode.COLLIDED, Mode.FAILED)]
        its = agent_intents(sim, i, extra=extra)
        return dict(zip(others, its, strict=True))

    def optimize_segment(
        self,
        sim,
        i: int,
        end: np.ndarray,
        purpose: str,
        width: float,
        budget_factor: float = 1.0,
        extra: dict[int, Intent] | None = None,
        ignore: set[int] | None = None,
        n_free: int | None = None,
    ) -> tuple[np.ndarray, float, SegmentCost]:
        """Optimize one segment from agent ``i`` to ``end``; returns (polyline, cost, cost model)."""
        s = sim.state
        w = sim.world
        r = float(sim.params.radius[i])
        k = int(n_free or self.cfg["waypoints"])
        # Keep waypoints where the potential field lets the agent reach them: an influence from
        # the bounds' faces (beyond every surface's push, its braking distance four times over:
        # a box out to the faces' shorter push led escapes into a small room's corners) and out
        # of the ground's repulsion (see swarmplan.flight.apf).
        rho0 = w.planner_config.apf.influence
        rb0 = rho0
        floor = max(float(sim.params.min_altitude[i]), w.terrain_clearance if w.peaks else 0.0)
        goal = s.goal[i]
        goal_height = float(goal[2] - w.terrain_height(goal[None, :2])[0])
        rho0_g = float(ground_range(rho0, floor, goal_height, r, not bool(sim.params.fixed_wing[i])))
        lo = w.bounds_min + r + rb0
        hi = w.bounds_max - r - rb0
        lo[2] = max(w.bounds_min[2] + r, floor + r + rho0_g)
        lo = np.minimum(lo, np.minimum(s.position[i], end))
        hi = np.maximum(hi, np.maximum(s.position[i], end))
        enc = SegmentEncoding(s.position[i], end, k, width=width, height=0.5 * width, lo=lo, hi=hi)
        cost = self.make_cost(sim, i, float(self.cfg["margin"]), extra, ignore)
        evals = max(self.population, int(self.population * self.iterations * budget_factor))
        x0 = seed_candidates(enc, width)
        # compiled code (the optimizer's kernels, the cost's kernel) loads before the timed run:
        # wall_ms measures planning; the one-time load is start-up (no random draws, same plan)
        self.optimizer.warm_up()
        cost(enc.decode(x0[:1]))
        res = self.optimizer.minimize(
            lambda X: cost(enc.decode(X)),
            enc.lower,
            enc.upper,
            max_evals=evals,
            seed=sim.rng_for(purpose, i),
            x0=x0,
        )
        sim.record_optimizer(i, purpose, self.name, res)
        return enc.decode(res.x)[0], float(res.f), cost

    def plan(
        self,
        sim,
        i: int,
        end_fn,
        purpose: str = "escape",
        extra: dict[int, Intent] | None = None,
        ignore: set[int] | None = None,
    ) -> EscapeOutcome:
        """Optimize, validate with FCL, retry with a larger horizon and budget."""
        cfg = self.cfg
        horizon = float(cfg["horizon"])
        r = float(sim.params.radius[i])
        start_clear = float(static_clearance(sim, sim.state.position[i], r)[0])
        costs = []
        # Each hold widens the next searches (up to the flight volume's size).
        extent = float(np.linalg.norm(sim.world.bounds_max - sim.world.bounds_min)) / max(horizon, 1e-9)
        widen = min(float(cfg["growth"]) ** self.holds.get(i, 0), max(1.0, extent))
        for attempt in range(int(cfg["retries"]) + 1):
            grow = float(cfg["growth"]) ** attempt * widen
            end = end_fn(horizon * grow)
            L = float(np.linalg.norm(end - sim.state.position[i]))
            width = 1.25 * max(L, horizon * grow)
            poly, f, _ = self.optimize_segment(sim, i, end, purpose, width, grow, extra, ignore)
            costs.append(f)
            if self.segment_hit(sim, i, poly, start_clear) is None:
                poly = self.fillet(sim, i, self.shortcut(sim, i, poly, start_clear))
                return EscapeOutcome(poly[1:], attempt + 1, costs)
        return EscapeOutcome(None, int(cfg["retries"]) + 1, costs)

    # ------------------------------------------------------------------ events

    def deadlock_partners(self, sim: PlanningContext, i: int) -> list[int]:
        """Other flying agents close to ``i`` and slow (or coming at it): a mutual blockage."""
        s, p = sim.state, sim.params
        out = []
        for j in np.flatnonzero(s.active):
            if j == i:
                continue
            sep = float(np.linalg.norm(np.maximum(p.separation[i], p.separation[j])))
            reach = 3.0 * (sep + p.radius[i] + p.radius[j])
            dp = s.position[j] - s.position[i]
            dist = float(np.linalg.norm(dp))
            if dist > reach:
                continue
            slow = np.linalg.norm(s.velocity[j]) < 0.5 * p.speed_cruise[j]
            towards = float(np.dot(s.velocity[j], -dp)) > 0.3 * dist * np.linalg.norm(s.velocity[j])
            if slow or towards:
                out.append(int(j))
        return out

    def yield_point(self, sim: PlanningContext, i: int, j: int, dist: float) -> np.ndarray:
        """A point ``dist`` to the side of the line between ``j`` and its goal, on ``i``'s side,
        where ``i`` waits out of ``j``'s way (the side with more clearance)."""
        s = sim.state
        pj, gj = s.position[j], s.goal[j]
        u = gj - pj
        u[2] = 0.0
        nu = np.linalg.norm(u)
        u = u / nu if nu > 1e-9 else np.array([1.0, 0.0, 0.0])
        side = np.array([-u[1], u[0], 0.0])
        r = float(sim.params.radius[i])
        best, best_c = None, -np.inf
        for sgn in (1.0, -1.0):
            for back in (0.0, 0.5, 1.0):
                q = s.position[i] + sgn * dist * side + back * dist * u
                q = np.clip(q, sim.world.bounds_min + r + 1, sim.world.bounds_max - r - 1)
                c = float(static_clearance(sim, q, r)[0])
                c = min(c, 2.0 * dist)  # enough clearance is enough: prefer the nearest
                score = c - 0.2 * back * dist
                if score > best_c:
                    best, best_c = q, score
        return best

    def only_agents_around(self, sim: PlanningContext, i: int) -> bool:
        """Whether other agents, not a trap, hold ``i``: ``CROWD`` or more flying agents within
        the reach of the field's agent term; or some, while the obstacles do not hold it (their
        push along its pull leaves it more than half the pull). Such a jam is the swarm's (the
        field's agent term, with its passing rules and priority near goals, and the other
        agents' own progress dissolve it); one agent's escape around its neighbours only adds
        a detour."""
        near = self.agents_near(sim, i)
        if not near.any():
            return False
        if near.sum() >= CROWD:
            return True  # in a crowd, obstacles or not: one agent's detour does not dissolve it
        return not held_by_obstacles(sim, i)

    def agents_near(self, sim: PlanningContext, i: int) -> np.ndarray:
        """Mask of the flying agents other than ``i`` within the reach of the field's agent term."""
        s, p = sim.state, sim.params
        if self._agent_reach is None:
            rho0 = float(sim.world.planner_config.apf.influence)
            self._agent_reach = current_reach(p, stopping_reach(p, sim.world.dt), rho0)
        near = (np.linalg.norm(s.position - s.position[i], axis=1) < self._agent_reach) & s.active
        near[i] = False
        return near

    def on_stuck(self, sim: PlanningContext, i: int) -> StuckOutcome:
        if i in self.pending:  # a yield planned for us by the agent we block
            return self.pending.pop(i)
        near, crowd = (lambda: self.agents_near(sim, i)), (lambda: self.only_agents_around(sim, i))
        gate = self.stand_downs.decide(sim, i, self._escaped_at.get(i), near, crowd)
        if gate is not None:
            sim.note_event(i, "escape_stood_down", {"gate": gate, "held_by": held_by(sim, i)})
            return None
        n_done = self.escapes.get(i, 0)
        if n_done >= int(self.cfg["max_escapes"]):
            self.escapes[i] = 0  # after holding, escapes are tried again (with wider searches)
            return self.hold(sim, i, f"{n_done} escapes without getting free")
        self.escapes[i] = n_done + 1
        self._escaped_at[i] = float(np.linalg.norm(sim.state.goal[i] - sim.state.position[i]))
        r = float(sim.params.radius[i])
        need = r + 2.0 * float(self.cfg["margin"])
        s = sim.state
        partners = [
            j for j in self.deadlock_partners(sim, i) if s.mode[j] == Mode.APF and j not in self.pending
        ]
        # Deadlock: the agent with the higher index steps aside, the other goes on.
        if any(j < i for j in partners):
            j = min(partners)
            q = self.yield_point(sim, i, j, self._yield_distance(sim, i))
            out = self.plan(sim, i, lambda _h, q=q: q, ignore={j})
            if out.waypoints is not None:
                return PlannedSegment(out.waypoints, mode=Mode.ESCAPE)
        extra = {}
        for j in partners:
            if j > i:
                q = self.yield_point(sim, j, i, self._yield_distance(sim, j))
                out = self.plan(sim, j, lambda _h, q=q, j=j: q, ignore={i})
                if out.waypoints is not None:
                    self.pending[j] = PlannedSegment(out.waypoints, mode=Mode.ESCAPE)
                    extra[j] = _intent_of(sim, j, out.waypoints)
        out = self.plan(sim, i, lambda h: choose_subgoal(sim, i, h, need), extra=extra)
        if out.waypoints is None:
            failures = self.failures.get(i, 0) + 1
            self.failures[i] = failures
            if failures >= int(self.cfg["rounds"]):
                self.failures[i] = 0
                return self.hold(sim, i, f"no valid escape segment in {failures} rounds")
            detail = {"round": failures, "attempts": out.attempts, "held_by": held_by(sim, i)}
            sim.note_event(i, "escape_deferred", detail)
            return None
        self.failures[i] = 0
        return PlannedSegment(out.waypoints, mode=Mode.ESCAPE)

    def hold(self, sim: PlanningContext, i: int, reason: str) -> StuckOutcome:
        """A holding pattern (:mod:`swarmplan.planner.hold`) instead of giving up; later searches
        are ``growth`` times wider per hold. A multirotor hovers; a fixed wing with no free
        loiter circle flies towards free volume (``hold.free_volume_waypoints``), or, with no
        free way there either, on under the field (None) until it plans again."""
        rounds = self.holds.get(i, 0) + 1
        self.holds[i] = rounds
        s = sim.state
        start_clear = float(static_clearance(sim, s.position[i], float(sim.params.radius[i]))[0])
        r = float(sim.params.radius[i])
        # A fixed wing with no free circle here: towards the nearest free volume, to hold there.
        pts, free_volume = holding_pattern(
            s.position[i],
            s.velocity[i],
            bool(sim.params.fixed_wing[i]),
            model_turn_radius(sim, i),
            float(sim.params.max_climb[i]),
            lambda q: static_clearance(sim, q, r),
            lambda poly: self.segment_hit(sim, i, poly, start_clear) is not None,
        )
        detail = {"reason": reason, "round": rounds, "possible": pts is not None, "held_by": held_by(sim, i)}
        if free_volume:
            detail["free_volume"] = True
        sim.note_event(i, "hold", detail)
        if pts is None:  # nothing free within reach: it flies on under the field and plans again
            return None
        return PlannedSegment(pts, mode=Mode.ESCAPE)

    def take_pending(self, sim: PlanningContext) -> dict[int, PlannedSegment]:
        """Yield segments planned for other agents, to start now (``Planner.on_step``)."""
        out = {j: seg for j, seg in self.pending.items() if sim.state.mode[j] == Mode.APF}
        self.pending = {}
        return out

    def _yield_distance(self, sim: PlanningContext, i: int) -> float:
        p = sim.params
        rho0 = float(sim.world.planner_config.apf.influence)
        return max(0.8 * rho0, 2.0 * (float(np.linalg.norm(p.separation[i])) + 2.0 * float(p.radius[i])))


def _intent_of(sim: PlanningContext, j: int, waypoints: np.ndarray) -> Intent:
    """Agent ``j`` flying ``waypoints`` from where it is at cruise speed."""
    s, p = sim.state, sim.params
    pts = np.vstack([s.position[j], waypoints])
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    times = s.t + np.concatenate([[0.0], np.cumsum(seg)]) / max(float(p.speed_cruise[j]), 0.1)
    return Intent(times[keep], pts[keep], float(p.radius[j]), p.separation[j])


def seed_candidates(enc: SegmentEncoding, width: float) -> np.ndarray:
    """A few structured starting points for the optimizer: the straight line, lateral detours
    on both sides (half and full width), and the same detours backing out first (a pocket)."""
    k = enc.k
    frac = np.arange(1, k + 1) / (k + 1)
    L = max(enc.length, 1.0)
    rows = [np.zeros((k, 3))]
    # Backing out: the first half of the waypoints go behind the start by most of the width.
    back = -(frac * L + 0.8 * width) * (frac <= 0.5)
    for side in (1.0, -1.0):
        for w in (0.5, 1.0):
            for along in (np.zeros(k), back):
                r = np.zeros((k, 3))
                r[:, 0] = along
                r[:, 1] = side * w * width
                rows.append(r)
    X = np.array([r.reshape(-1) for r in rows])
    return np.clip(X, enc.lower, enc.upper)
