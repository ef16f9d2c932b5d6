"""What a run reports besides its states: the random streams of the planner's purposes, and the
events and optimizer runs of the running step (or, before flight, of the reset).

:class:`~swarmplan.sim.env.Simulation` hands these to observers with each step's result; the
planner reaches them through the simulation (``rng_for``, ``record_optimizer``,
``note_event``: see ``swarmplan.core.PlanningContext``).
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from swarmplan.core import AgentStates, Event, OptimizerRun, StuckOutcome, SwarmState
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim.metrics import RunMetrics, Tally


class RunRecords:
    """The random streams, events and optimizer runs of one run (reset with :meth:`reset`)."""

    def __init__(self, ids: tuple[str, ...]):
        self.ids = ids
        self.seed: int | None = None
        self._streams: dict[tuple[str, int | None], np.random.Generator] = {}
        self.events: list[Event] = []  # the running step's events (see note_event)
        self.optimizer_runs: list[OptimizerRun] = []  # the running step's (see optimizer_run)
        self.before_flight: list[OptimizerRun | Event] | None = None  # planning before flight, in order

    def reset(self, seed: int) -> None:
        """A new run with ``seed``: no streams drawn, no events or optimizer runs yet."""
        self.seed = seed
        self._streams = {}
        self.events = []
        self.optimizer_runs = []

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

    def optimizer_run(
        self, metrics: RunMetrics, t: float, agent: int | None, purpose: str, algorithm: str, result: Any
    ) -> None:
        """One optimizer run (a ``swarmplan.optimizers.Result``) at ``t``: in ``metrics``, and in the
        running step's records (before flight: the reset's)."""
        wall_ms = float(result.wall_time) * 1000.0
        if agent is not None and purpose == "escape":
            metrics.escape_ms[agent].append(wall_ms)
        if agent is not None:
            metrics.optimizer_runs[agent] += 1
        run = OptimizerRun(
            t=round(t, 9),
            agent=None if agent is None else self.ids[agent],
            algorithm=algorithm,
            purpose=purpose,
            evaluations=int(result.evaluations),
            iterations=int(result.iterations),
            best_cost=float(result.f),
            wall_ms=round(wall_ms, 3),
            convergence=[float(x) for x in result.history],
        )
        (self.optimizer_runs if self.before_flight is None else self.before_flight).append(run)

    def event(self, t: float, agent: int | None, kind: str, detail: dict[str, Any]) -> None:
        """An event the planner reports at ``t`` (with the running step's events; before the
        first step, with the reset's records, between the optimizer runs it follows)."""
        event = Event(t, None if agent is None else self.ids[agent], kind, detail)
        (self.events if self.before_flight is None else self.before_flight).append(event)

    def merge(self, tally: Tally, metrics: RunMetrics) -> None:
        """Take in what one part of the step changed: its events (after those so far) and its counts."""
        self.events.extend(tally.events)
        metrics.merge(tally)

    def ask(self, call: Callable[[], StuckOutcome]) -> tuple[StuckOutcome, tuple[Event, ...]]:
        """The planner's answer ``call()`` and the events it reported meanwhile (taken out of the
        step's events: they go out with the answer)."""
        before = len(self.events)
        outcome = call()
        reported = tuple(self.events[before:])
        del self.events[before:]
        return outcome, reported

    def take(self) -> tuple[list[Event], list[OptimizerRun]]:
        """The running step's events and optimizer runs, handed over (the next step starts afresh)."""
        out = self.events, self.optimizer_runs
        self.events, self.optimizer_runs = [], []
        return out


def agent_states(ids: tuple[str, ...], s: SwarmState, compiled: bool) -> AgentStates:
    """The ``/agents/state`` entries, as arrays (no dict per agent: a log encodes them directly);
    ``compiled``: both roundings in one compiled call (the same bits)."""
    if compiled:
        position, velocity = kernel_module("swarmplan.sim._step_kernels").round6(s.position, s.velocity)
    else:
        position, velocity = np.round(s.position, 6), np.round(s.velocity, 6)
    return AgentStates(ids, position, velocity, s.mode.copy(), s.goal)
