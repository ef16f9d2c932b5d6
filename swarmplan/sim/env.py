"""The multi-UAV simulation: ``reset(seed=...)`` / ``step()`` in the manner of Gymnasium.

Each step, for every flying agent at once: potential-field command (or segment following
while escaping/smoothing) → kinematic limits → a swept FCL safety check of the step
(alternative feasible commands when the step would touch something) → the committed
step is checked again (contact ends the agent) → arrival, stuck and near-miss detection
→ the step's result (everything a log needs: states, events, optimizer runs; the simulation
writes nothing itself, observers of the results do). ``terminated`` means every agent
arrived, collided or failed; ``truncated`` means the world's ``sim.max_time`` ran out.

This module only orchestrates; the jobs live beside it: :mod:`~swarmplan.sim.scene`
(obstacles, distances), :mod:`~swarmplan.sim.navigation` (plan following, stuck detection),
:mod:`~swarmplan.sim.loiter` (arrived fixed wings circle their goals),
:mod:`~swarmplan.sim.safety` (safety filter, deconfliction, fixed-wing guard),
:mod:`~swarmplan.sim.contacts` (collisions, crash point, arrival, near misses),
:mod:`~swarmplan.sim.guard` (arrived multirotors out of a mover's way and back).
"""

from __future__ import annotations

import time
import zlib
from typing import Any, Literal

import numpy as np

from swarmplan.core import (
    DONE_MODES,
    AgentStates,
    Event,
    Mode,
    ObstacleStates,
    OptimizerRun,
    Planner,
    ResetResult,
    StepResult,
    StuckOutcome,
    SwarmState,
)
from swarmplan.flight.apf import ApfField, FieldInputs, Flyers, Swarm, commanded_velocity
from swarmplan.flight.guide import make_guide
from swarmplan.flight.kinematics import AgentParams, initial_velocity, turn_states
from swarmplan.geometry.collision import first_hits
from swarmplan.geometry.compiled import use_compiled_checks
from swarmplan.geometry.neighbours import agent_contacts_indexed
from swarmplan.geometry.vec3 import norm3
from swarmplan.planner import make_planner
from swarmplan.sim.contacts import NearMisses, arrivals, collide, crash_point, parked_contacts
from swarmplan.sim.guard import GoalGuard
from swarmplan.sim.loiter import Loiter
from swarmplan.sim.metrics import RunMetrics, Tally, summary_report
from swarmplan.sim.modes import PARKED, mode_in
from swarmplan.sim.navigation import Navigator, distance_to_go
from swarmplan.sim.safety import AgentMotion, Commands, SafetyFilter, StepWindow, step_kernels
from swarmplan.sim.scene import Scene
from swarmplan.sim.threats import nearest_with_cores, threat_cores, with_cores
from swarmplan.world.model import World
from swarmplan.world.motion import next_rest

FAR_GOAL = np.array([1e9, 0.0, 0.0])
"""Offset of the goal row an evading agent's braking margin sees: its goal's cap never binds."""


class Simulation:
    """One run of a world. It records nothing: :meth:`start` and :meth:`step` return everything
    a log needs (see ``swarmplan.io.runner``, whose observers write it).

    ``planner`` plans global routes, escapes and smoothing: by default (``"world"``) the
    world's own ``planner.optimizer``, as the command line flies it; ``"none"`` (or None) is
    pure APF; or any object with the :class:`~swarmplan.core.Planner` methods.
    """

    def __init__(
        self,
        world: World,
        planner: Planner | Literal["world", "none"] | None = "world",
    ):
        self.world = world
        if planner == "world":
            planner = make_planner(world)
        elif planner == "none":
            planner = None
        elif isinstance(planner, str):
            raise ValueError(f"planner: expected 'world', 'none' or a Planner, got {planner!r}")
        self.planner = planner
        self.params = AgentParams.from_world(world)
        self.apf = ApfField(world, self.params)
        self.scene = Scene(world, self.params)
        # The way round static obstacles for agents whose straight line is blocked (None without any).
        self.guide = make_guide(world, self.params)
        self._guide_at = 0.0  # the time the guide's bodies are at rest for good from
        self._rest_at = next_rest(world, 0.0)  # when the next mover comes to rest for good
        self._threat_cores = threat_cores(world)
        # What planners read (see swarmplan.core.PlanningContext).
        self.collision = self.scene.collision
        self.field = self.scene.field
        self.moving_mask = self.scene.moving_mask
        self.n = len(world.agents)
        self.ids = self.params.ids
        self.safety = SafetyFilter(world, self.params, self.scene)
        self._compiled = use_compiled_checks(self.n)  # swarm size: compiled per-step helpers
        self.navigator = Navigator(world, self.params, self.guide)
        self.guard = GoalGuard(self.params, world.dt)
        self.loiter = Loiter(self.params)  # arrived fixed wings circle their goals
        self._static_idx = np.flatnonzero(~self.moving_mask)
        # The speed a one-step stop can take within max_accel (fixed wings: any), read every step.
        self._stop_speed = np.where(self.params.fixed_wing, np.inf, self.params.max_accel * world.dt)
        self._stop_speed.setflags(write=False)
        self._fixed_wings = bool(self.params.fixed_wing.any())
        self._mover_ids = tuple(o.id for o in world.obstacles if o.moving)
        self._mover_radii = self.scene.bounding_radius[self.moving_mask]  # read every guarded step
        self.state: SwarmState | None = None
        self.seed: int | None = None
        self._streams: dict[tuple[str, int | None], np.random.Generator] = {}
        self.metrics: RunMetrics | None = None
        self.wall_start = 0.0
        self._events: list[Event] = []  # the running step's events (see note_event)
        self._optimizer_runs: list[OptimizerRun] = []  # the running step's (see record_optimizer)
        self._records: list[OptimizerRun | Event] | None = None  # planning before flight, in order

    # ------------------------------------------------------------------ lifecycle

    def reset(self, seed: int | None = None) -> SwarmState:
        """Start the run at t = 0 with ``seed`` (default: the world's seed)."""
        return self.start(seed).state

    def start(self, seed: int | None = None) -> ResetResult:
        """:meth:`reset`, with what it produced for observers: the ``/world`` message, the
        optimizer runs and events of planning before flight, the entries at t = 0."""
        self.seed = self.world.seed if seed is None else int(seed)
        self._streams = {}
        self._events = []
        self._optimizer_runs = []
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
        self._measure_start(start)
        if self._guide_at > 0.0:  # a mover parked in the last run: back to the bodies at rest at 0
            self.guide, self._guide_at = make_guide(self.world, self.params), 0.0
            self._rest_at = next_rest(self.world, 0.0)
            self.navigator.guide = self.guide
        if self.guide is not None:
            self.guide.reset(start, goal)
        self.navigator.reset(self.state)
        self.guard.reset()
        self.loiter.reset()
        self.safety.turn[:] = 0.0  # fixed wings start straight and level
        self.near_misses = NearMisses(self.params)
        self._field_cache: tuple[np.ndarray, np.ndarray] | None = None
        self.wall_start = time.perf_counter()
        world_message = self.world.to_message(self.seed)
        records: list[OptimizerRun | Event] = []
        if self.planner is not None:
            self._records = records  # its runs and events in the order they come (note_event)
            try:
                routes = self.planner.on_reset(self)
            finally:
                self._records = None
            for i, route in routes.items():
                self.state.route[i] = np.asarray(route, dtype=float)
            self.navigator.reset(self.state)
        agents, obstacles = self._agent_states(), self._obstacle_states(0.0)
        return ResetResult(self.state, world_message, records, agents, obstacles)

    def _measure_start(self, start: np.ndarray) -> None:
        """The clearances at the start count too (a log's replay measures every sample from
        t = 0: an agent that starts nearer to something than it ever flies was reported farther)."""
        m, r = self.metrics, self.params.radius
        if len(self.world.obstacles):
            q0 = self.scene.poses(0.0)[0]
            m.min_clearance = np.minimum(m.min_clearance, self.field.min_distance(start, q0) - r)
        m.min_agent_clearance = np.minimum(m.min_agent_clearance, self.scene.agent_clearance(start))
        terrain = start[:, 2] - self.world.terrain_height(start[:, :2]) - r
        m.min_terrain_clearance = np.minimum(m.min_terrain_clearance, terrain)

    def rng_for(self, purpose: str, agent: int | None = None) -> np.random.Generator:
        """The random stream of one purpose (e.g. 'escape') for one agent, seeded from the run's
        seed: each stream is its own child of ``SeedSequence(seed)``, so one more optimizer run
        for one purpose or agent does not shift the draws of any other."""
        key = (purpose, agent)
        if key not in self._streams:
            if self.seed is None:
                raise RuntimeError("call reset() before rng_for()")
            # A stable key per (purpose, agent): the purpose's CRC-32 and the agent index + 1 (0: none).
            spawn_key = (zlib.crc32(purpose.encode()), 0 if agent is None else agent + 1)
            self._streams[key] = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=spawn_key))
        return self._streams[key]

    def record_optimizer(
        self, agent: int | None, purpose: str, algorithm: str, result: Any, t: float | None = None
    ) -> None:
        """One optimizer run (a ``swarmplan.optimizers.Result``): in the metrics, and in the running
        step's result (``optimizer_runs``; before flight: the reset's ``records``)."""
        wall_ms = float(result.wall_time) * 1000.0
        if agent is not None and purpose == "escape":
            self.metrics.escape_ms[agent].append(wall_ms)
        if agent is not None:
            self.metrics.optimizer_runs[agent] += 1
        run = OptimizerRun(
            t=round(self.state.t if t is None else t, 9),
            agent=None if agent is None else self.ids[agent],
            algorithm=algorithm,
            purpose=purpose,
            evaluations=int(result.evaluations),
            iterations=int(result.iterations),
            best_cost=float(result.f),
            wall_ms=round(wall_ms, 3),
            convergence=[float(x) for x in result.history],
        )
        (self._optimizer_runs if self._records is None else self._records).append(run)

    def note_event(self, agent: int | None, kind: str, detail: dict[str, Any]) -> None:
        """An event the planner reports during ``step()`` (recorded with that step's events)."""
        if self.state is None:
            raise RuntimeError("call reset() before note_event()")
        event = Event(self.state.t, None if agent is None else self.ids[agent], kind, detail)
        if self._records is not None:
            # Before the first step there is no step to carry it: it goes out with the reset,
            # between the optimizer runs it follows.
            self._records.append(event)
            return
        self._events.append(event)

    def _merge(self, tally: Tally) -> None:
        """Take in what one part of the step changed: its events (after those so far) and its counts."""
        self._events.extend(tally.events)
        self.metrics.merge(tally)

    def _ask_planner(self, i: int) -> tuple[StuckOutcome, tuple[Event, ...]]:
        """The planner's answer for stuck agent ``i`` and the events it reported meanwhile."""
        before = len(self._events)
        outcome = self.planner.on_stuck(self, i)
        reported = tuple(self._events[before:])
        del self._events[before:]
        return outcome, reported

    def world_message(self) -> dict[str, Any]:
        return self.world.to_message(self.seed)

    # ------------------------------------------------------------------ one step

    def step(self) -> StepResult:
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        s = self.state
        w = self.world
        dt = w.dt
        nav = self.navigator
        events = self._events  # with any noted between steps
        t0, t1 = s.t, (s.step + 1) * dt
        q0, qv0 = self.scene.poses(t0)
        q1, _ = self.scene.poses(t1)
        mv = self.moving_mask
        # Arrived multirotors under threat take off again (mode apf) to get out of its way.
        flying_before = s.mode != Mode.ARRIVED
        if self.guard.guarding.any():
            self._merge(self._guard_goals(s, q0, qv0))
        active = s.active
        # Arrived fixed wings fly on (they loiter about their goals): they are flown as the rest.
        loiter = self.loiter.rows(s)
        flying_now = active | loiter if loiter.any() else active
        idx = np.flatnonzero(flying_now)
        # Every agent is measured at every step, whatever its mode: an arrived one hovers at its
        # goal, a failed or collided one stays where it stopped, and a mover may pass any of them.
        measured = np.ones(self.n, dtype=bool)
        touched = False  # whether a mode set this step ended an agent (a collision)

        # Extra segments from the planner (e.g. smoothing) start before commands are formed.
        if self.planner is not None and len(idx):
            for i, seg in self.planner.on_step(self).items():
                if s.mode[i] == Mode.APF and not self.guard.guarding[i]:
                    touched |= seg.mode in DONE_MODES  # not a segment's mode: ask the modes again
                    self._merge(nav.start_segment(s, i, seg))

        pos0 = s.position.copy()
        vel0 = s.velocity.copy()
        pos1 = pos0.copy()
        vel1 = np.zeros_like(vel0)
        obst_clear = np.full(self.n, np.inf)
        if len(idx):
            # The previous step already measured every agent's distances at this position and time.
            if self._field_cache is None:
                self._field_cache = self.field.query(pos0, q0)
            if len(idx) == self.n:  # every agent flies: the rows are the cache's (read only)
                d, g = self._field_cache
                p_idx, v_idx, goal_idx = pos0, vel0, s.goal.copy()
            else:
                d, g = self._field_cache[0][idx], self._field_cache[1][idx]
                p_idx, v_idx, goal_idx = pos0[idx], vel0[idx], s.goal[idx]
            inputs = FieldInputs(d, g, qv0 * mv[:, None], mv, self.scene.bounding_radius, q0)
            if self._threat_cores is not None:  # threats[i].avoid: cores repel like static spheres
                inputs = with_cores(inputs, p_idx, self._threat_cores)
            target, rep_scale, ended = nav.attraction_targets(s, idx)
            self._merge(ended)
            if self._rest_at <= t0:  # a mover parked for good: go round it too
                self._guide_at = t0
                self._rest_at = next_rest(w, t0)
                self.guide = make_guide(w, self.params, t0)
                self.navigator.guide = self.guide
            if self.guide is not None:
                target, rep_scale = self.guide.targets(s.step, idx, pos0[idx], s.goal[idx], target, rep_scale)
            if loiter.any():  # a point ahead on its circle is a loitering agent's target and goal
                rows = np.flatnonzero(loiter[idx])
                ahead = self.loiter.targets(idx[rows], pos0[idx[rows]])
                target, goal_idx = np.array(target, dtype=float), goal_idx.copy()
                target[rows] = goal_idx[rows] = ahead
            parked = ~flying_now  # modes changed above stay flying ones: arrivals come later
            flyers = Flyers(idx, p_idx, v_idx, goal_idx, target, rep_scale)
            to_go = norm3(s.goal - pos0)
            force = self.apf.forces(flyers, inputs, Swarm(pos0, vel0, parked, to_go))
            clearance, normal = self.scene.nearest_surface(idx, p_idx, d, g)
            if self._threat_cores is not None:
                cores, radius = self._threat_cores, self.params.radius[idx]
                clearance, normal = nearest_with_cores(clearance, normal, p_idx, radius, cores)
            v_cmd = commanded_velocity(self.params, idx, force, p_idx, goal_idx, clearance, normal)
            v_cmd = self.guard.commands(idx, v_cmd)
            v_cmd, guarded = self.safety.guard_fixed_wings(idx, pos0, vel0, v_cmd, d, clearance, t0)
            self._merge(guarded)
            # An evading agent is not slowed by its goal: its row names a point so far off that
            # the goal's speed cap never binds.
            evading = self.guard.evading[idx]
            brake_goal = np.where(evading[:, None], p_idx + FAR_GOAL, goal_idx) if evading.any() else goal_idx
            v_cmd, v_new, free = self.safety.brake_and_limit(idx, pos0, vel0, v_cmd, q0, q1, brake_goal)
            if len(idx) == self.n:  # every row (the same values as through idx)
                vel1[:] = v_new
                pos1 = pos0 + vel1 * dt
            else:
                vel1[idx] = v_new
                pos1[idx] = pos0[idx] + vel1[idx] * dt
            filtered = self.safety.filter(
                Commands(idx, v_cmd),
                AgentMotion(pos0, vel0),
                AgentMotion(pos1, vel1),
                StepWindow(t0, t1, q0, q1),
                s.mode,
                free,
            )
            pos1, vel1, validated = filtered.end.position, filtered.end.velocity, filtered.validated
            self._merge(filtered.tally)
            # Contact on the committed step ends the agent. Steps the filter cleared with a
            # margin cannot touch anything; the rest (stops, agent-conflict brakes) are checked.
            check = idx[~validated]
            if len(check):
                hits = first_hits(
                    self.collision, pos0[check], pos1[check], self.params.radius[check], q0[mv], q1[mv]
                )
                for i, hit in zip(check, hits, strict=True):
                    if hit is not None:
                        touched = True
                        self._merge(collide(s, self.ids, i, hit, t1))
                        pos1[i] = crash_point(self.scene, self.params.radius[i], pos0[i], pos1[i], t0, dt)
                        vel1[i] = 0.0
            fw = idx[self.params.fixed_wing[idx]]
            if len(fw):  # the curvature each fixed wing flew, which its next step rolls on from
                self.safety.turn[fw] = turn_states(self.params, vel0[fw], vel1[fw], dt, fw)
        for i, j in agent_contacts_indexed(pos0, pos1, self.params.radius, flying_now):
            for a, b in ((i, j), (j, i)):
                if s.mode[a] != Mode.COLLIDED:  # an arrived agent touched is a collision too
                    touched = True
                    self._merge(collide(s, self.ids, a, self.ids[b], t1))

        # Arrival (and its stop) only at a speed a one-step stop can take within max_accel.
        # Agents out of a threat's way cannot arrive; one back at its goal ends its evasion.
        stop_speed = self.guard.stop_speeds(self._stop_speed)
        # Only a collision ends an agent between the step's start and here (segments, their ends
        # and the guard's take-offs keep agents flying): who still flies is known without
        # asking every mode again.
        flying = s.active if touched else active
        kept = vel1.copy() if self._fixed_wings else None
        arrived = arrivals(s, self.ids, pos0, pos1, vel1, w.goal_tolerance, t1, stop_speed, flying)
        for i, _t in arrived.arrivals if self._fixed_wings else ():
            if self.params.fixed_wing[i]:  # it cannot stop: it flies on round its goal
                vel1[i] = kept[i]
                self.loiter.start(i, s.goal[i], self.safety.turn[i], self._clear_of_statics(i))
        self._merge(self.guard.arrived(arrived, s))

        # Clearances at the committed positions (also the next step's distances).
        self._field_cache = self.field.query(pos1, q1)
        if len(self.world.obstacles):
            # Exact for meshes too (the grid in the cache is approximate, a lower bound beyond it).
            obst_clear = self.field.min_distance(pos1, q1, self._field_cache[0]) - self.params.radius
            parked = mode_in(s.mode, PARKED)
            if parked.any():
                # Arrived and failed agents stay in the air: an obstacle moving through one is a collision.
                self._merge(parked_contacts(s, self.ids, obst_clear, self._nearest_obstacle, t1))
        agent_clear = self.scene.agent_clearance(pos1)
        terr_clear = pos1[:, 2] - w.terrain_height(pos1[:, :2]) - self.params.radius
        self.metrics.add_step(pos0, pos1, measured, obst_clear, agent_clear, terr_clear, flying_before)
        self._merge(self.near_misses.update(pos1, active, t1))

        s.position, s.velocity, s.t, s.step = pos1, vel1, t1, s.step + 1
        on_stuck = None if self.planner is None else self._ask_planner
        self._merge(nav.detect_stuck(s, on_stuck, exempt=self.guard.guarding))

        terminated = not s.active.any()
        truncated = (not terminated) and t1 >= w.max_time - 1e-9
        if truncated:
            for i in np.flatnonzero(s.active):
                distance = round(float(np.linalg.norm(s.goal[i] - s.position[i])), 6)
                events.append(Event(t1, self.ids[i], "timeout", {"distance_to_goal": distance}))
        self._events = []
        runs, self._optimizer_runs = self._optimizer_runs, []
        agents, obstacles = self._agent_states(), self._obstacle_states(t1)
        return StepResult(s, events, terminated, truncated, agents, obstacles, runs)

    def _clear_of_statics(self, i: int):  # noqa: ANN202
        """``clearance(points) -> (P,)`` of agent ``i``'s body at ``points``: from the terrain and
        the bounds beyond its radius, from static obstacles beyond its ``clearance``."""
        w, p, field, static = self.world, self.params, self.field, self._static_idx

        def clearance(points: np.ndarray) -> np.ndarray:
            r = p.radius[i]
            c = points[:, 2] - w.terrain_height(points[:, :2]) - r
            c = np.minimum(c, np.minimum(points - w.bounds_min, w.bounds_max - points).min(axis=1) - r)
            if len(static):
                c = np.minimum(c, field.distance(points, None, static).min(axis=1) - p.clearance[i])
            return c

        return clearance

    def _nearest_obstacle(self, i: int) -> str:
        """The id of the obstacle nearest to agent ``i`` at the step's end."""
        return self.world.obstacles[int(np.argmin(self._field_cache[0][i]))].id

    def _guard_goals(self, s: SwarmState, q0: np.ndarray, qv0: np.ndarray) -> Tally:
        """The goal guard's threat test at the step's start (``swarmplan.sim.guard``); an agent
        that takes off flies straight back to its goal afterwards (the rest of its route is done)."""
        if self._field_cache is None:
            self._field_cache = self.field.query(s.position, q0)
        cache, mv = self._field_cache, self.moving_mask
        movers = (q0[mv], qv0[mv], self._mover_radii, self._mover_ids)

        def surface(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return self.scene.nearest_surface(rows, s.position[rows], cache[0][rows], cache[1][rows])

        tally = self.guard.update(s, movers, surface)
        for _, i in tally.counts:  # the take-offs
            if s.route[i] is not None:
                s.route_index[i] = len(s.route[i])
        return tally

    # ------------------------------------------------------------------ reports

    def distance_to_go(self) -> np.ndarray:
        """Per agent: straight to the goal, or along the rest of its global route."""
        return distance_to_go(self.state)

    def _agent_states(self) -> AgentStates:
        """The ``/agents/state`` entries, as arrays (no dict per agent: a log encodes them directly)."""
        s = self.state
        if self._compiled:  # both roundings in one compiled call (the same bits)
            position, velocity = step_kernels().round6(s.position, s.velocity)
        else:
            position, velocity = np.round(s.position, 6), np.round(s.velocity, 6)
        return AgentStates(self.ids, position, velocity, s.mode.copy(), s.goal)

    def _obstacle_states(self, t: float) -> ObstacleStates | None:
        """The ``/obstacles/state`` entries at ``t`` (None when nothing moves)."""
        return self.scene.obstacle_states(t)

    def summary(self, interrupted: bool = False) -> dict[str, Any]:
        """Per-agent and overall metrics for ``/summary`` and the CLI table."""
        return summary_report(
            self.world,
            self.state,
            self.metrics,
            seed=self.seed,
            optimizer=self.optimizer_name,
            wall_time=time.perf_counter() - self.wall_start,
            interrupted=interrupted,
        )

    @property
    def optimizer_name(self) -> str:
        if self.planner is None:
            return "none"
        return str(getattr(self.planner, "optimizer_name", self.world.planner_config.optimizer.name))
