"""Foxglove 3D scene channels for a swarmplan run log.

:class:`FoxgloveScene` adds, next to the JSON analysis channels of the log contract,
channels that use Foxglove's own protobuf schemas (package ``foxglove_schemas_protobuf``)
so that opening the MCAP file in the Foxglove app shows the run in a 3D panel with no
setup (frame ``world``):

=================  ======================  ==============================================
topic              schema                  content
=================  ======================  ==============================================
``/scene/world``   ``foxglove.SceneUpdate``  once at t = 0: static obstacles (cubes,
                                           spheres, cylinders, capsules as cylinder + two
                                           spheres, meshes as triangle lists), bounds box,
                                           terrain surface, goals
``/scene``         ``foxglove.SceneUpdate``  agents (spheres coloured by mode) and moving
                                           obstacles; every ``scene_period`` s of sim time
``/scene/paths``   ``foxglove.SceneUpdate``  flown paths as they grow: every ``path_period`` s,
                                           per agent that moved, one new line strip
                                           ``path/<id>/<k>`` (k = 0, 1, ...) holding only
                                           the points sampled since its chunk k - 1, from
                                           that chunk's last point on (the chunks join)
``/scene/paths/overview``  ``foxglove.SceneUpdate``  every ``overview_period`` s: each
                                           agent's whole path as ``path/<id>``, at most
                                           ``overview_points`` points (evenly spaced over
                                           the kept samples), drawn thinner
``/agents/speed``  JSON                    with each ``/scene``: every agent's speed, their
                                           mean and maximum (for plots)
``/events/log``    ``foxglove.Log``        each ``/events`` message as a log entry (name:
                                           the agent, message: kind and detail)
``/tf``            ``foxglove.FrameTransforms`` every ``tf_period`` s (the scene's rate) a
                                           message holding a ``FrameTransform`` per agent:
                                           parent ``world``, child = agent id
=================  ======================  ==============================================

Static, dynamic and path entities are on separate topics because Foxglove, after a seek,
restores each topic from its latest message only. Every message is bounded independently
of the run's length: a path's chunks accumulate in the 3D panel during playback (entities
without a lifetime stay until replaced), and after a seek the overview's latest message
draws every path whole (coarse) until the chunks fill it in again.
``log_time``/``publish_time`` are simulation time in ns, like every channel of the log.

Cost: the per-agent fields (/tf, agents of /scene, path points) are written in protobuf's
wire format with the numbers of all agents packed at once (``swarmplan.io.wire``). A step
whose layout equals an earlier one (same agents, modes and movers, no pose component equal
to +-0.0, same timestamp length: nearly every step) only writes its timestamp and numbers
into that step's bytes (``wire.Patched``). Static and other entities are built through the
protobuf API (``swarmplan.io.foxglove_shapes``). See ``docs/performance.md`` for measured
per-step cost.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

from swarmplan.core import AgentStates, Mode, ObstacleStates
from swarmplan.io.foxglove_paths import PathTrails
from swarmplan.io.foxglove_shapes import (
    FRAME,
    MOVING_RGBA,
    ONE_PRIMITIVE,
    entity_record,
    mover_template,
    obstacle_entity,
    rest_orientation,
    world_entities,
)
from swarmplan.io.json_floats import record_kernels
from swarmplan.io.speeds import SPEED_SCHEMA, SPEED_TOPIC, SpeedText
from swarmplan.io.wire import (
    VECTOR_BYTES,
    Patched,
    file_descriptor_set,
    join_records,
    length_prefixes,
    pose_fields,
    record_starts,
    timestamp_bytes,
    varint,
    vector_fields,
)

SCENE_TOPIC = "/scene"
WORLD_TOPIC = "/scene/world"
PATHS_TOPIC = "/scene/paths"
LOG_TOPIC = "/events/log"
_EVENT_LEVELS = {
    "collision": Log.ERROR,
    "near_miss": Log.WARNING,
    "stuck": Log.WARNING,
    "timeout": Log.WARNING,
}
OVERVIEW_TOPIC = "/scene/paths/overview"
TF_TOPIC = "/tf"

MODE_COLORS = {
    Mode.APF: (0.12, 0.47, 0.71, 1.0),
    Mode.ESCAPE: (0.84, 0.15, 0.16, 1.0),
    Mode.SMOOTHING: (1.0, 0.75, 0.0, 1.0),
    Mode.ARRIVED: (0.17, 0.63, 0.17, 1.0),
    Mode.COLLIDED: (0.1, 0.1, 0.1, 1.0),
    Mode.FAILED: (0.5, 0.5, 0.5, 1.0),
}
_ENTITIES_TAG = b"\x12"  # SceneUpdate.entities: field 2, wire type 2
_DETAIL_JSON = json.JSONEncoder(separators=(",", ":"), default=str)  # json.dumps's, made once
_TRANSFORMS_TAG = b"\x0a"  # FrameTransforms.transforms: field 1, wire type 2


class FoxgloveScene:
    """Write Foxglove scene channels of a run into an open ``mcap.writer.Writer``.

    ``world`` is the resolved world dict (as written on ``/world``). Call
    :meth:`write_world` once, then :meth:`write_step` every simulation step with the same
    agent and obstacle entries as ``/agents/state`` and ``/obstacles/state``; call
    :meth:`finish` (or ``write_step(..., force=True)``) on the last step so the final
    state and full paths are written regardless of throttling.
    """

    def __init__(
        self,
        writer,
        world: dict[str, Any],
        scene_period: float = 0.2,
        path_period: float = 1.0,
        path_max_points: int = 400,
        tf_period: float = 0.2,
        overview_period: float = 5.0,
        overview_points: int = 32,
    ):
        self.writer = writer
        self.world = world
        self.scene_period = float(scene_period)
        self.path_period = float(path_period)
        self.tf_period = float(tf_period)
        self.overview_period = float(overview_period)
        self._channels: dict[str, int] = {}
        schema_ids: dict[str, int] = {}
        for topic, cls in (
            (WORLD_TOPIC, SceneUpdate),
            (SCENE_TOPIC, SceneUpdate),
            (PATHS_TOPIC, SceneUpdate),
            (OVERVIEW_TOPIC, SceneUpdate),
            # One message per step for all agents (one per agent made /tf ~95 % of the
            # messages of a 64-agent log and ~30 % of a pure-APF step's time).
            (TF_TOPIC, FrameTransforms),
            (LOG_TOPIC, Log),
        ):
            name = cls.DESCRIPTOR.full_name
            if name not in schema_ids:
                schema_ids[name] = writer.register_schema(
                    name=name, encoding="protobuf", data=file_descriptor_set(cls).SerializeToString()
                )
            self._channels[topic] = writer.register_channel(
                topic=topic, message_encoding="protobuf", schema_id=schema_ids[name]
            )
        speed_schema = writer.register_schema(
            name="swarmplan.AgentSpeeds", encoding="jsonschema", data=json.dumps(SPEED_SCHEMA).encode()
        )
        self._channels[SPEED_TOPIC] = writer.register_channel(
            topic=SPEED_TOPIC, message_encoding="json", schema_id=speed_schema
        )
        self._speeds = SpeedText()
        defaults = world.get("agent_defaults") or {}
        self._radius = {
            str(a["id"]): float(a.get("radius", defaults.get("radius", 0.5)) or 0.5)
            for a in world.get("agents") or []
        }
        self._obstacles = {str(o["id"]): o for o in world.get("obstacles") or [] if "id" in o}
        self._agent_heads: dict[str, tuple[bytes, bytes, bytes]] = {}
        self._colors: dict[tuple[float, float, float, float], bytes] = {}
        self._mover_ids: tuple[str, ...] | None = None
        self._mover_simple = True
        self._mover_known: list[dict | None] = []
        self._mover_rest: list[tuple[float, ...]] = []
        self._mover_templates: dict[tuple[int, bytes], Patched | bool] = {}
        self._mover_pairs: list[tuple[None, dict]] | None = None
        self._tf_prefix: dict[str, bytes] = {}  # per agent: parent and child frame fields
        # Per agent slot (_rows): last heading as a quaternion's z and w; its path (trails).
        self._slot: dict[str, int] = {}
        self._slot_ids: tuple[str, ...] | None = None
        self._slots = np.zeros(0, dtype=np.intp)
        self._qz = np.zeros(0)
        self._qw = np.zeros(0)
        self.trails = PathTrails(path_max_points, overview_points)
        self._sphere_cache: dict[tuple[str, Any, int], tuple[bytes, bytes, int]] = {}
        self._tf_ids: tuple[str, ...] | None = None
        self._tf_heads: list[bytes] = []
        self._tf_head_len: list[int] = []
        self._tf_stamp_len = 0
        self._tf_templates: dict[int, Patched] = {}  # per timestamp length (_write_tf)
        self._scene_ids: tuple[str, ...] | None = None
        self._scene_modes: list = []
        # per timestamp length (_write_scene): the agents' records, where each record's part
        # before its position starts, and each agent's parts (_sphere_parts)
        self._scene_templates: dict[int, tuple[Patched, list[int], list]] = {}
        self._next_scene = -math.inf
        self._next_path = -math.inf
        self._next_overview = -math.inf
        self._next_tf = -math.inf
        self._last: tuple[float, list, list] | None = None
        self._written_at: dict[str, float] = {}  # per throttled channel: the time of its last message
        self.messages_written = 0
        self.compiled = False  # headings by a compiled kernel (the same bits)

    def _kernels(self) -> ModuleType | None:
        """The compiled writers once ``compiled`` is set (None before)."""
        return record_kernels() if self.compiled else None

    # ------------------------------------------------------------------ low level
    def _write(self, topic: str, data: bytes, t: float):
        ns = int(round(t * 1e9))
        self.writer.add_message(self._channels[topic], log_time=ns, publish_time=ns, data=data)
        self.messages_written += 1

    # ------------------------------------------------------------------ steps
    def write_step(
        self, t: float, agents: Sequence[dict[str, Any]], obstacles: list[dict[str, Any]], force: bool = False
    ) -> None:
        """Record one simulation step (``agents``/``obstacles``: the JSON state entries; ``agents``
        may be a :class:`~swarmplan.core.AgentStates`, whose arrays are used directly).
        ``force``: write every throttled channel now, except one already written at ``t``."""
        t = float(t)
        eps = 1e-9
        self._last = (t, agents, obstacles)
        done = self._written_at

        def due(channel: str, next_t: float) -> bool:
            return t >= next_t - eps or (force and done.get(channel) != t)

        rows = None
        if due(TF_TOPIC, self._next_tf):
            rows = self._rows(agents)
            self._write_tf(t, rows)
            self._next_tf = t + self.tf_period if self.tf_period > 0 else -math.inf
            done[TF_TOPIC] = t
        scene_due = due(SCENE_TOPIC, self._next_scene)
        if scene_due:
            rows = rows or self._rows(agents)
            self.trails.sample(rows.ids, rows.pos, rows.slots, self._kernels())
            self._write_scene(t, rows, obstacles)
            self._next_scene = t + self.scene_period
            done[SCENE_TOPIC] = t
        if due(PATHS_TOPIC, self._next_path):
            if not scene_due:
                rows = rows or self._rows(agents)
                self.trails.sample(rows.ids, rows.pos, rows.slots, self._kernels())
            data = self.trails.chunks(timestamp_bytes(t), self._kernels())
            if data is not None:
                self._write(PATHS_TOPIC, data, t)
            self._next_path = t + self.path_period
            done[PATHS_TOPIC] = t
        if due(OVERVIEW_TOPIC, self._next_overview):
            data = self.trails.overview(timestamp_bytes(t), self._kernels())
            if data is not None:
                self._write(OVERVIEW_TOPIC, data, t)
            self._next_overview = t + self.overview_period
            done[OVERVIEW_TOPIC] = t

    def finish(self) -> None:
        """Write the last step seen so the scene ends in the final state: each throttled channel
        not already written at that step's time (never twice at one time)."""
        if self._last is not None:
            t, agents, obstacles = self._last
            self.write_step(t, agents, obstacles, force=True)
            self._last = None

    def _rows(self, agents: Sequence[dict[str, Any]]) -> _Rows:
        """The agents as arrays: ids, positions, velocities, modes and their per-agent slots
        (the index of the state kept between steps: last heading, last path point)."""
        if isinstance(agents, AgentStates):
            ids, pos, vel, modes = agents.ids, agents.position, agents.velocity, agents.mode.tolist()
        else:
            ids = tuple(str(a["id"]) for a in agents)
            pos = np.array([[float(c) for c in a["position"][:3]] for a in agents], dtype=float).reshape(
                -1, 3
            )
            vel = np.array(
                [[float(c) for c in (a.get("velocity") or (0.0, 0.0, 0.0))[:3]] for a in agents], dtype=float
            ).reshape(-1, 3)
            modes = [a.get("mode") for a in agents]
        if ids != self._slot_ids:
            for aid in ids:
                if aid not in self._slot:
                    self._slot[aid] = len(self._slot)
            grow = len(self._slot) - len(self._qz)
            if grow > 0:
                # No heading yet: the identity rotation (z = 0, w = 1); no path point yet.
                self._qz = np.concatenate([self._qz, np.zeros(grow)])
                self._qw = np.concatenate([self._qw, np.ones(grow)])
                self.trails.grow(grow)
            self._slot_ids = ids
            self._slots = np.array([self._slot[aid] for aid in ids], dtype=np.intp)
        return _Rows(ids, pos, vel, modes, self._slots)

    def _tf_head(self, aid: str) -> bytes:
        """A transform's parent and child frame fields."""
        head = self._tf_prefix.get(aid)
        if head is None:
            child = aid.encode()
            head = self._tf_prefix[aid] = (
                b"\x12"
                + varint(len(FRAME))
                + FRAME.encode()
                + (b"\x1a" + varint(len(child)) + child if child else b"")
            )
        return head

    def _write_tf(self, t: float, rows: _Rows) -> None:
        # Per agent: timestamp, frame ids, translation, rotation (a yaw along the horizontal
        # velocity; without horizontal motion the last heading, none yet: identity). The
        # numbers are packed for all agents at once (pose_fields) and the message is one join.
        stamp = timestamp_bytes(t)
        if rows.ids != self._tf_ids:
            self._tf_ids = rows.ids
            self._tf_heads = [self._tf_head(aid) for aid in rows.ids]
            self._tf_head_len = [len(h) + len(stamp) for h in self._tf_heads]
            self._tf_stamp_len = len(stamp)
            self._tf_templates = {}
        vel = np.ascontiguousarray(rows.vel, dtype=float)
        template = self._tf_templates.get(len(stamp)) if self.compiled else None
        if template is not None:
            # headings, the usual-step check and the numbers in one compiled call
            pos = np.ascontiguousarray(rows.pos, dtype=float)
            data = template.fill_poses(stamp, record_kernels(), vel, rows.slots, self._qz, self._qw, pos)
            if data is not None:
                self._write(TF_TOPIC, data, t)
                return
        vx, vy = rows.vel[:, 0], rows.vel[:, 1]
        turning = () if self.compiled else np.flatnonzero((vx != 0.0) | (vy != 0.0))
        if self.compiled:
            record_kernels().headings(vel, rows.slots, self._qz, self._qw)  # (again: the same)
        elif len(turning):
            # math's functions, as the per-agent encoder used them (numpy's may round otherwise).
            half = np.array(list(map(math.atan2, vy[turning].tolist(), vx[turning].tolist()))) / 2.0
            slots = rows.slots[turning]
            self._qz[slots] = list(map(math.sin, half.tolist()))
            self._qw[slots] = list(map(math.cos, half.tolist()))
        qz, qw = self._qz[rows.slots], self._qw[rows.slots]
        # The usual step (no coordinate or rotation component equal to +-0.0, which proto3
        # writes differently): every record has the same layout as the last such step with a
        # timestamp of this length, so only the numbers and the timestamp are written into it.
        usual = bool((rows.pos != 0.0).all() and (qz != 0.0).all() and (qw != 0.0).all())
        template = self._tf_templates.get(len(stamp)) if usual else None
        if template is not None:
            self._write(
                TF_TOPIC, template.fill(stamp, np.column_stack((rows.pos, qz, qw)), self._kernels()), t
            )
            return
        fields = pose_fields(rows.pos, qz, qw)
        shift = len(stamp) - self._tf_stamp_len
        lengths = [n + f + shift for n, f in zip(self._tf_head_len, map(len, fields), strict=True)]
        data = join_records(_TRANSFORMS_TAG, lengths, stamp, self._tf_heads, fields)
        if usual and len(lengths):
            # pose fields: translation x, y, z at 3, 12, 21; rotation z, w at 32, 41
            stamp_at = record_starts(lengths)
            body = stamp_at + np.asarray(self._tf_head_len) + shift  # after stamp and frame ids
            self._tf_templates[len(stamp)] = Patched(
                data, stamp_at, len(stamp), body[:, None] + np.array([3, 12, 21, 32, 41])
            )
        self._write(TF_TOPIC, data, t)

    def _agent_head(self, aid: str) -> tuple[bytes, bytes, bytes]:
        """An agent entity's fixed fields: frame and entity ids, and the sphere's orientation
        and size fields (the latter serialized by protobuf itself, once)."""
        head = self._agent_heads.get(aid)
        if head is None:
            eid = f"agent/{aid}".encode()
            d = 2.0 * self._radius.get(aid, 0.5)
            orientation = Quaternion(w=1.0).SerializeToString()
            size = Vector3(x=d, y=d, z=d).SerializeToString()
            head = self._agent_heads[aid] = (
                b"\x12" + varint(len(FRAME)) + FRAME.encode() + b"\x1a" + varint(len(eid)) + eid,
                b"\x12" + varint(len(orientation)) + orientation,
                b"\x12" + varint(len(size)) + size,
            )
        return head

    def _color_bytes(self, rgba: tuple[float, float, float, float]) -> bytes:
        b = self._colors.get(rgba)
        if b is None:
            c = Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]).SerializeToString()
            b = self._colors[rgba] = b"\x1a" + varint(len(c)) + c
        return b

    def _sphere_parts(self, key: tuple[str, Any, int]) -> tuple[bytes, bytes, int]:
        """An agent entity's bytes around its position field, for (agent id, mode, length of
        the position field): frame and entity ids with the sphere's and the pose's length
        fields before it; orientation, size and colour after it; and the fixed length."""
        aid, mode, position_len = key
        ids, orientation, size = self._agent_head(aid)
        color = self._color_bytes(MODE_COLORS.get(mode, (0.8, 0.2, 0.8, 1.0)))
        pose_len = position_len + len(orientation)
        sphere_len = 1 + len(varint(pose_len)) + pose_len + len(size) + len(color)
        before = ids + b"\x4a" + varint(sphere_len) + b"\x0a" + varint(pose_len)
        after = orientation + size + color
        parts = self._sphere_cache[key] = (before, after, len(before) + len(after))
        return parts

    def _write_scene(self, t: float, rows: _Rows, obstacles: list[dict[str, Any]]) -> None:
        # Agent entities are assembled in protobuf's wire format (a SceneEntity with one
        # sphere: timestamp, frame and entity ids, pose, size, colour), the bytes protobuf's
        # serializer gives (tests/test_foxglove_tf_bytes.py); obstacles go through the API.
        stamp = timestamp_bytes(t)
        if rows.ids != self._scene_ids:
            self._scene_ids, self._scene_modes = rows.ids, list(rows.modes)
            self._scene_templates = {}
        elif rows.modes != self._scene_modes:
            self._recolor(rows)
        # As in _write_tf: with no coordinate equal to +-0.0 the agents' records keep the
        # layout of the last such step (same ids, modes and timestamp length).
        template = self._scene_templates.get(len(stamp))
        agents = None
        if template is not None and self.compiled:  # the check and the numbers compiled
            agents = template[0].fill_nonzero(
                stamp, np.ascontiguousarray(rows.pos, dtype=float), record_kernels()
            )
        if agents is None:
            usual = bool((rows.pos != 0.0).all())
            if usual and template is not None:
                agents = template[0].fill(stamp, rows.pos, self._kernels())
            else:
                agents = self._scene_agents(stamp, rows, usual)
        self._write(SCENE_TOPIC, agents + self._movers_bytes(t, stamp, obstacles or []), t)
        self._write_speeds(t, rows)

    def write_event(self, event: dict[str, Any]) -> None:
        """The event as a ``foxglove.Log`` entry on ``/events/log`` (Foxglove's Log panel):
        name the agent (``run`` for the run's own), message its kind and detail."""
        t = float(event["t"])
        ns = int(round(t * 1e9))
        entry = Log(
            level=_EVENT_LEVELS.get(event["kind"], Log.INFO),
            message=f"{event['kind']} {_DETAIL_JSON.encode(event['detail'])}",
            name=event["agent"] or "run",
        )
        entry.timestamp.seconds, entry.timestamp.nanos = divmod(ns, 1_000_000_000)
        self._write(LOG_TOPIC, entry.SerializeToString(), t)

    def _write_speeds(self, t: float, rows: _Rows) -> None:
        """``/agents/speed`` (``swarmplan.io.speeds``)."""
        data = self._speeds.encode(t, rows.vel, self.compiled)
        if data is not None:
            self._write(SPEED_TOPIC, data, t)

    def _scene_agents(self, stamp: bytes, rows: _Rows, keep: bool) -> bytes:
        """The agents' entities of a /scene message (``keep``: store them as the template
        of this timestamp length)."""
        positions = vector_fields(0x0A, rows.pos)
        cache = self._sphere_cache
        parts = [
            cache.get(key) or self._sphere_parts(key)
            for key in zip(rows.ids, rows.modes, map(len, positions), strict=True)
        ]
        n = len(parts)
        lengths = [len(stamp) + len(p) + fixed for p, (_, _, fixed) in zip(positions, parts, strict=True)]
        flat: list[bytes] = [b""] * (5 * n)
        flat[0::5] = length_prefixes(_ENTITIES_TAG, lengths)
        flat[1::5] = [stamp] * n
        flat[2::5] = [p[0] for p in parts]
        flat[3::5] = positions
        flat[4::5] = [p[1] for p in parts]
        agents = b"".join(flat)
        if keep and n:
            stamp_at = record_starts(lengths)
            position_at = stamp_at + len(stamp) + np.array([len(p[0]) for p in parts])
            patched = Patched(agents, stamp_at, len(stamp), position_at[:, None] + np.array([3, 12, 21]))
            self._scene_templates[len(stamp)] = (patched, (stamp_at + len(stamp)).tolist(), parts)
        return agents

    def _recolor(self, rows: _Rows) -> None:
        """The agents' records of the kept templates in the modes of ``rows``: an agent whose mode
        changed gets its parts around the position written in place when they keep their
        lengths (the colours: four non-zero numbers each); otherwise the template is made again."""
        changed = [
            i for i, (m, was) in enumerate(zip(rows.modes, self._scene_modes, strict=True)) if m != was
        ]
        self._scene_modes = list(rows.modes)
        cache = self._sphere_cache
        for size, (patched, before_at, parts) in list(self._scene_templates.items()):
            for i in changed:
                key = (rows.ids[i], rows.modes[i], VECTOR_BYTES)
                new, old = cache.get(key) or self._sphere_parts(key), parts[i]
                if len(new[0]) != len(old[0]) or len(new[1]) != len(old[1]):
                    del self._scene_templates[size]
                    break
                patched.write(before_at[i], new[0])
                patched.write(before_at[i] + len(new[0]) + VECTOR_BYTES, new[1])
                parts[i] = new

    def _movers_bytes(
        self, t: float, stamp: bytes, obstacles: list[dict[str, Any]] | ObstacleStates
    ) -> bytes:
        """The moving obstacles' entities of a /scene message. With one-primitive shapes only,
        an entity changes between steps in its timestamp and pose alone: the numbers go into
        a template per layout (Patched; which pose components are left out as +0.0 and the
        timestamp's length); other shapes are built through the protobuf API."""
        arrays = isinstance(obstacles, ObstacleStates)
        ids = obstacles.ids if arrays else tuple(str(o["id"]) for o in obstacles)
        if ids != self._mover_ids:
            self._mover_ids = ids
            self._mover_known = [self._obstacles.get(oid) for oid in ids]
            known = [obst for obst in self._mover_known if obst is not None]
            self._mover_simple = all(obst.get("shape") in ONE_PRIMITIVE for obst in known)
            self._mover_rest = [rest_orientation(obst) for obst in known]
            self._mover_templates = {}
            every = len(known) == len(ids)  # every mover is one of the world's (the usual case)
            self._mover_pairs = [(None, obst) for obst in known] if every else None
        if arrays and self._mover_simple and self._mover_pairs is not None:
            known = self._mover_pairs
            values = np.empty((len(ids), 7))
            values[:, :3] = obstacles.position
            values[:, 3:] = obstacles.orientation
        else:
            entries = obstacles.dicts() if arrays else obstacles
            known = [
                (o, obst) for o, obst in zip(entries, self._mover_known, strict=True) if obst is not None
            ]
            values = None
            if self._mover_simple:
                rows = [
                    [*o["position"][:3], *(q if (q := o.get("orientation")) is not None else rest)]
                    for (o, _), rest in zip(known, self._mover_rest, strict=True)
                ]
                values = np.array(rows, dtype=float) if all(len(r) == 7 for r in rows) else None
            if values is None:
                return b"".join(
                    entity_record(obstacle_entity(obst, t, o["position"], o.get("orientation"), MOVING_RGBA))
                    for o, obst in known
                )
        if not known:
            return b""
        present = (values != 0.0) | np.signbit(values)  # proto3 leaves out +0.0 only
        key = (len(stamp), present.tobytes())
        template = self._mover_templates.get(key)
        if template is None:
            template = self._mover_templates[key] = mover_template(known, stamp, present)
        if template is False:  # a marker value was not unique: the protobuf API
            return b"".join(
                entity_record(obstacle_entity(obst, t, list(v[:3]), list(v[3:]), MOVING_RGBA))
                for (_, obst), v in zip(known, values.tolist(), strict=True)
            )
        return template.fill(stamp, values[present], self._kernels())

    def write_world(self, t: float = 0.0) -> None:
        """Static obstacles, bounds, terrain and goals on ``/scene/world`` at time ``t``."""
        entities = world_entities(self.world, list(self._obstacles.values()), t)
        self._write(WORLD_TOPIC, b"".join(map(entity_record, entities)), t)


class _Rows(NamedTuple):
    """One step's agents as arrays (FoxgloveScene._rows)."""

    ids: tuple[str, ...]
    pos: np.ndarray  # (n, 3)
    vel: np.ndarray  # (n, 3)
    modes: list  # per agent: its mode (a Mode, a string or None)
    slots: np.ndarray  # (n,) per-agent state index


__all__ = [
    "FoxgloveScene",
    "file_descriptor_set",
    "FRAME",
    "SCENE_TOPIC",
    "WORLD_TOPIC",
    "PATHS_TOPIC",
    "OVERVIEW_TOPIC",
    "TF_TOPIC",
]
