"""Contracts shared by the simulator, the planners and the recorders: data types and protocols.

Nothing here does work; every other module may import it and it imports none of ours, so
it is the place to read first: what a run's state looks like (:class:`SwarmState`), what a
step reports (:class:`StepResult`, :class:`Event`), what a planner gives back
(:class:`PlannedSegment`) and what the simulator asks of planners and recorders.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Literal, Protocol, overload

import numpy as np

TIME_DIGITS = 9
"""Times are rounded to this many decimals: ``k * dt`` lands on the step grid (40.8, not
40.800000000000004), the same value the log carries."""


SEGMENT_REPULSION_SCALE = 0.3
"""Scale of static-obstacle repulsion while an agent follows a planned segment: FCL already
validated the segment, so the field only nudges. The escape planner's clearance target is
derived from it (``swarmplan.planner.escape``), so both read this one constant."""

REACH_STEPS = 3.0
"""A waypoint counts as reached within this many steps of flight at the current speed (or the
goal tolerance, if larger): waypoints are passed, not hit exactly."""


class Mode(StrEnum):
    """What an agent is doing; the values are the log's ``mode`` strings."""

    APF = "apf"  # flying the potential field (towards its goal or along its global route)
    ESCAPE = "escape"  # following an escape segment out of a trap
    SMOOTHING = "smoothing"  # following a curvature-smoothing segment
    ARRIVED = "arrived"
    COLLIDED = "collided"
    FAILED = "failed"  # the planner found no way out


SEGMENT_MODES = (Mode.ESCAPE, Mode.SMOOTHING)
DONE_MODES = (Mode.ARRIVED, Mode.COLLIDED, Mode.FAILED)
_FLYING = {m: m not in DONE_MODES for m in Mode}

# The last list of modes seen by mode_codes and the masks made of it, per table: (modes, {id(table):
# (table, mask)}). Replaced whole (never changed in place once another list comes), so a reader
# holding it sees one consistent pair.
_MODE_MEMO: tuple[list, dict[int, tuple[dict, np.ndarray]]] = ([], {})


def mode_codes(mode: np.ndarray, table: dict[Mode, Any], dtype: type = bool) -> np.ndarray:
    """Per agent, ``table[mode[i]]`` as an array of ``dtype`` (a new array each call; a value
    not in ``table`` is a ``KeyError``).

    Modes change a few times a run, and a step asks for several masks of the same modes
    (one lookup per agent in a table costs ~10 us at 64 agents): the masks of the last list of
    modes are kept, and a call whose modes equal it (one comparison of two lists, their
    entries mostly the same objects) copies the kept mask. Equal lists give equal masks, so
    the answer is the lookup's whatever the state it came from."""
    global _MODE_MEMO
    modes = mode.tolist()
    memo = _MODE_MEMO
    if memo[0] != modes:
        memo = _MODE_MEMO = (modes, {})
    kept = memo[1].get(id(table))
    if kept is None or kept[0] is not table or kept[1].dtype != dtype:
        # (the table is held with its mask: its id is not another's while kept)
        kept = (table, np.fromiter(map(table.__getitem__, modes), dtype=dtype, count=len(modes)))
        memo[1][id(table)] = kept
    return kept[1].copy()


@dataclass
class SwarmState:
    """Agent state at time ``t``; arrays have one row per agent in world order."""

    t: float
    step: int
    position: np.ndarray  # (N, 3)
    velocity: np.ndarray  # (N, 3)
    goal: np.ndarray  # (N, 3)
    mode: np.ndarray  # (N,) object array of Mode
    segment: list[np.ndarray | None] = field(default_factory=list)  # waypoints being followed, per agent
    segment_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    route: list[np.ndarray | None] = field(default_factory=list)  # global path waypoints, per agent
    route_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def active(self) -> np.ndarray:
        """Agents still flying (not arrived, collided or failed)."""
        # One dict lookup per agent, kept while the modes stay the same (mode_codes; np.isin on
        # an object array sorts and compares Python objects: ~4x the time).
        return mode_codes(self.mode, _FLYING)


class AgentEntries(Sequence):
    """Per-agent entries of a message kept as arrays, read as the list of dicts a recorder may
    iterate (one dict per agent, :meth:`entry`); equal to any sequence of the same dicts."""

    __slots__ = ("ids",)

    def __init__(self, ids: tuple[str, ...]):
        self.ids = ids

    def entry(self, i: int) -> dict[str, Any]:
        """Agent ``i``'s entry."""
        raise NotImplementedError

    def __len__(self) -> int:
        return len(self.ids)

    @overload
    def __getitem__(self, i: int) -> dict[str, Any]: ...
    @overload
    def __getitem__(self, i: slice) -> list[dict[str, Any]]: ...

    def __getitem__(self, i: int | slice) -> dict[str, Any] | list[dict[str, Any]]:
        if isinstance(i, slice):
            return [self.entry(k) for k in range(*i.indices(len(self)))]
        return self.entry(i)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Sequence) and list(self) == list(other)

    __hash__ = None  # type: ignore[assignment]


class AgentStates(AgentEntries):
    """The agents' entries of an ``/agents/state`` message, kept as arrays.

    Reads as the list of dicts ``{"id", "position", "velocity", "mode", "goal"}`` any recorder
    may iterate; recorders that know it (``swarmplan.io.recording.McapRecorder``) encode the
    arrays directly instead of building one dict per agent per step. ``position`` and
    ``velocity`` are already rounded as the log writes them.
    """

    __slots__ = ("position", "velocity", "mode", "goal")

    def __init__(
        self,
        ids: tuple[str, ...],
        position: np.ndarray,
        velocity: np.ndarray,
        mode: np.ndarray,
        goal: np.ndarray,
    ):
        super().__init__(ids)
        self.position = position
        self.velocity = velocity
        self.mode = mode
        self.goal = goal

    def entry(self, i: int) -> dict[str, Any]:
        return {
            "id": self.ids[i],
            "position": self.position[i].tolist(),
            "velocity": self.velocity[i].tolist(),
            "mode": str(self.mode[i]),
            "goal": self.goal[i].tolist(),
        }

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return iter(self.dicts())

    def dicts(self) -> list[dict[str, Any]]:
        """Every entry as a dict (one conversion of each array)."""
        pos, vel, goal = self.position.tolist(), self.velocity.tolist(), self.goal.tolist()
        return [
            {"id": aid, "position": p, "velocity": v, "mode": str(m), "goal": g}
            for aid, p, v, m, g in zip(self.ids, pos, vel, self.mode.tolist(), goal, strict=True)
        ]


class AgentAges(AgentEntries):
    """The agents' entries of a ``/comms`` message, kept as codes into the few ages a step has.

    Reads as the list of dicts ``{"id", "age"}`` any recorder may iterate; ``ages`` holds the
    distinct values (``ages[0]`` is None: no age) and ``code`` (N,) each agent's index into
    them, so a recorder that knows it (``swarmplan.io.recording.McapRecorder``) writes each
    distinct age once instead of one dict per agent per step.
    """

    __slots__ = ("ages", "code")

    def __init__(self, ids: tuple[str, ...], ages: tuple[float | None, ...], code: np.ndarray):
        super().__init__(ids)
        self.ages, self.code = ages, code

    def entry(self, i: int) -> dict[str, Any]:
        return {"id": self.ids[i], "age": self.ages[int(self.code[i])]}


@dataclass(frozen=True)
class Event:
    """Something that happened to an agent (or to the run when ``agent`` is None) at ``t``.

    The same shape as a ``/events`` message; ``t`` is rounded to the step grid on creation.
    """

    t: float
    agent: str | None
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", round(float(self.t), TIME_DIGITS))

    def to_json(self) -> dict[str, Any]:
        return {"t": self.t, "agent": self.agent, "kind": self.kind, "detail": self.detail}


@dataclass(frozen=True)
class OptimizerRun:
    """One optimizer run (escape, smoothing, global route): the fields of an ``/optimizer``
    message, in its order."""

    t: float
    agent: str | None
    algorithm: str
    purpose: str
    evaluations: int
    iterations: int
    best_cost: float
    wall_ms: float
    convergence: list[float]

    def to_json(self) -> dict[str, Any]:
        return {
            "t": self.t,
            "agent": self.agent,
            "algorithm": self.algorithm,
            "purpose": self.purpose,
            "evaluations": self.evaluations,
            "iterations": self.iterations,
            "best_cost": self.best_cost,
            "wall_ms": self.wall_ms,
            "convergence": self.convergence,
        }


class ObstacleStates:
    """The moving obstacles' entries of an ``/obstacles/state`` message, kept as arrays
    (``position`` and ``velocity`` already rounded as the log writes them); :meth:`dicts`
    gives the message's entries ``{"id", "position", "orientation", "velocity"}``."""

    __slots__ = ("ids", "position", "orientation", "velocity")

    def __init__(
        self, ids: tuple[str, ...], position: np.ndarray, orientation: list[list[float]], velocity: np.ndarray
    ):
        self.ids = ids
        self.position = position
        self.orientation = orientation  # per obstacle [qx, qy, qz, qw]
        self.velocity = velocity

    def __len__(self) -> int:
        return len(self.ids)

    def dicts(self) -> list[dict[str, Any]]:
        pos, vel = self.position.tolist(), self.velocity.tolist()
        return [
            {"id": oid, "position": p, "orientation": q, "velocity": v}
            for oid, p, q, v in zip(self.ids, pos, self.orientation, vel, strict=True)
        ]


@dataclass(frozen=True)
class PlannedSegment:
    """A segment an agent follows in ``mode`` (escape or smoothing) before returning to APF."""

    waypoints: np.ndarray  # (K, 3), the first is the next point to reach
    mode: Literal[Mode.ESCAPE, Mode.SMOOTHING] = Mode.ESCAPE
    route_index: int | None = None  # the global-route waypoint to go on from (e.g. a rounded corner skipped)


FAILED: Literal["failed"] = "failed"
"""What ``Planner.on_stuck`` returns when no escape exists (the agent then stops flying)."""

StuckOutcome = PlannedSegment | None | Literal["failed"]


@dataclass
class StepResult:
    """What one step did, and everything a log of it needs: the agents' and moving obstacles'
    entries at the step's end, the optimizer runs made during the step (logged before its
    state) and its events (logged after)."""

    state: SwarmState
    events: list[Event]
    terminated: bool
    truncated: bool
    agents: AgentStates | None = None
    obstacles: ObstacleStates | None = None  # None when nothing moves
    optimizer_runs: list[OptimizerRun] = field(default_factory=list)
    comms: dict[str, Any] | None = None  # the ``/comms`` message (worlds with ``comms`` only)


@dataclass
class ResetResult:
    """What a reset produced: the state at t = 0, the ``/world`` message, what planning before
    flight reported (optimizer runs and events, in the order they came) and the t = 0 entries
    of the agents and moving obstacles."""

    state: SwarmState
    world: dict[str, Any]
    records: list[OptimizerRun | Event]
    agents: AgentStates
    obstacles: ObstacleStates | None


class Observer(Protocol):
    """Sees a run from outside (a log, a live view, a progress bar): every reset and step result."""

    def on_reset(self, result: ResetResult) -> None: ...
    def on_step(self, result: StepResult) -> None: ...


class PlanningContext(Protocol):
    """What a planner may read of the running simulation, and the two ways it reports back."""

    world: Any  # swarmplan.world.World
    state: SwarmState
    ids: tuple[str, ...]
    n: int
    params: Any  # swarmplan.flight.kinematics.AgentParams
    collision: Any  # swarmplan.geometry.collision.CollisionWorld
    distances: Any  # the obstacles' distance field: swarmplan.geometry.shapes.ObstacleField
    moving_mask: np.ndarray
    guide: Any  # swarmplan.flight.guide.StaticGuide, None in worlds without static obstacles
    sight: Any  # swarmplan.flight.sight.Sight: fixed wings' clear lines and points of their ways

    def rng_for(self, purpose: str, agent: int | None = None) -> np.random.Generator:
        """The seeded random stream of one purpose ('global', 'escape', ...) for one agent."""

    def record_optimizer(
        self, agent: int | None, purpose: str, algorithm: str, result: Any, t: float | None = None
    ) -> None:
        """Report one optimizer run (a ``swarmplan.optimizers.Result``): it goes out with the
        running step's result (before flight: with the reset's)."""

    def note_event(self, agent: int | None, kind: str, detail: dict[str, Any]) -> None:
        """Report an event; it is recorded with the running step's events."""


class Planner(Protocol):
    """What the simulation asks of the refinement planner (see ``swarmplan.planner``)."""

    optimizer_name: str

    def on_reset(self, sim: PlanningContext) -> dict[int, np.ndarray]:
        """Global routes (waypoints to the goal) planned before flight, per agent index."""

    def on_stuck(self, sim: PlanningContext, agent: int) -> StuckOutcome:
        """A segment to escape a trap, None to keep flying APF, or ``FAILED`` to give up."""

    def on_step(self, sim: PlanningContext) -> dict[int, PlannedSegment]:
        """Segments to start this step for other reasons (e.g. curvature smoothing)."""


class Recorder(Protocol):
    """Where a run's messages go (``swarmplan.io.recording.McapRecorder`` writes MCAP). The
    simulator knows none: an observer (``swarmplan.io.runner.RecordingObserver``) writes what
    the reset and step results carry, and the runner writes ``/summary`` and closes it."""

    def write_world(self, world: dict[str, Any]) -> None: ...
    def write_state(
        self, t: float, agents: Sequence[dict], obstacles: ObstacleStates | list[dict] | None
    ) -> None:
        """``agents``: a list of dicts or an :class:`AgentStates` (which reads as one)."""

    def write_event(self, event: dict[str, Any]) -> None: ...
    def write_optimizer(self, msg: dict[str, Any]) -> None: ...
    def write_comms(self, msg: dict[str, Any]) -> None:
        """One ``/comms`` message (worlds with ``comms``)."""

    def write_summary(self, summary: dict[str, Any]) -> None: ...
    def close(self) -> None: ...
