"""The multi-UAV simulation: ``reset(seed=...)`` / ``step()`` in the manner of Gymnasium.

Each step, for every flying agent at once: potential-field command (or segment following
while escaping/smoothing) → kinematic limits → a swept FCL safety check of the step
(alternative feasible commands when the step would touch something) → the committed
step is checked again (contact ends the agent) → arrival, stuck and near-miss detection
→ recording. ``terminated`` means every agent arrived, collided or failed; ``truncated``
means ``sim.max_time`` ran out.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from swarmplan.apf import ApfGains, FieldInputs, apf_forces, commanded_velocity
from swarmplan.core import (
    FAILED,
    SEGMENT_MODES,
    Event,
    Mode,
    PlannedSegment,
    Planner,
    Recorder,
    StepResult,
    SwarmState,
)
from swarmplan.dynamics import AgentParams, initial_velocity, limit_velocity
from swarmplan.geometry.collision import (
    CollisionWorld,
    agent_contacts,
    first_hits,
    segment_segment_min_distance,
)
from swarmplan.geometry.rotation import matrix_to_quaternion
from swarmplan.geometry.shapes import ObstacleField, distance_and_gradient
from swarmplan.lookahead import guard_commands, horizon_steps
from swarmplan.metrics import RunMetrics
from swarmplan.motion import max_speed, poses_at
from swarmplan.world.model import World

CRASH_DEPTH = 0.02
"""Metres a crashed agent is recorded past its first contact (see ``Simulation._crash_point``)."""


class Simulation:
    """One run of a world. ``planner`` (optional) plans escapes and smoothing; ``recorder`` logs."""

    def __init__(self, world: World, planner: Planner | None = None, recorder: Recorder | None = None):
        self.world = world
        self.planner = planner
        self.recorder = recorder
        self.params = AgentParams.from_world(world)
        self.gains = ApfGains.from_world(world)
        self.collision = CollisionWorld(world)
        self.field = ObstacleField(world.obstacles)
        self.moving_mask = np.array([o.moving for o in world.obstacles], dtype=bool)
        self.bounding_radius = np.array([o.bounding_radius for o in world.obstacles])
        self._max_obstacle_speed = max((max_speed(o) for o in world.obstacles), default=0.0)
        self.moving_quat = [
            matrix_to_quaternion(o.rotation).round(9).tolist() for o in world.moving_obstacles
        ]
        self.n = len(world.agents)
        self.ids = self.params.ids
        self.state: SwarmState | None = None
        self.seed: int | None = None
        self.rng: np.random.Generator | None = None
        self.metrics: RunMetrics | None = None
        self.wall_start = 0.0
        self._events: list[Event] = []  # the running step's events (see note_event)
        self._planning_before_flight = False

    # ------------------------------------------------------------------ lifecycle

    def reset(self, seed: int | None = None) -> SwarmState:
        """Start the run at t = 0 with ``seed`` (default: the world's seed)."""
        self.seed = self.world.seed if seed is None else int(seed)
        self.rng = np.random.default_rng(self.seed)
        self._events = []
        start = np.array([a.start for a in self.world.agents], dtype=float)
        goal = np.array([a.goal for a in self.world.agents], dtype=float)
        self.state = SwarmState(
            t=0.0,
            step=0,
            position=start,
            velocity=initial_velocity(self.params, start, goal),
            goal=goal,
            mode=np.array([Mode.APF] * self.n, dtype=object),
            segment=[None] * self.n,
            segment_index=np.zeros(self.n, dtype=int),
            route=[None] * self.n,
            route_index=np.zeros(self.n, dtype=int),
        )
        self.metrics = RunMetrics(self.ids, len(self.world.obstacles))
        self.metrics.positions.append(start.copy())
        self._progress_ref = np.linalg.norm(goal - start, axis=1)
        self._progress_t = np.zeros(self.n)
        self._segment_ref: dict[int, tuple] = {}  # agent -> (waypoint index, distance, t, segment)
        self._near = np.zeros((self.n, self.n), dtype=bool)
        self._field_cache: tuple[np.ndarray, np.ndarray] | None = None
        self.interrupted = False
        self.wall_start = time.perf_counter()
        if self.recorder is not None:
            self.recorder.write_world(self.world_message())
        if self.planner is not None:
            self._planning_before_flight = True  # its events are logged as they come (see note_event)
            try:
                routes = self.planner.on_reset(self)
            finally:
                self._planning_before_flight = False
            for i, route in routes.items():
                self.state.route[i] = np.asarray(route, dtype=float)
            self._progress_ref = self._distance_to_go()
        if self.recorder is not None:
            self.recorder.write_state(0.0, self._agent_dicts(), self._obstacle_dicts(0.0))
        return self.state

    def record_optimizer(
        self, agent: int | None, purpose: str, algorithm: str, result: Any, t: float | None = None
    ) -> None:
        """Log one optimizer run (a ``swarmplan.optimizers.Result``) on ``/optimizer`` and in the metrics."""
        wall_ms = float(result.wall_time) * 1000.0
        if agent is not None and purpose == "escape":
            self.metrics.escape_ms[agent].append(wall_ms)
        if agent is not None:
            self.metrics.optimizer_runs[agent] += 1
        if self.recorder is not None:
            self.recorder.write_optimizer(
                {
                    "t": round(self.state.t if t is None else t, 9),
                    "agent": None if agent is None else self.ids[agent],
                    "algorithm": algorithm,
                    "purpose": purpose,
                    "evaluations": int(result.evaluations),
                    "iterations": int(result.iterations),
                    "best_cost": float(result.f),
                    "wall_ms": round(wall_ms, 3),
                    "convergence": [float(x) for x in result.history],
                }
            )

    def note_event(self, agent: int | None, kind: str, detail: dict[str, Any]) -> None:
        """An event the planner reports during ``step()`` (recorded with that step's events)."""
        if self.state is None:
            raise RuntimeError("call reset() before note_event()")
        event = Event(self.state.t, None if agent is None else self.ids[agent], kind, detail)
        if self._planning_before_flight:
            # Before the first step there is no step to carry it: it goes to the log at t = 0,
            # between the optimizer runs it follows.
            if self.recorder is not None:
                self.recorder.write_event(event.to_json())
            return
        self._events.append(event)

    def world_message(self) -> dict[str, Any]:
        return self.world.to_message(self.seed)

    # ------------------------------------------------------------------ one step

    def step(self) -> StepResult:
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        s = self.state
        w = self.world
        dt = w.dt
        events = self._events  # with any noted between steps
        t0, t1 = s.t, (s.step + 1) * dt
        q0, qv0 = poses_at(w.obstacles, t0)
        q1, _ = poses_at(w.obstacles, t1)
        mv = self.moving_mask
        active = s.active
        idx = np.flatnonzero(active)

        # Extra segments from the planner (e.g. smoothing) start before commands are formed.
        if self.planner is not None and len(idx):
            for i, seg in self.planner.on_step(self).items():
                if s.mode[i] == Mode.APF:
                    self._start_segment(i, seg, events)

        pos0 = s.position.copy()
        vel0 = s.velocity.copy()
        pos1 = pos0.copy()
        vel1 = np.zeros_like(vel0)
        obst_clear = np.full(self.n, np.inf)
        if len(idx):
            # The previous step already measured every agent's distances at this position and time.
            if self._field_cache is None:
                self._field_cache = self.field.query(pos0, q0)
            d, g = self._field_cache[0][idx], self._field_cache[1][idx]
            inputs = FieldInputs(d, g, qv0 * mv[:, None], mv, self.bounding_radius, q0)
            target, rep_scale = self._attraction_targets(idx, events)
            force = apf_forces(
                w,
                self.params,
                self.gains,
                idx,
                pos0[idx],
                vel0[idx],
                s.goal[idx],
                inputs,
                pos0,
                vel0,
                target=target,
                static_scale=rep_scale,
            )
            clearance, normal = self._nearest_surface(idx, pos0[idx], d, g)
            v_cmd = commanded_velocity(self.params, idx, force, pos0[idx], s.goal[idx], clearance, normal)
            v_cmd = self._guard_fixed_wings(idx, pos0, vel0, v_cmd, d, clearance, t0)
            vel1[idx] = limit_velocity(self.params, vel0[idx], v_cmd, dt, idx)
            pos1[idx] = pos0[idx] + vel1[idx] * dt
            validated = self._safety_filter(idx, pos0, vel0, pos1, vel1, v_cmd, q0, q1, events, t1)
            # Contact on the committed step ends the agent. Steps the filter cleared with a
            # margin cannot touch anything; the rest (stops, agent-conflict brakes) are checked.
            check = idx[~validated]
            if len(check):
                hits = first_hits(
                    self.collision, pos0[check], pos1[check], self.params.radius[check], q0[mv], q1[mv]
                )
                for i, hit in zip(check, hits, strict=True):
                    if hit is not None:
                        self._collide(i, hit, events, t1)
                        pos1[i] = self._crash_point(i, pos0[i], pos1[i], t0, dt)
                        vel1[i] = 0.0
        for i, j in agent_contacts(pos0, pos1, self.params.radius, active):
            for a, b in ((i, j), (j, i)):
                if s.mode[a] not in (Mode.ARRIVED, Mode.COLLIDED):
                    self._collide(a, self.ids[b], events, t1)

        # Arrival: the step passed within goal tolerance of the goal.
        tol = w.goal_tolerance
        flying = np.flatnonzero(s.active)
        dmins = segment_segment_min_distance(pos0[flying], pos1[flying], s.goal[flying], s.goal[flying])
        for i, dmin in zip(flying, dmins.tolist(), strict=True):
            if dmin <= tol:
                s.mode[i] = Mode.ARRIVED
                vel1[i] = 0.0
                s.segment[i] = None
                self.metrics.arrival_time[i] = t1
                events.append(Event(t1, self.ids[i], "arrived", {"distance": round(dmin, 6)}))

        # Clearances at the committed positions (also the next step's distances).
        self._field_cache = self.field.query(pos1, q1)
        if len(self.world.obstacles):
            obst_clear = (self._field_cache[0] - self.params.radius[:, None]).min(axis=1)
        agent_clear = self._agent_clearance(pos1)
        terr_clear = pos1[:, 2] - w.terrain_height(pos1[:, :2]) - self.params.radius
        self.metrics.add_step(pos0, pos1, active, obst_clear, agent_clear, terr_clear)
        self._near_misses(pos1, active, events, t1)

        s.position, s.velocity, s.t, s.step = pos1, vel1, t1, s.step + 1
        self._detect_stuck(events)

        terminated = not s.active.any()
        truncated = (not terminated) and t1 >= w.max_time - 1e-9
        if truncated:
            for i in np.flatnonzero(s.active):
                events.append(
                    Event(
                        t1,
                        self.ids[i],
                        "timeout",
                        {"distance_to_goal": round(float(np.linalg.norm(s.goal[i] - s.position[i])), 6)},
                    )
                )
        self._events = []
        if self.recorder is not None:
            self.recorder.write_state(t1, self._agent_dicts(), self._obstacle_dicts(t1))
            for e in events:
                self.recorder.write_event(e.to_json())
        return StepResult(s, events, terminated, truncated)

    # ------------------------------------------------------------------ helpers

    def _nearest_surface(
        self, idx: np.ndarray, pos: np.ndarray, d: np.ndarray, g: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Clearance and outward normal of the closest static surface (obstacles, terrain) per agent."""
        r = self.params.radius[idx]
        h = self.world.terrain_height(pos[:, :2])
        clear = pos[:, 2] - h - r
        gh = self.world.terrain_gradient(pos[:, :2])
        normal = np.stack([-gh[:, 0], -gh[:, 1], np.ones(len(idx))], axis=1)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        static = ~self.moving_mask
        if static.any():
            ds = d[:, static] - r[:, None]
            j = np.argmin(ds, axis=1)
            dj = ds[np.arange(len(idx)), j]
            closer = dj < clear
            clear = np.where(closer, dj, clear)
            normal = np.where(closer[:, None], g[:, static][np.arange(len(idx)), j], normal)
        return clear, normal

    def _attraction_targets(self, idx: np.ndarray, events: list[Event]) -> tuple[np.ndarray, np.ndarray]:
        """Point each agent is attracted to (segment waypoint, route waypoint or goal) and the scale
        of its static repulsion (reduced along a segment that FCL already validated)."""
        s = self.state
        target = s.goal[idx].copy()
        scale = np.ones(len(idx))
        for k, i in enumerate(idx):
            if s.mode[i] in SEGMENT_MODES and s.segment[i] is not None:
                wp = self._advance(s.segment[i], i, "segment")
                if wp is None:
                    kind = "escape_end" if s.mode[i] == Mode.ESCAPE else "smoothing_end"
                    events.append(Event(s.t, self.ids[i], kind, {}))
                    s.mode[i] = Mode.APF
                    s.segment[i] = None
                    self._rejoin_route(i)
                else:
                    target[k] = wp
                    scale[k] = 0.3
                    continue
            if s.route[i] is not None:
                wp = self._advance(s.route[i], i, "route")
                target[k] = s.goal[i] if wp is None else wp
        return target, scale

    def _advance(self, pts: np.ndarray, i: int, which: str) -> np.ndarray | None:
        """Next waypoint of ``pts`` not yet reached by agent ``i`` (None once all are)."""
        s = self.state
        index = s.segment_index if which == "segment" else s.route_index
        p = s.position[i]
        reach = max(self.world.goal_tolerance, float(np.linalg.norm(s.velocity[i])) * self.world.dt * 3.0)
        k = index[i]
        while k < len(pts) and np.linalg.norm(pts[k] - p) <= reach:
            k += 1
        index[i] = k
        return None if k >= len(pts) else pts[k]

    def _start_segment(self, i: int, seg: PlannedSegment, events: list[Event]) -> None:
        s = self.state
        s.segment[i] = np.asarray(seg.waypoints, dtype=float)
        s.segment_index[i] = 0
        s.mode[i] = seg.mode
        if seg.mode == Mode.ESCAPE:
            self.metrics.escapes[i] += 1
            events.append(
                Event(s.t, self.ids[i], "escape_start", {"waypoints": np.round(s.segment[i], 6).tolist()})
            )
        else:
            events.append(
                Event(s.t, self.ids[i], "smoothing_start", {"waypoints": np.round(s.segment[i], 6).tolist()})
            )

    def _guard_fixed_wings(
        self,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        v_cmd: np.ndarray,
        d: np.ndarray,
        clearance: np.ndarray,
        t0: float,
    ) -> np.ndarray:
        """Fixed wings keep the field's command only while they could still turn away
        (``swarmplan.lookahead``). Only agents with an obstacle, the terrain or the bounds within
        reach of the horizon (obstacles' own motion included) are checked, and only against the
        obstacles within that reach."""
        p = self.params
        fw = p.fixed_wing[idx]
        if not fw.any():
            return v_cmd
        dt = self.world.dt
        speed = np.linalg.norm(vel0[idx], axis=1)
        horizon = horizon_steps(p, idx[fw], speed[fw], dt) * dt
        required = p.radius[idx]
        reach = (speed + self._max_obstacle_speed) * horizon + required + p.radius[idx]
        obstacle_clear = (d - p.radius[idx, None]).min(axis=1) if d.shape[1] else np.full(len(idx), np.inf)
        q = pos0[idx]
        bounds_clear = (
            np.minimum(q - self.world.bounds_min, self.world.bounds_max - q).min(axis=1) - p.radius[idx]
        )
        near = fw & (np.minimum(np.minimum(clearance, obstacle_clear), bounds_clear) < reach)
        if not near.any():
            return v_cmd
        rows = np.flatnonzero(near)
        close = np.flatnonzero((d[rows] < reach[rows, None]).any(axis=0)) if d.shape[1] else np.array([], int)
        obstacles = self.world.obstacles

        def clearance_at(points: np.ndarray, radii: np.ndarray, times: np.ndarray) -> np.ndarray:
            w = self.world
            c = points[:, 2] - w.terrain_height(points[:, :2]) - radii
            # Leaving the flight volume counts as a collision ('bounds') as well.
            inside = np.minimum(points - w.bounds_min, w.bounds_max - points).min(axis=1)
            c = np.minimum(c, inside - radii)
            if len(close):
                movers = [obstacles[j] for j in close if obstacles[j].moving]
                if movers:
                    when, which = np.unique(times, return_inverse=True)
                    centers = np.stack([poses_at(movers, t)[0] for t in when])  # (T, movers, 3)
                k = 0
                for j in close:
                    o = obstacles[j]
                    at = o.position
                    if o.moving:
                        at, k = centers[which, k], k + 1
                    dj = distance_and_gradient(o, points, at, self.field.mesh_grids.get(j))[0]
                    c = np.minimum(c, dj - radii)
            return c

        guarded, replaced = guard_commands(
            p, idx[rows], pos0[idx[rows]], vel0[idx[rows]], v_cmd[rows], t0, dt, clearance_at, required[rows]
        )
        out = v_cmd.copy()
        out[rows] = guarded
        for i in idx[rows][replaced]:
            self.metrics.guard_steps[i] += 1
        return out

    def _margin(self, i: int | np.ndarray) -> np.ndarray:
        return np.minimum(0.25, 0.2 * self.params.radius[i])

    def _step_is_safe(self, i: int, p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> bool:
        mv = self.moving_mask
        return (
            self.collision.first_hit(p0, p1, self.params.radius[i] + self._margin(i), q0[mv], q1[mv]) is None
        )

    def _safety_filter(
        self,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        pos1: np.ndarray,
        vel1: np.ndarray,
        v_cmd: np.ndarray,
        q0: np.ndarray,
        q1: np.ndarray,
        events: list[Event],
        t1: float,
    ) -> np.ndarray:
        """Replace steps that would touch an obstacle by the closest safe feasible alternative.

        Returns, per agent of ``idx``, whether its final step was cleared with the safety margin.
        """
        dt = self.world.dt
        mv = self.moving_mask
        hits = first_hits(
            self.collision, pos0[idx], pos1[idx], self.params.radius[idx] + self._margin(idx), q0[mv], q1[mv]
        )
        validated = np.array([h is None for h in hits], dtype=bool)
        for k in np.flatnonzero(~validated):
            i = idx[k]
            cands = self._alternative_velocities(i, vel0[i])
            safe = [v for v in cands if self._step_is_safe(i, pos0[i], pos0[i] + v * dt, q0, q1)]
            if safe:
                best = min(safe, key=lambda v: float(np.linalg.norm(v - v_cmd[k])))
                vel1[i] = best
                validated[k] = True
            elif not self.params.fixed_wing[i]:
                # No feasible command avoids contact: stop (beyond the accel limit) and say so.
                vel1[i] = 0.0
                self.metrics.emergency_stops[i] += 1
                events.append(
                    Event(
                        t1, self.ids[i], "emergency_stop", {"speed": round(float(np.linalg.norm(vel0[i])), 6)}
                    )
                )
            pos1[i] = pos0[i] + vel1[i] * dt
        # Agents: conflicting pairs stop the multirotor(s) involved, until no conflict remains.
        active = np.zeros(self.n, dtype=bool)
        active[idx] = True
        stopped = np.zeros(self.n, dtype=bool)
        for _ in range(self.n):
            margin = 0.2
            pairs = agent_contacts(
                pos0, pos1, self.params.radius, active | (self.state.mode == Mode.ARRIVED), margin
            )
            changed = False
            for a, b in pairs:
                for i in (a, b):
                    if active[i] and not stopped[i] and not self.params.fixed_wing[i]:
                        safe_brake = self._brake(i, vel0[i])
                        p_brake = pos0[i] + safe_brake * dt
                        other = b if i == a else a
                        d = float(segment_segment_min_distance(pos0[i], p_brake, pos0[other], pos1[other]))
                        if d >= self.params.radius[i] + self.params.radius[
                            other
                        ] + margin and self._step_is_safe(i, pos0[i], p_brake, q0, q1):
                            vel1[i] = safe_brake
                        else:
                            vel1[i] = 0.0
                            self.metrics.emergency_stops[i] += 1
                            events.append(
                                Event(t1, self.ids[i], "emergency_stop", {"other": self.ids[other]})
                            )
                        pos1[i] = pos0[i] + vel1[i] * dt
                        stopped[i] = True
                        changed = True
            if not changed:
                break
        return validated & ~stopped[idx]

    def _brake(self, i: int, v0: np.ndarray) -> np.ndarray:
        sp = float(np.linalg.norm(v0))
        dv = self.params.max_accel[i] * self.world.dt
        return v0 * max(0.0, sp - dv) / sp if sp > 1e-12 else np.zeros(3)

    def _alternative_velocities(self, i: int, v0: np.ndarray) -> list[np.ndarray]:
        """Feasible next velocities spanning the model's envelope (brake, turn, climb, dive)."""
        dt = self.world.dt
        p = self.params
        if not p.fixed_wing[i]:
            dv = p.max_accel[i] * dt
            dirs = [np.array(v, float) for v in np.ndindex(3, 3, 3) if v != (1, 1, 1)]
            dirs = [(d - 1) / np.linalg.norm(d - 1) for d in dirs]
            out = [self._brake(i, v0)] + [v0 + dv * d for d in dirs]
            vmax = p.speed_max[i]
            return [v if np.linalg.norm(v) <= vmax else v * vmax / np.linalg.norm(v) for v in out]
        speed = float(np.linalg.norm(v0))
        psi = math.atan2(v0[1], v0[0])
        cmds = []
        for dpsi in (-1.0, -0.5, 0.0, 0.5, 1.0):
            for gam in (-1.0, 0.0, 1.0):
                for sp in (p.speed_min[i], speed, p.speed_max[i]):
                    a = psi + dpsi * math.pi / 2
                    g = gam * p.max_climb[i]
                    cmds.append(
                        sp * np.array([math.cos(g) * math.cos(a), math.cos(g) * math.sin(a), math.sin(g)])
                    )
        cmds = np.array(cmds)
        v = limit_velocity(p, np.repeat(v0[None], len(cmds), 0), cmds, dt, np.full(len(cmds), i))
        return list(v)

    def _crash_point(self, i: int, p0: np.ndarray, p1: np.ndarray, t0: float, dt: float) -> np.ndarray:
        """Where the agent strikes on the step ``p0 → p1``: it stops there instead of flying on.

        Bisection on the swept check finds the first contact; the crash is recorded
        ``CRASH_DEPTH`` past it (bodies overlap in a crash), so an audit from positions alone
        sees the contact, and an agent never appears on the far side of a thin obstacle.
        """
        mv = self.moving_mask
        r = self.params.radius[i]
        step = p1 - p0
        length = float(np.linalg.norm(step))
        if length < 1e-12:
            return p1.copy()

        def hits(s: float) -> bool:
            qa = poses_at(self.world.obstacles, t0)[0][mv]
            qb = poses_at(self.world.obstacles, t0 + s * dt)[0][mv]
            return first_hits(self.collision, p0[None], (p0 + s * step)[None], r[None], qa, qb)[0] is not None

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

    def _collide(self, i: int, other: str, events: list[Event], t1: float) -> None:
        s = self.state
        if s.mode[i] == Mode.COLLIDED:
            return
        s.mode[i] = Mode.COLLIDED
        s.segment[i] = None
        self.metrics.collisions[i] += 1
        self.metrics.collided_with[i].append(other)
        events.append(Event(t1, self.ids[i], "collision", {"other": other}))

    def _agent_clearance(self, pos: np.ndarray) -> np.ndarray:
        if self.n < 2:
            return np.full(self.n, np.inf)
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (
            self.params.radius[:, None] + self.params.radius[None]
        )
        np.fill_diagonal(d, np.inf)
        return d.min(axis=1)

    def _near_misses(self, pos: np.ndarray, active: np.ndarray, events: list[Event], t1: float) -> None:
        """A pair entering each other's separation ellipsoid is a near miss (reported once per entry)."""
        if self.n < 2:
            return
        sep = np.maximum(self.params.separation[:, None], self.params.separation[None])
        rr = self.params.radius[:, None] + self.params.radius[None]
        q = (pos[:, None] - pos[None]) / (sep + rr[..., None])
        inside = np.linalg.norm(q, axis=-1) < 1.0
        np.fill_diagonal(inside, False)
        inside &= active[:, None] | active[None]
        new = inside & ~self._near
        self._near = inside
        for i, j in zip(*np.nonzero(np.triu(new)), strict=True):
            dist = float(np.linalg.norm(pos[i] - pos[j]))
            self.metrics.near_misses[[i, j]] += 1
            events.append(
                Event(t1, self.ids[i], "near_miss", {"other": self.ids[j], "distance": round(dist, 6)})
            )

    def _detect_stuck(self, events: list[Event]) -> None:
        """No progress towards the goal for ``planner.stuck.window`` seconds is a local minimum.

        Progress is measured as the distance still to fly: straight to the goal, or along the
        rest of the global route when the agent has one (a route may detour away from the goal).
        """
        s = self.state
        window = self.world.planner["stuck"]["window"]
        min_progress = self.world.planner["stuck"]["min_progress"]
        dg = self._distance_to_go()
        for i in np.flatnonzero(s.active):
            if s.mode[i] != Mode.APF:
                self._progress_ref[i], self._progress_t[i] = dg[i], s.t
                self._segment_watchdog(int(i), window, min_progress, events)
                continue
            if s.t - self._progress_t[i] < window - 1e-9:
                continue
            progress = self._progress_ref[i] - dg[i]
            self._progress_ref[i], self._progress_t[i] = dg[i], s.t
            if progress < min_progress:
                self.metrics.stuck_events[i] += 1
                events.append(
                    Event(
                        s.t,
                        self.ids[i],
                        "stuck",
                        {
                            "progress": round(float(progress), 6),
                            "window": window,
                            "distance_to_goal": round(float(np.linalg.norm(s.goal[i] - s.position[i])), 6),
                            "distance_to_go": round(float(dg[i]), 6),
                        },
                    )
                )
                if self.planner is not None:
                    outcome = self.planner.on_stuck(self, int(i))
                    if outcome == FAILED:
                        s.mode[i] = Mode.FAILED
                        events.append(
                            Event(s.t, self.ids[i], "failed", {"reason": "no valid escape segment"})
                        )
                    elif outcome is not None:
                        self._start_segment(int(i), outcome, events)

    def _distance_to_go(self) -> np.ndarray:
        """Per agent: straight to the goal, or along the rest of its global route when it has one."""
        s = self.state
        dg = np.linalg.norm(s.goal - s.position, axis=1)
        for i, route in enumerate(s.route):
            k = int(s.route_index[i])
            if route is not None and k < len(route):
                rest = np.vstack([route[k:], s.goal[i]])
                legs = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
                dg[i] = np.linalg.norm(route[k] - s.position[i]) + legs
        return dg

    def _segment_watchdog(self, i: int, window: float, min_progress: float, events: list[Event]) -> None:
        """A segment whose next waypoint gets no closer for ``window`` s is abandoned (back to APF,
        whose stuck detection then asks the planner again)."""
        s = self.state
        seg = s.segment[i]
        if seg is None or s.segment_index[i] >= len(seg):
            return
        k = int(s.segment_index[i])
        d = float(np.linalg.norm(seg[k] - s.position[i]))
        ref = self._segment_ref.get(i)
        if ref is None or ref[0] != k or ref[3] is not seg:
            self._segment_ref[i] = (k, d, s.t, seg)
            return
        # A sharp corner at a waypoint costs a turnaround (brake, turn, speed up again) before
        # the distance to the next one falls: half a minimum-radius circle at cruise speed.
        p = self.params
        turn_radius = p.min_turn_radius[i] if p.fixed_wing[i] else p.speed_cruise[i] ** 2 / p.max_accel[i]
        grace = math.pi * turn_radius / max(p.speed_cruise[i], 1e-6)
        if s.t - ref[2] < window + grace - 1e-9:
            return
        if ref[1] - d >= min_progress:
            self._segment_ref[i] = (k, d, s.t, seg)
            return
        kind = "escape_end" if s.mode[i] == Mode.ESCAPE else "smoothing_end"
        events.append(Event(s.t, self.ids[i], kind, {"abandoned": True, "waypoint": k}))
        s.mode[i] = Mode.APF
        s.segment[i] = None
        self._segment_ref.pop(i, None)
        self._rejoin_route(i)

    def _rejoin_route(self, i: int) -> None:
        """After a segment, go on along the global route from its nearest point ahead of where the
        agent left it (the route is what avoids the obstacles: never straight to the goal, and
        not back to the point where the segment began)."""
        s = self.state
        route, k0 = s.route[i], int(s.route_index[i])
        if route is None or k0 >= len(route):
            return
        d = np.linalg.norm(route[k0:] - s.position[i], axis=1)
        s.route_index[i] = k0 + int(np.argmin(d))

    # ------------------------------------------------------------------ messages

    def _agent_dicts(self) -> list[dict[str, Any]]:
        s = self.state
        pos = np.round(s.position, 6).tolist()
        vel = np.round(s.velocity, 6).tolist()
        goal = s.goal.tolist()
        return [
            {
                "id": self.ids[i],
                "position": pos[i],
                "velocity": vel[i],
                "mode": str(s.mode[i]),
                "goal": goal[i],
            }
            for i in range(self.n)
        ]

    def _obstacle_dicts(self, t: float) -> list[dict[str, Any]] | None:
        moving = self.world.moving_obstacles
        if not moving:
            return None
        pos, vel = poses_at(moving, t)
        pos = np.round(pos, 6).tolist()
        vel = np.round(vel, 6).tolist()
        return [
            {"id": o.id, "position": pos[k], "orientation": self.moving_quat[k], "velocity": vel[k]}
            for k, o in enumerate(moving)
        ]

    def summary(self, interrupted: bool = False) -> dict[str, Any]:
        """Per-agent and overall metrics for ``/summary`` and the CLI table."""
        m = self.metrics
        s = self.state
        agents = []
        for i, aid in enumerate(self.ids):
            curv = m.curvature(i)
            start = self.world.agents[i].start
            straight = float(np.linalg.norm(self.world.agents[i].goal - start))
            agents.append(
                {
                    "id": aid,
                    "arrived": bool(s.mode[i] == Mode.ARRIVED),
                    "final_mode": str(s.mode[i]),
                    "arrival_time": None
                    if math.isnan(m.arrival_time[i])
                    else round(float(m.arrival_time[i]), 9),
                    "path_length": round(float(m.path_length[i]), 6),
                    "straight_line": round(straight, 6),
                    "length_ratio": round(float(m.path_length[i]) / straight, 6) if straight > 0 else None,
                    "min_clearance": _finite(min(m.min_clearance[i], m.min_agent_clearance[i])),
                    "min_obstacle_clearance": _finite(m.min_clearance[i]),
                    "min_agent_clearance": _finite(m.min_agent_clearance[i]),
                    "min_terrain_clearance": _finite(m.min_terrain_clearance[i]),
                    "max_curvature": round(float(curv.max()), 6) if len(curv) else 0.0,
                    "mean_curvature": round(float(curv.mean()), 6) if len(curv) else 0.0,
                    "collisions": int(m.collisions[i]),
                    "collided_with": m.collided_with[i],
                    "escapes": int(m.escapes[i]),
                    "escape_planning_ms": [round(x, 3) for x in m.escape_ms[i]],
                    "stuck_events": int(m.stuck_events[i]),
                    "near_misses": int(m.near_misses[i]),
                    "emergency_stops": int(m.emergency_stops[i]),
                    "guard_steps": int(m.guard_steps[i]),
                }
            )
        arrived = sum(a["arrived"] for a in agents)
        collisions = sum(a["collisions"] for a in agents)
        return {
            "t": round(s.t, 9),
            "world": self.world.name,
            "seed": self.seed,
            "optimizer": self.optimizer_name,
            "interrupted": interrupted,
            "success": bool(arrived == self.n and collisions == 0 and not interrupted),
            "sim_time": round(s.t, 9),
            "wall_time": round(time.perf_counter() - self.wall_start, 6),
            "steps": s.step,
            "arrived": arrived,
            "agents_total": self.n,
            "collisions": collisions,
            "agents": agents,
        }

    @property
    def optimizer_name(self) -> str:
        if self.planner is None:
            return "none"
        return str(getattr(self.planner, "optimizer_name", self.world.planner["optimizer"]["name"]))


def _finite(x: float) -> float | None:
    return round(float(x), 6) if math.isfinite(x) else None
