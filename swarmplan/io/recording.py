"""MCAP recording of a run, per the log format (docs/log-format.md).

JSON channels with ``jsonschema`` schemas, timestamps in simulation nanoseconds, zstd
chunks, written by foxglove-sdk (``swarmplan.io.sink``, which also serves them live with
``live=(host, port)``). The writer is flushed every ``flush_interval`` simulated seconds so a
hard kill loses at most about that much; ``close`` always finishes the file (use the recorder
as a context manager). Foxglove's protobuf scene channels are written alongside when enabled.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.core import AgentAges, AgentStates, Mode, ObstacleStates
from swarmplan.io.foxglove_scene import FoxgloveScene
from swarmplan.io.json_floats import Interleaved
from swarmplan.io.sink import LogSink
from swarmplan.runtime.compiled import use_compiled

_NUM3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}

SCHEMAS: dict[str, dict[str, Any]] = {
    "/world": {
        "title": "swarmplan.World",
        "type": "object",
        "required": ["name", "bounds", "agents", "seed", "swarmplan_version"],
        "properties": {
            "name": {"type": "string"},
            "seed": {"type": "integer"},
            "swarmplan_version": {"type": "string"},
            "bounds": {"type": "object"},
            "agents": {"type": "array"},
            "obstacles": {"type": "array"},
        },
    },
    "/agents/state": {
        "title": "swarmplan.AgentsState",
        "type": "object",
        "required": ["t", "agents"],
        "properties": {
            "t": {"type": "number"},
            "agents": {
                "type": "array",
                "items": {
                    "type": "object",
                    "required": ["id", "position", "velocity", "mode", "goal"],
                    "properties": {
                        "id": {"type": "string"},
                        "position": _NUM3,
                        "velocity": _NUM3,
                        "goal": _NUM3,
                        "mode": {"enum": [m.value for m in Mode]},
                    },
                },
            },
        },
    },
    "/obstacles/state": {
        "title": "swarmplan.ObstaclesState",
        "type": "object",
        "required": ["t", "obstacles"],
        "properties": {
            "t": {"type": "number"},
            "obstacles": {
                "type": "array",
                "items": {
                    "type": "object",
                    "required": ["id", "position", "orientation"],
                    "properties": {
                        "id": {"type": "string"},
                        "position": _NUM3,
                        "orientation": {
                            "type": "array",
                            "items": {"type": "number"},
                            "minItems": 4,
                            "maxItems": 4,
                        },
                        "velocity": _NUM3,
                    },
                },
            },
        },
    },
    "/events": {
        "title": "swarmplan.Event",
        "type": "object",
        "required": ["t", "agent", "kind", "detail"],
        "properties": {
            "t": {"type": "number"},
            "agent": {"type": ["string", "null"]},
            "kind": {"type": "string"},
            "detail": {"type": "object"},
        },
    },
    "/optimizer": {
        "title": "swarmplan.OptimizerRun",
        "type": "object",
        "required": [
            "t",
            "agent",
            "algorithm",
            "purpose",
            "evaluations",
            "iterations",
            "best_cost",
            "wall_ms",
            "convergence",
        ],
        "properties": {
            "t": {"type": "number"},
            "agent": {"type": ["string", "null"]},
            "algorithm": {"type": "string"},
            "purpose": {"type": "string"},
            "evaluations": {"type": "integer"},
            "iterations": {"type": "integer"},
            "best_cost": {"type": ["number", "null"]},
            "wall_ms": {"type": "number"},
            "convergence": {"type": "array", "items": {"type": ["number", "null"]}},
        },
    },
    "/summary": {
        "title": "swarmplan.Summary",
        "type": "object",
        "required": ["interrupted", "success", "wall_time", "agents"],
        "properties": {
            "interrupted": {"type": "boolean"},
            "success": {"type": "boolean"},
            "wall_time": {"type": "number"},
            "sim_time": {"type": "number"},
            "agents": {"type": "array"},
        },
    },
}


_MODE_JSON = {m: json.dumps(str(m)) for m in Mode}
# json.dumps(..., separators=(",", ":"), allow_nan=False), its encoder made once (json.dumps
# makes one per call when given options)
_COMPACT = json.JSONEncoder(separators=(",", ":"), allow_nan=False)


# From this many numbers on, Interleaved's ~40 numpy calls cost less than a %r per number
# (equal at ~30 agents: 200 numbers; measured 16 agents 77 vs 165 us, 64: 251 vs 164 us).
_NUMPY_FROM = 200


class _StateEncoder:
    """``/agents/state`` from :class:`AgentStates`: its text around the numbers is fixed while
    the agents, goals and modes stay the same, and the numbers are written all at once
    (:class:`~swarmplan.io.json_floats.Interleaved`; one ``%r`` format for a few agents).

    The bytes are ``json.dumps(..., separators=(",", ":"))``'s: floats as ``repr`` writes
    them, ids and goals encoded by ``json`` itself once. Building a dict and a list per agent
    and walking them in the encoder was ~60 % of the recorder's JSON time at 256 agents, and
    then the ``repr`` of every number (``%r``) most of what remained."""

    def __init__(self) -> None:
        self.compiled = False  # write the numbers in one compiled pass (same bytes)
        self._key: tuple[tuple[str, ...], bytes] | None = None
        self._pieces: list[bytes] = []  # the text around the numbers (1 + 6 per agent + 1)
        self._tails: list[dict] = []  # per agent and mode: the piece after its last number
        self._goals: list[str] = []  # per agent: ',"goal":[..]}'
        self._nexts: list[str] = []  # per agent: what follows its goal up to the next number
        self._modes: list | None = None
        self._text: Interleaved | str = ""  # the numbers' fixed text (a %-format for few agents)

    def _tail(self, i: int, mode: object) -> bytes:
        """Agent ``i``'s piece after its velocity in ``mode``: '],"mode":..,"goal":[..]}' and
        what follows up to the next agent's first number (or the message's end)."""
        tail = self._tails[i].get(mode)
        if tail is None:
            mode_json = _MODE_JSON.get(mode) or json.dumps(str(mode))
            tail = self._tails[i][mode] = f'],"mode":{mode_json}{self._goals[i]}{self._nexts[i]}'.encode()
        return tail

    def _layout(self, agents: AgentStates, goal: np.ndarray) -> None:
        """The pieces that depend on the ids and goals only (the modes' pieces follow)."""
        heads = [f'{{"id":{json.dumps(aid)},"position":[' for aid in agents.ids]
        self._goals = [
            f',"goal":{json.dumps(g, separators=(",", ":"), allow_nan=False)}}}' for g in goal.tolist()
        ]
        self._nexts = ["," + h for h in heads[1:]] + ["]}"]
        self._tails = [{} for _ in heads]
        # the text before each number: t first, then x, y, z, vx, vy, vz of every agent
        pieces = [b'{"t":', (',"agents":[' + heads[0]).encode() if heads else b',"agents":[]}']
        for _ in heads:
            pieces += [b",", b",", b'],"velocity":[', b",", b",", b""]
        self._pieces = pieces

    def encode(self, t: float, agents: AgentStates) -> bytes | None:
        """The message's bytes, or None when a value is not finite (the caller then goes
        through ``json``, which refuses it as before)."""
        pos, vel = agents.position, agents.velocity
        if not self.compiled and not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            return None  # (compiled: the numbers' pass refuses them, then the check below)
        goal = np.ascontiguousarray(agents.goal, dtype=float)
        key = (agents.ids, goal.tobytes())
        if key != self._key:
            self._layout(agents, goal)
            self._key, self._modes = key, None
        modes = agents.mode.tolist()
        if self.compiled and not (isinstance(self._text, Interleaved) and self._text.compiled):
            self._modes = None
        if modes != self._modes:
            # only the pieces of agents whose mode changed are made again
            old = self._modes if self._modes is not None else [None] * len(modes)
            pieces = self._pieces
            changed = [i for i, (m, was) in enumerate(zip(modes, old, strict=True)) if m != was]
            for i in changed if self._modes is not None else range(len(modes)):
                pieces[7 + 6 * i] = self._tail(i, modes[i])
            known = self._modes is not None and isinstance(self._text, Interleaved)
            self._modes = modes
            if known and self._text.compiled == self.compiled:
                self._text.replace([7 + 6 * i for i in changed], pieces)  # the same layout otherwise
            elif self.compiled or len(pieces) - 1 >= _NUMPY_FROM:
                self._text = Interleaved(pieces, compiled=self.compiled)
            else:
                self._text = "%r".join(p.decode().replace("%", "%%") for p in pieces)
        if not isinstance(self._text, str) and self._text.compiled:
            data = self._text.fill_rows(round(t, 9), pos, vel)  # read in place, compiled
            if data is not None:
                return data
        n = len(agents.ids)
        values = np.empty(1 + 6 * n)
        values[0] = round(t, 9)
        rows = values[1:].reshape(n, 6)
        rows[:, 0:3], rows[:, 3:6] = pos, vel
        if isinstance(self._text, str):
            return (self._text % tuple(values.tolist())).encode()
        if self._text.compiled and not np.isfinite(values).all():
            return None
        return self._text.fill(values)


class _ObstacleEncoder:
    """``/obstacles/state`` from :class:`ObstacleStates`: the text around the numbers (ids and
    the fixed orientations) once per set of movers, then t, positions and velocities written
    into it (:class:`~swarmplan.io.json_floats.Interleaved`); the bytes ``json.dumps`` gives."""

    def __init__(self) -> None:
        self.compiled = False
        self._key: tuple[tuple[str, ...], bool] | None = None
        self._text: Interleaved | None = None

    def encode(self, t: float, obstacles: ObstacleStates) -> bytes | None:
        pos, vel = obstacles.position, obstacles.velocity
        if not self.compiled and not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            return None  # (compiled: the numbers' pass refuses them, then the check below)
        key = (obstacles.ids, self.compiled)
        if key != self._key or self._text is None:
            text = ['{"t":', ',"obstacles":[']
            for i, (oid, q) in enumerate(zip(obstacles.ids, obstacles.orientation, strict=True)):
                text[-1] += f'{{"id":{json.dumps(oid)},"position":['
                orientation = json.dumps(q, separators=(",", ":"), allow_nan=False)
                text += [",", ",", f'],"orientation":{orientation},"velocity":[', ",", ","]
                text.append("]}" + ("," if i < len(obstacles.ids) - 1 else ""))
            text[-1] += "]}"
            self._text = Interleaved([p.encode() for p in text], compiled=self.compiled)
            self._key = key
        if self.compiled:
            data = self._text.fill_rows(round(t, 9), pos, vel)  # read in place, compiled
            if data is not None:
                return data
            if not (np.isfinite(pos).all() and np.isfinite(vel).all()):
                return None
        n = len(obstacles.ids)
        values = np.empty(1 + 6 * n)
        values[0] = round(t, 9)
        rows = values[1:].reshape(n, 6)
        rows[:, 0:3], rows[:, 3:6] = pos, vel
        return self._text.fill(values)


COMMS_SCHEMA: dict[str, Any] = {
    "title": "swarmplan.Comms",
    "type": "object",
    "required": ["t", "agents", "sent", "lost", "out_of_range"],
    "properties": {
        "t": {"type": "number"},
        "agents": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["id", "age"],
                "properties": {"id": {"type": "string"}, "age": {"type": ["number", "null"]}},
            },
        },
        "sent": {"type": "integer"},
        "lost": {"type": "integer"},
        "out_of_range": {"type": "integer"},
    },
}
"""``/comms``: per step and agent the age of the oldest state of another agent it acted on
(null: none near, or not flying), and the run's messages so far."""


class CommsText:
    """Each agent's fixed text in ``/comms`` (``{"id":...,"age":``), made once: by id, and as
    the list for the tuple of ids a run's steps all share."""

    def __init__(self) -> None:
        self.by_id: dict[str, str] = {}
        self._ids: tuple[str, ...] | None = None
        self._heads: list[str] = []

    def head(self, name: str) -> str:
        head = self.by_id.get(name)
        if head is None:
            head = self.by_id[name] = '{"id":' + _COMPACT.encode(name) + ',"age":'
        return head

    def heads(self, ids: tuple[str, ...]) -> list[str]:
        if ids is not self._ids:
            self._ids, self._heads = ids, [self.head(name) for name in ids]
        return self._heads


def comms_json(msg: dict[str, Any], text: CommsText) -> bytes:
    """A ``/comms`` message as ``json.dumps(msg, separators=(",", ":"))`` writes it (its agents
    hold an ``id`` and a finite or null ``age``; as a list of dicts or an :class:`AgentAges`,
    whose distinct ages are written once each), each agent's fixed text made once in
    ``text``: the general encoder's pass over a swarm's entries cost more than the step's
    network."""
    agents = msg["agents"]
    if isinstance(agents, AgentAges):
        ages = np.array([_age_text(age) for age in agents.ages], dtype=object)
        parts = (np.array(text.heads(agents.ids), dtype=object) + ages[agents.code]).tolist()
    else:
        parts = [text.head(a["id"]) + _age_text(a["age"]) for a in agents]
    rest = _COMPACT.encode({**msg, "agents": []})
    cut = rest.index('"agents":[') + len('"agents":[')
    return (rest[:cut] + ",".join(parts) + rest[cut:]).encode()


def _age_text(age: float | None) -> str:
    """An age as JSON writes it, with its entry's closing brace."""
    text = "null" if age is None else float.__repr__(age) if type(age) is float else _COMPACT.encode(age)
    return text + "}"


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def _clean(x: Any) -> Any:
    """JSON cannot hold inf/nan: they become null."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


class McapRecorder:
    """Writes one run to ``path``. Use ``with McapRecorder(...) as rec:`` so the file is always finished."""

    def __init__(
        self,
        path: str | Path,
        flush_interval: float = 1.0,
        foxglove: bool = True,
        live: tuple[str, int] | None = None,
    ):
        """``live=(host, port)``: also serve every channel live (Foxglove WebSocket protocol;
        port 0: a free one, see :attr:`live_port`)."""
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = LogSink(self.path, live)
        self._channels: dict[str, int] = {}
        self._comms_text = CommsText()
        for topic, schema in SCHEMAS.items():
            self.add_json_channel(topic, schema)
        self._flush_interval = flush_interval
        self._last_flush = 0.0
        self._foxglove_enabled = foxglove
        self._scene = None
        self._last_t = 0.0
        self._states = _StateEncoder()
        self._obstacle_text = _ObstacleEncoder()
        self._states_written = 0
        self._compiled = False  # set by the world's size (write_world)
        self.closed = False

    @property
    def live_port(self) -> int | None:
        """The live view's port (None when not served)."""
        return self._writer.port

    def add_json_channel(self, topic: str, schema: dict[str, Any]) -> None:
        """Register a JSON channel (``schema["title"]`` names its JSON schema) beside the contract's."""
        sid = self._writer.register_schema(
            name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
        )
        self._channels[topic] = self._writer.register_channel(
            topic=topic, message_encoding="json", schema_id=sid
        )

    def add_protobuf_channel(self, topic: str, schema_name: str, descriptor_set: bytes) -> None:
        """Register a protobuf channel whose schema is the serialized ``FileDescriptorSet``."""
        sid = self._writer.register_schema(name=schema_name, encoding="protobuf", data=descriptor_set)
        self._channels[topic] = self._writer.register_channel(
            topic=topic, message_encoding="protobuf", schema_id=sid
        )

    def write_json(self, topic: str, t: float, msg: dict[str, Any]) -> None:
        """One message on a channel added with :meth:`add_json_channel` (``msg`` must be finite)."""
        self._write(topic, t, msg, clean=False)

    def write_bytes(self, topic: str, t: float, data: bytes) -> None:
        """One already-serialized message (e.g. protobuf) on a registered channel."""
        self._writer.add_message(self._channels[topic], _ns(t), data)

    def _write(self, topic: str, t: float, msg: dict[str, Any], clean: bool = True) -> None:
        # States are finite by construction; other messages may hold inf (e.g. an unreachable
        # cost): the encoder refuses them, then they are cleaned (nearly every message is
        # finite, and the walk that cleans costs more than the encoding).
        try:
            text = _COMPACT.encode(msg)
        except ValueError:
            if not clean:
                raise
            text = _COMPACT.encode(_clean(msg))
        self.write_bytes(topic, t, text.encode())

    def write_world(self, world: dict[str, Any]) -> None:
        self._write("/world", 0.0, world)
        # Swarm-sized worlds and those with fixed wings write the per-step numbers compiled, as their
        # step runs compiled.
        agents = world.get("agents") or []
        self._compiled = use_compiled(len(agents), any(a.get("model") == "fixed_wing" for a in agents))
        if self._foxglove_enabled:
            self._scene = FoxgloveScene(self._writer, world)
            self._scene.write_world()

    def write_state(
        self, t: float, agents: Sequence[dict], obstacles: ObstacleStates | list[dict] | None
    ) -> None:
        self._last_t = t
        self._states_written += 1
        self._writer.tick(_ns(t))
        if self._states_written == 3 and self._compiled:
            # from the second step on (the first one and start-up stay without numba's load)
            self._states.compiled = self._obstacle_text.compiled = True
            if self._scene is not None:
                self._scene.compiled = True
        data = self._states.encode(t, agents) if isinstance(agents, AgentStates) else None
        if data is not None:
            self.write_bytes("/agents/state", t, data)
        else:
            entries = agents.dicts() if isinstance(agents, AgentStates) else agents
            self._write("/agents/state", t, {"t": round(t, 9), "agents": entries}, clean=False)
        if obstacles is not None:
            moving = isinstance(obstacles, ObstacleStates)
            data = self._obstacle_text.encode(t, obstacles) if moving else None
            if data is not None:
                self.write_bytes("/obstacles/state", t, data)
            else:
                entries = obstacles.dicts() if moving else obstacles
                self._write("/obstacles/state", t, {"t": round(t, 9), "obstacles": entries}, clean=False)
        if self._scene is not None:
            self._scene.write_step(t, agents, obstacles if obstacles is not None else [])
        if t - self._last_flush >= self._flush_interval - 1e-9:
            self._writer.flush()
            self._last_flush = t

    def write_event(self, event: dict[str, Any]) -> None:
        self._write("/events", float(event["t"]), event)
        if self._scene is not None:
            self._scene.write_event(event)

    def write_optimizer(self, msg: dict[str, Any]) -> None:
        self._write("/optimizer", float(msg["t"]), msg)

    def write_comms(self, msg: dict[str, Any]) -> None:
        """One ``/comms`` message (its channel added with the first: worlds without comms have none)."""
        if "/comms" not in self._channels:
            self.add_json_channel("/comms", COMMS_SCHEMA)
        self.write_bytes("/comms", float(msg["t"]), comms_json(msg, self._comms_text))

    def write_summary(self, summary: dict[str, Any]) -> None:
        self._write("/summary", self._last_t, summary)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            if self._scene is not None:
                self._scene.finish()  # the last throttled scene update
        finally:
            self._writer.close()

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
