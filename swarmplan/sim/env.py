"""The multi-UAV simulation: ``reset(seed=...)`` / ``step()`` in the manner of Gymnasium.

Each step, for every flying agent at once: field command (or segment following) → kinematic limits
→ swept FCL check of the step (feasible alternatives when it would touch something) and
deconfliction → the committed step checked again (contact ends the agent) → arrival, stuck and
near-miss detection → the step's result (everything a log needs; observers write it). ``terminated``:
every agent arrived, collided or failed; ``truncated``: the world's ``sim.max_time`` ran out.

This module only orchestrates; the jobs live beside it: ``obstacles`` (obstacles, distances),
``steering`` (the field's commands, the guide, loiters), ``navigation`` (plans, stuck detection),
``safety`` and ``deconflict`` (the step's checks), ``contacts`` (collisions, arrival, near misses),
``evasion`` (arrived multirotors out of a mover's way), ``network`` (what each agent has heard, with
``comms``), ``records`` (random streams, events, optimizer runs).
"""

from __future__ import annotations

import time
from typing import Any, Literal

import numpy as np

from swarmplan.core import (
    DONE_MODES,
    Event,
    Mode,
    OptimizerRun,
    Planner,
    ResetResult,
    StepResult,
    StuckOutcome,
    SwarmState,
)
from swarmplan.flight.guide import StaticGuide
from swarmplan.flight.kinematics import AgentParams
from swarmplan.flight.sight import Sight
from swarmplan.planner import make_planner
from swarmplan.runtime.compiled import use_compiled_checks
from swarmplan.sim.contacts import NearMisses, agent_collisions, arrivals, committed_hits, parked_contacts
from swarmplan.sim.evasion import Evasion
from swarmplan.sim.metrics import NOTHING, RunMetrics, Tally, summary_report
from swarmplan.sim.modes import ARRIVED, PARKED, mode_in
from swarmplan.sim.navigation import distance_to_go, initial_state, timeouts
from swarmplan.sim.network import AgentView
from swarmplan.sim.obstacles import Obstacles
from swarmplan.sim.records import RunRecords, agent_states
from swarmplan.sim.safety import AgentMotion, Commands, SafetyFilter, StepWindow
from swarmplan.sim.steering import Steering
from swarmplan.world.model import World


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
        self.obstacles = Obstacles(world, self.params)
        self.steering = st = Steering(world, self.params, self.obstacles)
        self.apf, self.navigator, self.loiter = st.apf, st.navigator, st.loiter
        # What planners read (see swarmplan.core.PlanningContext).
        self.collision = self.obstacles.collision
        self.distances = self.obstacles.distances
        self.moving_mask = self.obstacles.moving_mask
        self.n = len(world.agents)
        self.ids = self.params.ids
        self.safety = SafetyFilter(world, self.params, self.obstacles)
        # Swarm size or fixed wings: compiled per-step helpers (runtime.compiled).
        self._compiled = use_compiled_checks(self.n, bool(self.params.fixed_wing.any()))
        self._every_agent = np.ones(self.n, dtype=bool)  # (read only)
        self._every_agent.setflags(write=False)
        self.evasion = Evasion(self.params, world.dt, (world.bounds_min, world.bounds_max))
        self.state: SwarmState | None = None
        self.seed: int | None = None
        self.metrics: RunMetrics | None = None
        self.wall_start = 0.0
        self.records = RunRecords(self.ids)
        self.network = st.network  # what each agent has heard of the others (None: it knows the truth)

    @property
    def guide(self) -> StaticGuide | None:
        """The way round static obstacles for agents whose straight line is blocked (None without any)."""
        return self.steering.guide

    @property
    def sight(self) -> Sight:
        """Per fixed wing: whether its line to its goal is clear, else the point of its way in sight."""
        return self.steering.sight

    # ------------------------------------------------------------------ lifecycle

    def reset(self, seed: int | None = None) -> SwarmState:
        """Start the run at t = 0 with ``seed`` (default: the world's seed)."""
        return self.start(seed).state

    def start(self, seed: int | None = None) -> ResetResult:
        """:meth:`reset`, with what it produced for observers: the ``/world`` message, the
        optimizer runs and events of planning before flight, the entries at t = 0."""
        self.seed = self.world.seed if seed is None else int(seed)
        self.records.reset(self.seed)
        self.state = initial_state(self.world, self.params)
        start, goal = self.state.position, self.state.goal
        self.metrics = RunMetrics(self.ids, len(self.world.obstacles))
        self.metrics.positions.append(start.copy())
        # The clearances at the start count too (a log's replay measures every sample from t = 0:
        # an agent that starts nearer to something than it ever flies was reported farther).
        self.metrics.measure_start(*self.obstacles.clearances(start, self.obstacles.poses(0.0)[0]))
        self.steering.reset(start, goal)
        if self.network is not None:
            self.network.reset(self.rng_for("comms"), self.state)
        self.navigator.reset(self.state)
        self.evasion.reset()
        self.safety.turn[:] = 0.0  # fixed wings start straight and level
        self.near_misses = NearMisses(self.params)
        self._distance_cache: tuple[np.ndarray, np.ndarray] | None = None
        self.wall_start = time.perf_counter()
        world_message = self.world.to_message(self.seed)
        records: list[OptimizerRun | Event] = []
        if self.planner is not None:
            self.records.before_flight = records  # its runs and events in the order they come
            try:
                routes = self.planner.on_reset(self)
            finally:
                self.records.before_flight = None
            for i, route in routes.items():
                self.state.route[i] = np.asarray(route, dtype=float)
            self.navigator.reset(self.state)
        agents = agent_states(self.ids, self.state, self._compiled)
        return ResetResult(self.state, world_message, records, agents, self.obstacles.obstacle_states(0.0))

    def rng_for(self, purpose: str, agent: int | None = None) -> np.random.Generator:
        """The random stream of one purpose for one agent (:meth:`RunRecords.rng_for`)."""
        return self.records.rng_for(purpose, agent)

    def record_optimizer(
        self, agent: int | None, purpose: str, algorithm: str, result: Any, t: float | None = None
    ) -> None:
        """One optimizer run (a ``swarmplan.optimizers.Result``): in the metrics, and in the running
        step's result (``optimizer_runs``; before flight: the reset's ``records``)."""
        when = self.state.t if t is None else t
        self.records.optimizer_run(self.metrics, when, agent, purpose, algorithm, result)

    def note_event(self, agent: int | None, kind: str, detail: dict[str, Any]) -> None:
        """An event the planner reports during ``step()`` (recorded with that step's events)."""
        if self.state is None:
            raise RuntimeError("call reset() before note_event()")
        self.records.event(self.state.t, agent, kind, detail)

    def _merge(self, tally: Tally) -> None:
        """Take in what one part of the step changed: its events (after those so far) and its counts."""
        if tally is not NOTHING:  # (most parts of most steps change nothing)
            self.records.merge(tally, self.metrics)

    def _ask_planner(self, i: int) -> tuple[StuckOutcome, tuple[Event, ...]]:
        """The planner's answer for stuck agent ``i`` and the events it reported meanwhile."""
        context = self if self.network is None else AgentView(self, i)  # with comms: what i knows
        return self.records.ask(lambda: self.planner.on_stuck(context, i))

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
        t0, t1 = s.t, (s.step + 1) * dt
        q0, qv0 = self.obstacles.poses(t0)
        q1, _ = self.obstacles.poses(t1)
        # Arrived multirotors under threat take off again (mode apf) to get out of its way.
        flying_before = ~mode_in(s.mode, ARRIVED)
        if self.evasion.watching.any():
            if self._distance_cache is None:
                self._distance_cache = self.distances.query(s.position, q0)
            surface = self.obstacles.surface_of(s.position, self._distance_cache)
            # (without movers no pair is a mover's: the surfaces would change none)
            shapes = self.obstacles.mover_surfaces(q0) if self.obstacles.mover_ids else None
            self._merge(self.evasion.update(s, self.obstacles.movers(q0, qv0), surface, shapes))
        active = s.active
        flying_now = self.loiter.flying(s, active)  # arrived fixed wings fly on round their goals
        idx = flying_now.nonzero()[0]
        # Every agent is measured at every step, whatever its mode: an arrived one hovers at its
        # goal, a failed or collided one stays where it stopped, and a mover may pass any of them.
        measured = self._every_agent
        touched = False  # whether a mode set this step ended an agent (a collision)

        # Extra segments from the planner (e.g. smoothing) start before commands are formed.
        if self.planner is not None and len(idx):
            for i, seg in self.planner.on_step(self).items():
                if s.mode[i] == Mode.APF and not self.evasion.watching[i]:
                    touched |= seg.mode in DONE_MODES  # not a segment's mode: ask the modes again
                    self._merge(nav.start_segment(s, i, seg))

        pos0, vel0 = s.position.copy(), s.velocity.copy()
        oldest = None  # with comms: the oldest state each flyer acted on
        if not len(idx):  # the step of agents that do not fly
            pos1, vel1 = pos0.copy(), np.zeros_like(vel0)
        else:
            # The previous step already measured every agent's distances at this position and time.
            if self._distance_cache is None:
                self._distance_cache = self.distances.query(pos0, q0)
            # Parked: not flying (modes changed above stay flying ones: arrivals come later).
            cmd = self.steering.commands(s, idx, pos0, vel0, self._distance_cache, q0, qv0, ~flying_now)
            self._merge(cmd.ended)
            oldest = cmd.oldest
            v_cmd = self.evasion.commands(idx, cmd.velocity)
            v_cmd, guarded = self.safety.guard_fixed_wings(
                idx, pos0, vel0, v_cmd, cmd.obstacle_distance, cmd.clearance, t0
            )
            self._merge(guarded)
            brake_goal = self.evasion.brake_goals(idx, cmd.position, cmd.goal)
            window = StepWindow(t0, t1, q0, q1)
            agreed = None if self.network is None else self.network.agreed(t0)
            filtered = self.safety.fly(
                Commands(idx, v_cmd, cmd.beliefs, agreed), AgentMotion(pos0, vel0), window, s.mode, brake_goal
            )
            pos1, vel1, validated = filtered.end.position, filtered.end.velocity, filtered.validated
            self._merge(filtered.tally)
            # Contact on the committed step ends the agent. Steps the filter cleared with a
            # margin cannot touch anything; the rest (stops, agent-conflict brakes) are checked.
            hits, touched_any = committed_hits(
                self.obstacles, s, self.ids, idx[~validated], pos0, pos1, vel1, window
            )
            touched |= touched_any
            self._merge(hits)
        contacts = agent_collisions(
            s, self.ids, pos0, pos1, self.params.radius, flying_now, t1, compiled=self._compiled
        )
        touched |= bool(contacts.contacts)
        self._merge(contacts)

        # Arrival (and its stop) only at a speed a one-step stop can take within max_accel.
        # Agents out of a threat's way cannot arrive; one back at its goal ends its evasion.
        stop_speed = self.evasion.stop_speeds()
        # Only a collision ends an agent between the step's start and here (segments, their ends and
        # the evasions' take-offs keep agents flying): who still flies is known without asking every mode.
        flying = s.active if touched else active
        flown = vel1.copy() if self.loiter.fixed_wings else None
        arrived = arrivals(
            s, self.ids, pos0, pos1, vel1, w.goal_tolerance, t1, stop_speed, flying, compiled=self._compiled
        )
        self.loiter.fly_on(arrived.arrivals, pos1, vel1, flown, self.safety.turn, self.obstacles)
        self._merge(self.evasion.arrived(arrived, s))

        # Clearances at the committed positions (also the next step's distances).
        self._distance_cache = self.distances.query(pos1, q1)
        obst_clear, agent_clear, terr_clear = self.obstacles.clearances(pos1, q1, self._distance_cache[0])
        parked = mode_in(s.mode, PARKED)
        if len(self.world.obstacles) and parked.any():
            # Arrived and failed agents stay in the air: an obstacle moving through one is a collision.
            self._merge(parked_contacts(s, self.ids, obst_clear, self._nearest_obstacle, t1))
        self.metrics.add_step(pos0, pos1, measured, obst_clear, agent_clear, terr_clear, flying_before)
        self._merge(self.near_misses.update(pos1, active, t1))

        s.position, s.velocity, s.t, s.step = pos1, vel1, t1, s.step + 1
        if self.network is not None:
            parked_now = ~self.loiter.flying(s, s.active)
            self.network.broadcast(t0, s, parked_now, (vel1 - vel0) / dt, self.loiter.on)
        on_stuck = None if self.planner is None else self._ask_planner
        capturing = self.steering.capture.hold if self.steering.capture.any else None
        self._merge(nav.detect_stuck(s, on_stuck, exempt=self.evasion.watching, restart=capturing))

        terminated = not s.active.any()
        truncated = (not terminated) and t1 >= w.max_time - 1e-9
        if truncated:
            self._merge(timeouts(s, self.ids))
        events, runs = self.records.take()
        agents = agent_states(self.ids, self.state, self._compiled)
        comms = None if self.network is None else self.network.message(t1, self.ids, idx, oldest)
        obstacles = self.obstacles.obstacle_states(t1)
        return StepResult(s, events, terminated, truncated, agents, obstacles, runs, comms)

    def _nearest_obstacle(self, i: int) -> str:
        """The id of the obstacle nearest to agent ``i`` at the step's end."""
        return self.world.obstacles[int(np.argmin(self._distance_cache[0][i]))].id

    # ------------------------------------------------------------------ reports

    def distance_to_go(self) -> np.ndarray:
        """Per agent: straight to the goal, or along the rest of its global route."""
        return distance_to_go(self.state)

    def summary(self, interrupted: bool = False) -> dict[str, Any]:
        """Per-agent and overall metrics for ``/summary`` and the CLI table."""
        wall = time.perf_counter() - self.wall_start
        report = summary_report(self.world, self.state, self.metrics, seed=self.seed,
                                optimizer=self.optimizer_name, wall_time=wall,
                                interrupted=interrupted)  # fmt: skip
        if self.network is not None:
            report["comms"] = self.network.run_report()
        return report

    @property
    def optimizer_name(self) -> str:
        if self.planner is None:
            return "none"
        return str(getattr(self.planner, "optimizer_name", self.world.planner_config.optimizer.name))
