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
``/scene/paths``   ``foxglove.SceneUpdate``  flown path of each agent (line strip, decimated
                                           to ``path_max_points``); every ``path_period`` s
``/tf``            ``foxglove.FrameTransforms`` one message per step holding a
                                           ``FrameTransform`` per agent: parent ``world``,
                                           child = agent id
=================  ======================  ==============================================

Static, dynamic and path entities are on separate topics because Foxglove, after a seek,
restores each topic from its latest message only: every topic is self-contained.
``log_time``/``publish_time`` are simulation time in ns, like every channel of the log.

Cost: the per-agent fields (/tf, agents of /scene, path points) are written in protobuf's
wire format with the numbers of all agents packed at once (``swarmplan.io.wire``); other
entities are built through the protobuf API (movers' kept and updated in place). See
``docs/performance.md`` for measured per-step cost.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

from swarmplan.core import AgentStates, Mode
from swarmplan.geometry.rotation import euler_to_quaternion, rotate
from swarmplan.io.wire import (
    file_descriptor_set,
    join_records,
    length_prefixes,
    point_bytes,
    pose_fields,
    timestamp_bytes,
    varint,
    vector_fields,
)

FRAME = "world"
SCENE_TOPIC = "/scene"
WORLD_TOPIC = "/scene/world"
PATHS_TOPIC = "/scene/paths"
TF_TOPIC = "/tf"

MODE_COLORS = {
    Mode.APF: (0.12, 0.47, 0.71, 1.0),
    Mode.ESCAPE: (0.84, 0.15, 0.16, 1.0),
    Mode.SMOOTHING: (1.0, 0.75, 0.0, 1.0),
    Mode.ARRIVED: (0.17, 0.63, 0.17, 1.0),
    Mode.COLLIDED: (0.1, 0.1, 0.1, 1.0),
    Mode.FAILED: (0.5, 0.5, 0.5, 1.0),
}
OBSTACLE_RGBA = (0.55, 0.58, 0.65, 0.8)
MOVING_RGBA = (0.9, 0.45, 0.1, 0.85)
_ENTITIES_TAG = b"\x12"  # SceneUpdate.entities: field 2, wire type 2
_TRANSFORMS_TAG = b"\x0a"  # FrameTransforms.transforms: field 1, wire type 2


def _set_pose(pose, position, quat=(0.0, 0.0, 0.0, 1.0)):
    pose.position.x, pose.position.y, pose.position.z = (float(c) for c in position[:3])
    o = pose.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in quat)


def _set_color(color, rgba):
    color.r, color.g, color.b, color.a = rgba


def _set_time(ts, t: float):
    ns = int(round(t * 1e9))
    ts.seconds, ts.nanos = divmod(ns, 1_000_000_000)


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
        tf_period: float = 0.0,
    ):
        self.writer = writer
        self.world = world
        self.scene_period = float(scene_period)
        self.path_period = float(path_period)
        self.path_max_points = max(4, int(path_max_points))
        self.tf_period = float(tf_period)
        self._channels: dict[str, int] = {}
        schema_ids: dict[str, int] = {}
        for topic, cls in (
            (WORLD_TOPIC, SceneUpdate),
            (SCENE_TOPIC, SceneUpdate),
            (PATHS_TOPIC, SceneUpdate),
            # One message per step for all agents (one per agent made /tf ~95 % of the
            # messages of a 64-agent log and ~30 % of a pure-APF step's time).
            (TF_TOPIC, FrameTransforms),
        ):
            name = cls.DESCRIPTOR.full_name
            if name not in schema_ids:
                schema_ids[name] = writer.register_schema(
                    name=name, encoding="protobuf", data=file_descriptor_set(cls).SerializeToString()
                )
            self._channels[topic] = writer.register_channel(
                topic=topic, message_encoding="protobuf", schema_id=schema_ids[name]
            )
        defaults = world.get("agent_defaults") or {}
        self._radius = {
            str(a["id"]): float(a.get("radius", defaults.get("radius", 0.5)) or 0.5)
            for a in world.get("agents") or []
        }
        self._obstacles = {str(o["id"]): o for o in world.get("obstacles") or [] if "id" in o}
        self._agent_heads: dict[str, tuple[bytes, bytes, bytes]] = {}
        self._colors: dict[tuple[float, float, float, float], bytes] = {}
        self._obstacle_entities: dict[str, SceneEntity] = {}
        self._path_heads: dict[str, bytes] = {}
        self._path_bytes: dict[str, bytearray] = {}  # per agent: its path's encoded points
        self._paths: dict[str, int] = {}  # agents with a path (message order) -> slot
        self._tf_prefix: dict[str, bytes] = {}  # per agent: parent and child frame fields
        # Per agent slot (_rows): last heading as a quaternion's z and w, last path point.
        self._slot: dict[str, int] = {}
        self._slot_ids: tuple[str, ...] | None = None
        self._slots = np.zeros(0, dtype=np.intp)
        self._qz = np.zeros(0)
        self._qw = np.zeros(0)
        self._path_last = np.zeros((0, 3))
        self._path_has = np.zeros(0, dtype=bool)
        # Per slot: the path's points (a row each, path_max_points + 1 rows), their count,
        # and the same encoded points as _path_bytes.
        self._path_points = np.zeros((0, self.path_max_points + 1, 3))
        self._path_count = np.zeros(0, dtype=np.intp)
        self._path_slot_bytes: list[bytearray | None] = []
        self._sphere_cache: dict[tuple[str, Any, int], tuple[bytes, bytes, int]] = {}
        self._tf_ids: tuple[str, ...] | None = None
        self._tf_heads: list[bytes] = []
        self._tf_head_len: list[int] = []
        self._tf_stamp_len = 0
        self._next_scene = -math.inf
        self._next_path = -math.inf
        self._next_tf = -math.inf
        self._last: tuple[float, list, list] | None = None
        self.messages_written = 0

    # ------------------------------------------------------------------ low level
    def _write(self, topic: str, data: bytes, t: float):
        ns = int(round(t * 1e9))
        self.writer.add_message(self._channels[topic], log_time=ns, publish_time=ns, data=data)
        self.messages_written += 1

    @staticmethod
    def _scene_bytes(entities) -> bytes:
        parts = []
        for e in entities:
            b = e.SerializeToString()
            parts.append(_ENTITIES_TAG + varint(len(b)) + b)
        return b"".join(parts)

    @staticmethod
    def _entity(eid: str, t: float) -> SceneEntity:
        e = SceneEntity(frame_id=FRAME, id=eid)
        _set_time(e.timestamp, t)
        return e

    # ------------------------------------------------------------------ shapes
    def _obstacle_entity(self, obst: dict[str, Any], t: float, position=None, quat=None, rgba=OBSTACLE_RGBA):
        e = self._entity(f"obstacle/{obst['id']}", t)
        self._fill_obstacle(e, obst, position, quat, rgba)
        return e

    def _fill_obstacle(self, e, obst, position=None, quat=None, rgba=OBSTACLE_RGBA):
        shape = obst.get("shape")
        pos = np.asarray(obst.get("position", [0, 0, 0]) if position is None else position, float)
        q = (
            tuple(quat)
            if quat is not None
            else tuple(euler_to_quaternion((list(obst.get("rotation") or []) + [0, 0, 0])[:3]))
        )
        if shape == "sphere":
            s = e.spheres.add()
            _set_pose(s.pose, pos, q)
            d = 2.0 * float(obst["radius"])
            s.size.x = s.size.y = s.size.z = d
            _set_color(s.color, rgba)
        elif shape == "box":
            c = e.cubes.add()
            _set_pose(c.pose, pos, q)
            c.size.x, c.size.y, c.size.z = (float(v) for v in obst["size"])
            _set_color(c.color, rgba)
        elif shape in ("cylinder", "capsule"):
            r = float(obst["radius"])
            h = float(obst.get("height", obst.get("length", 0.0)))
            c = e.cylinders.add()
            _set_pose(c.pose, pos, q)
            c.size.x = c.size.y = 2.0 * r
            c.size.z = h
            c.bottom_scale = c.top_scale = 1.0
            _set_color(c.color, rgba)
            if shape == "capsule":
                for sign in (-1.0, 1.0):
                    s = e.spheres.add()
                    _set_pose(s.pose, pos + rotate(q, [0.0, 0.0, sign * h / 2.0]), q)
                    s.size.x = s.size.y = s.size.z = 2.0 * r
                    _set_color(s.color, rgba)
        elif shape == "mesh" and "vertices" in obst:
            tri = e.triangles.add()
            v = np.asarray(obst["vertices"], float)
            if position is not None:  # moving mesh: vertices are its pose at t = 0
                v = v - np.asarray(obst.get("position", [0, 0, 0]), float)
                _set_pose(tri.pose, pos, q if quat is not None else (0.0, 0.0, 0.0, 1.0))
            else:
                _set_pose(tri.pose, (0.0, 0.0, 0.0))
            for x, y, z in v:
                tri.points.add(x=float(x), y=float(y), z=float(z))
            tri.indices.extend(int(i) for i in np.asarray(obst["faces"], int).ravel())
            _set_color(tri.color, rgba)

    # ------------------------------------------------------------------ world
    def write_world(self, t: float = 0.0) -> None:
        """Static obstacles, bounds, terrain and goals on ``/scene/world`` at time ``t``."""
        entities = []
        for obst in self._obstacles.values():
            if not obst.get("motion"):
                entities.append(self._obstacle_entity(obst, t))
        b = self.world.get("bounds") or {}
        if b.get("min") is not None and b.get("max") is not None:
            lo, hi = np.asarray(b["min"], float), np.asarray(b["max"], float)
            e = self._entity("bounds", t)
            line = e.lines.add(type=LinePrimitive.LINE_LIST, thickness=2.0, scale_invariant=True)
            _set_pose(line.pose, (0.0, 0.0, 0.0))
            corners = [
                np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])
            ]
            for i in range(8):
                for j in range(i + 1, 8):
                    if np.count_nonzero(corners[i] != corners[j]) == 1:
                        for p in (corners[i], corners[j]):
                            line.points.add(x=float(p[0]), y=float(p[1]), z=float(p[2]))
            _set_color(line.color, (0.6, 0.6, 0.6, 1.0))
            entities.append(e)
            terrain = self._terrain_entity(lo, hi, t)
            if terrain is not None:
                entities.append(terrain)
        for a in self.world.get("agents") or []:
            if a.get("goal") is None:
                continue
            e = self._entity(f"goal/{a['id']}", t)
            s = e.spheres.add()
            _set_pose(s.pose, a["goal"])
            tol = float((self.world.get("sim") or {}).get("goal_tolerance", 1.0) or 1.0)
            s.size.x = s.size.y = s.size.z = 2.0 * tol
            _set_color(s.color, (0.17, 0.63, 0.17, 0.35))
            entities.append(e)
        self._write(WORLD_TOPIC, self._scene_bytes(entities), t)

    def _terrain_entity(self, lo, hi, t, n=32):
        peaks = (self.world.get("terrain") or {}).get("peaks") or []
        if not peaks:
            return None
        xs, ys = np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)
        X, Y = np.meshgrid(xs, ys)
        Z = np.zeros_like(X)
        for pk in peaks:
            cx, cy = pk["center"][:2]
            sx, sy = (pk.get("spread") or [1, 1])[:2]
            Z += float(pk["height"]) * np.exp(-(((X - cx) / sx) ** 2) - ((Y - cy) / sy) ** 2)
        e = self._entity("terrain", t)
        tri = e.triangles.add()
        _set_pose(tri.pose, (0.0, 0.0, 0.0))
        for x, y, z in zip(X.ravel(), Y.ravel(), Z.ravel(), strict=True):
            tri.points.add(x=float(x), y=float(y), z=float(z))
        idx = []
        for r in range(n - 1):
            for c in range(n - 1):
                a, b2, c2, d = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
                idx += [a, b2, d, a, d, c2]
        tri.indices.extend(idx)
        _set_color(tri.color, (0.45, 0.6, 0.35, 0.5))
        return e

    # ------------------------------------------------------------------ steps
    def write_step(
        self, t: float, agents: Sequence[dict[str, Any]], obstacles: list[dict[str, Any]], force: bool = False
    ) -> None:
        """Record one simulation step (``agents``/``obstacles``: the JSON state entries; ``agents``
        may be a :class:`~swarmplan.core.AgentStates`, whose arrays are used directly)."""
        t = float(t)
        eps = 1e-9
        self._last = (t, agents, obstacles)
        rows = None
        if force or t >= self._next_tf - eps:
            rows = self._rows(agents)
            self._write_tf(t, rows)
            self._next_tf = t + self.tf_period if self.tf_period > 0 else -math.inf
        scene_due = force or t >= self._next_scene - eps
        if scene_due:
            rows = rows or self._rows(agents)
            self._sample_paths(t, rows)
            self._write_scene(t, rows, obstacles)
            self._next_scene = t + self.scene_period
        if force or t >= self._next_path - eps:
            if not scene_due:
                self._sample_paths(t, rows or self._rows(agents))
            self._write_paths(t)
            self._next_path = t + self.path_period

    def finish(self) -> None:
        """Write the last step seen (unthrottled) so the scene ends in the final state."""
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
                self._path_last = np.concatenate([self._path_last, np.full((grow, 3), np.nan)])
                self._path_has = np.concatenate([self._path_has, np.zeros(grow, dtype=bool)])
                self._path_points = np.concatenate(
                    [self._path_points, np.zeros((grow,) + self._path_points.shape[1:])]
                )
                self._path_count = np.concatenate([self._path_count, np.zeros(grow, dtype=np.intp)])
                self._path_slot_bytes += [None] * grow
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
        vx, vy = rows.vel[:, 0], rows.vel[:, 1]
        turning = np.flatnonzero((vx != 0.0) | (vy != 0.0))
        if len(turning):
            # math's functions, as the per-agent encoder used them (numpy's may round otherwise).
            half = np.array(list(map(math.atan2, vy[turning].tolist(), vx[turning].tolist()))) / 2.0
            slots = rows.slots[turning]
            self._qz[slots] = list(map(math.sin, half.tolist()))
            self._qw[slots] = list(map(math.cos, half.tolist()))
        fields = pose_fields(rows.pos, self._qz[rows.slots], self._qw[rows.slots])
        if rows.ids != self._tf_ids:
            self._tf_ids = rows.ids
            self._tf_heads = [self._tf_head(aid) for aid in rows.ids]
            self._tf_head_len = [len(h) + len(stamp) for h in self._tf_heads]
            self._tf_stamp_len = len(stamp)
        shift = len(stamp) - self._tf_stamp_len
        lengths = [n + f + shift for n, f in zip(self._tf_head_len, map(len, fields), strict=True)]
        self._write(TF_TOPIC, join_records(_TRANSFORMS_TAG, lengths, stamp, self._tf_heads, fields), t)

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
        entities = []
        for o in obstacles or []:
            oid = str(o["id"])
            obst = self._obstacles.get(oid)
            if obst is None:
                continue
            entities.append(self._mover_entity(oid, obst, t, o["position"], o.get("orientation")))
        self._write(SCENE_TOPIC, agents + self._scene_bytes(entities), t)

    def _mover_entity(self, oid: str, obst: dict[str, Any], t: float, position, quat) -> SceneEntity:
        """A moving obstacle's entity at ``t``. One-primitive shapes keep their entity and only
        get a new time and pose (every other field is the same each time); others are rebuilt."""
        e = self._obstacle_entities.get(oid)
        if e is None:
            e = self._entity(f"obstacle/{oid}", t)
            self._fill_obstacle(e, obst, position, quat, MOVING_RGBA)
            if obst.get("shape") in ("sphere", "box", "cylinder"):
                self._obstacle_entities[oid] = e
            return e
        _set_time(e.timestamp, t)
        q = (
            tuple(quat)
            if quat is not None
            else tuple(euler_to_quaternion((list(obst.get("rotation") or []) + [0, 0, 0])[:3]))
        )
        _set_pose((e.spheres or e.cubes or e.cylinders)[0].pose, np.asarray(position, float), q)
        return e

    def _path_head(self, aid: str) -> bytes:
        """A path entity's fixed fields (frame and entity ids)."""
        head = self._path_heads.get(aid)
        if head is None:
            eid = f"path/{aid}".encode()
            head = self._path_heads[aid] = (
                b"\x12" + varint(len(FRAME)) + FRAME.encode() + b"\x1a" + varint(len(eid)) + eid
            )
        return head

    def _sample_paths(self, t: float, rows: _Rows) -> None:
        """Append the agents' current positions to their path lines, kept encoded (the
        ``points`` fields of a LinePrimitive): only new points are converted. An agent whose
        position equals its last point (standing) adds none."""
        last = self._path_last[rows.slots]
        same = self._path_has[rows.slots] & (last == rows.pos).all(axis=1)
        new = np.flatnonzero(~same)
        if not len(new):
            return
        slots = rows.slots[new]
        self._path_last[slots] = rows.pos[new]
        self._path_has[slots] = True
        encoded = self._path_slot_bytes
        room = self.path_max_points + 1 - self._path_points.shape[1]
        if room > 0:  # path_max_points was raised after construction
            self._path_points = np.pad(self._path_points, ((0, 0), (0, room), (0, 0)))
        counts = self._path_count[slots]
        for i in np.flatnonzero(counts == 0).tolist():  # first points: paths start (message order)
            aid = rows.ids[new[i]]
            self._paths[aid] = int(slots[i])
            encoded[slots[i]] = self._path_bytes[aid] = bytearray()
        self._path_points[slots, counts] = rows.pos[new]
        counts += 1
        self._path_count[slots] = counts
        fields = vector_fields(0x2A, rows.pos[new])
        full = counts > self.path_max_points
        if not full.any():
            list(map(bytearray.extend, [encoded[k] for k in slots.tolist()], fields))
            return
        for k, b, decimate in zip(slots.tolist(), fields, full.tolist(), strict=True):
            if not decimate:
                encoded[k].extend(b)
                continue
            # halve the resolution of the older part, keep the newest point; rebuild
            pts = self._path_points[k, : self.path_max_points + 1]
            kept = np.concatenate([pts[:-1:2], pts[-1:]])
            self._path_points[k, : len(kept)] = kept
            self._path_count[k] = len(kept)
            encoded[k][:] = b"".join(point_bytes(tuple(q)) for q in kept.tolist())

    def _write_paths(self, t):
        # Each path is a SceneEntity with one LINE_STRIP, assembled from its encoded points
        # between the line's fixed fields (1-4: type, pose, thickness, scale_invariant) and its
        # colour (6), in field order as protobuf writes them (tests/test_foxglove_tf_bytes.py).
        stamp = timestamp_bytes(t)
        parts = []
        for aid in self._paths:
            pts = self._path_bytes[aid]
            line_len = len(_LINE_HEAD) + len(pts) + len(_LINE_COLOR)
            b = b"".join(
                (stamp, self._path_head(aid), b"\x5a", varint(line_len), _LINE_HEAD, pts, _LINE_COLOR)
            )
            parts.append(_ENTITIES_TAG + varint(len(b)) + b)
        self._write(PATHS_TOPIC, b"".join(parts), t)


class _Rows(NamedTuple):
    """One step's agents as arrays (FoxgloveScene._rows)."""

    ids: tuple[str, ...]
    pos: np.ndarray  # (n, 3)
    vel: np.ndarray  # (n, 3)
    modes: list  # per agent: its mode (a Mode, a string or None)
    slots: np.ndarray  # (n,) per-agent state index


def _line_fixed_fields() -> tuple[bytes, bytes]:
    """The path line's fields before and after its points, serialized by protobuf itself."""
    line = LinePrimitive(type=LinePrimitive.LINE_STRIP, thickness=2.0, scale_invariant=True)
    _set_pose(line.pose, (0.0, 0.0, 0.0))
    color = Color()
    _set_color(color, PATH_RGBA)
    c = color.SerializeToString()
    return line.SerializeToString(), b"\x32" + varint(len(c)) + c


PATH_RGBA = (0.12, 0.47, 0.71, 0.9)
_LINE_HEAD, _LINE_COLOR = _line_fixed_fields()


__all__ = [
    "FoxgloveScene",
    "file_descriptor_set",
    "FRAME",
    "SCENE_TOPIC",
    "WORLD_TOPIC",
    "PATHS_TOPIC",
    "TF_TOPIC",
]
