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

Cost: entity messages are built once and mutated in place; scene messages are assembled
from serialized entities. See ``docs/replay.md`` for measured per-step cost.
"""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.descriptor_pb2 import FileDescriptorSet

from swarmplan.core import Mode
from swarmplan.geometry.rotation import euler_to_quaternion, rotate

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

# FrameTransform written directly in protobuf's wire format (the bytes protobuf's own
# serializer gives, tests/test_foxglove_tf_bytes.py): building and serializing 256 messages
# per step through the protobuf API was the largest recording cost of a 256-agent step.
# Fields: 1 timestamp, 2 parent_frame_id, 3 child_frame_id, 4 translation, 5 rotation;
# proto3 leaves out a double equal to +0.0 (not -0.0); doubles are tags 0x09/0x11/0x19/0x21.
_DOUBLE = struct.Struct("<d").pack
_XYZ = struct.Struct("<BBBdBdBd").pack  # translation with x, y, z all non-zero: the usual case
_ZW = struct.Struct("<BBBdBd").pack  # rotation with only z and w set (a yaw), both non-zero
_DOUBLE_TAGS = (b"\x09", b"\x11", b"\x19", b"\x21")


def _present(v: float) -> bool:
    return v != 0.0 or math.copysign(1.0, v) < 0.0  # -0.0 and NaN are written


def _vector_bytes(field_tag: bytes, values: tuple[float, ...], tags: tuple[bytes, ...]) -> bytes:
    inner = b"".join(tag + _DOUBLE(v) for tag, v in zip(tags, values, strict=True) if _present(v))
    return field_tag + _varint(len(inner)) + inner


_IDENTITY_ROTATION = b"\x2a\x09\x21" + _DOUBLE(1.0)


def _timestamp_bytes(t: float) -> bytes:
    ns = int(round(t * 1e9))
    sec, nanos = divmod(ns, 1_000_000_000)
    inner = (b"\x08" + _varint(sec) if sec else b"") + (b"\x10" + _varint(nanos) if nanos else b"")
    return b"\x0a" + _varint(len(inner)) + inner


def file_descriptor_set(message_class) -> FileDescriptorSet:
    """FileDescriptorSet of a message's .proto file and all its dependencies (deps first)."""
    fds = FileDescriptorSet()
    seen: set[str] = set()

    def add(fd):
        if fd.name in seen:
            return
        seen.add(fd.name)
        for dep in fd.dependencies:
            add(dep)
        fd.CopyToProto(fds.file.add())

    add(message_class.DESCRIPTOR.file)
    return fds


def _varint_slow(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


# Lengths of entities and transforms are almost always below 2**14 (one or two bytes): no
# loop for those (tens of thousands of calls per second of a 256-agent log).
_ONE_BYTE = [bytes((n,)) for n in range(128)]


def _varint(n: int) -> bytes:
    if n < 128:
        return _ONE_BYTE[n]
    if n < 16384:
        return bytes((n & 0x7F | 0x80, n >> 7))
    return _varint_slow(n)


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
        self._paths: dict[str, list[tuple[float, float, float]]] = {}
        self._tf_prefix: dict[str, bytes] = {}  # per agent: parent and child frame fields
        self._tf_yaw: dict[str, bytes] = {}  # per agent: its last rotation field
        self._next_scene = -math.inf
        self._next_path = -math.inf
        self._next_tf = -math.inf
        self._last_path_sample = -math.inf
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
            parts.append(_ENTITIES_TAG + _varint(len(b)) + b)
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
        self, t: float, agents: list[dict[str, Any]], obstacles: list[dict[str, Any]], force: bool = False
    ) -> None:
        """Record one simulation step (``agents``/``obstacles``: the JSON state entries)."""
        t = float(t)
        eps = 1e-9
        self._last = (t, agents, obstacles)
        if force or t >= self._next_tf - eps:
            self._write_tf(t, agents)
            self._next_tf = t + self.tf_period if self.tf_period > 0 else -math.inf
        scene_due = force or t >= self._next_scene - eps
        if scene_due:
            self._sample_paths(t, agents)
            self._write_scene(t, agents, obstacles)
            self._next_scene = t + self.scene_period
        if force or t >= self._next_path - eps:
            if not scene_due:
                self._sample_paths(t, agents)
            self._write_paths(t)
            self._next_path = t + self.path_period

    def finish(self) -> None:
        """Write the last step seen (unthrottled) so the scene ends in the final state."""
        if self._last is not None:
            t, agents, obstacles = self._last
            self.write_step(t, agents, obstacles, force=True)
            self._last = None

    def _write_tf(self, t, agents):
        stamp = _timestamp_bytes(t)
        prefix, yaw = self._tf_prefix, self._tf_yaw
        parts = []
        for a in agents:
            aid = str(a["id"])
            head = prefix.get(aid)
            if head is None:
                child = aid.encode()
                head = prefix[aid] = (
                    b"\x12"
                    + _varint(len(FRAME))
                    + FRAME.encode()
                    + (b"\x1a" + _varint(len(child)) + child if child else b"")
                )
            p = a["position"]
            x, y, z = float(p[0]), float(p[1]), float(p[2])
            if x and y and z:
                trans = _XYZ(0x22, 27, 0x09, x, 0x11, y, 0x19, z)
            else:
                trans = _vector_bytes(b"\x22", (x, y, z), _DOUBLE_TAGS[:3])
            v = a.get("velocity")
            if v is not None and (v[0] or v[1]):  # yaw along the horizontal velocity
                half = math.atan2(v[1], v[0]) / 2.0
                qz, qw = math.sin(half), math.cos(half)
                rot = yaw[aid] = (
                    _ZW(0x2A, 18, 0x19, qz, 0x21, qw)
                    if qz and qw
                    else _vector_bytes(b"\x2a", (0.0, 0.0, qz, qw), _DOUBLE_TAGS)
                )
            else:  # no horizontal motion: the last heading (none yet: identity)
                rot = yaw.get(aid, _IDENTITY_ROTATION)
            b = stamp + head + trans + rot
            parts.append(_TRANSFORMS_TAG + _varint(len(b)) + b)
        self._write(TF_TOPIC, b"".join(parts), t)

    def _agent_head(self, aid: str) -> tuple[bytes, bytes]:
        """An agent entity's fixed fields: frame and entity ids, and the sphere's orientation
        and size fields (the latter serialized by protobuf itself, once)."""
        head = self._agent_heads.get(aid)
        if head is None:
            eid = f"agent/{aid}".encode()
            d = 2.0 * self._radius.get(aid, 0.5)
            orientation = Quaternion(w=1.0).SerializeToString()
            size = Vector3(x=d, y=d, z=d).SerializeToString()
            head = self._agent_heads[aid] = (
                b"\x12" + _varint(len(FRAME)) + FRAME.encode() + b"\x1a" + _varint(len(eid)) + eid,
                b"\x12" + _varint(len(orientation)) + orientation,
                b"\x12" + _varint(len(size)) + size,
            )
        return head

    def _color_bytes(self, rgba: tuple[float, float, float, float]) -> bytes:
        b = self._colors.get(rgba)
        if b is None:
            c = Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]).SerializeToString()
            b = self._colors[rgba] = b"\x1a" + _varint(len(c)) + c
        return b

    def _write_scene(self, t, agents, obstacles):
        # Agent entities are assembled in protobuf's wire format (a SceneEntity with one
        # sphere: timestamp, frame and entity ids, pose, size, colour), the bytes protobuf's
        # serializer gives (tests/test_foxglove_tf_bytes.py); obstacles go through the API.
        stamp = _timestamp_bytes(t)
        parts = []
        for a in agents:
            aid = str(a["id"])
            ids, orientation, size = self._agent_head(aid)
            p = a["position"]
            x, y, z = float(p[0]), float(p[1]), float(p[2])
            if x and y and z:
                position = _XYZ(0x0A, 27, 0x09, x, 0x11, y, 0x19, z)
            else:
                position = _vector_bytes(b"\x0a", (x, y, z), _DOUBLE_TAGS[:3])
            pose = position + orientation
            sphere = (
                b"\x0a"
                + _varint(len(pose))
                + pose
                + size
                + self._color_bytes(MODE_COLORS.get(a.get("mode"), (0.8, 0.2, 0.8, 1.0)))
            )
            b = stamp + ids + b"\x4a" + _varint(len(sphere)) + sphere
            parts.append(_ENTITIES_TAG + _varint(len(b)) + b)
        entities = []
        for o in obstacles or []:
            oid = str(o["id"])
            obst = self._obstacles.get(oid)
            if obst is None:
                continue
            e = self._entity(f"obstacle/{oid}", t)
            self._fill_obstacle(e, obst, o["position"], o.get("orientation"), MOVING_RGBA)
            entities.append(e)
        self._write(SCENE_TOPIC, b"".join(parts) + self._scene_bytes(entities), t)

    def _path_head(self, aid: str) -> bytes:
        """A path entity's fixed fields (frame and entity ids)."""
        head = self._path_heads.get(aid)
        if head is None:
            eid = f"path/{aid}".encode()
            head = self._path_heads[aid] = (
                b"\x12" + _varint(len(FRAME)) + FRAME.encode() + b"\x1a" + _varint(len(eid)) + eid
            )
        return head

    def _sample_paths(self, t, agents):
        """Append the agents' current positions to their path lines, kept encoded (the
        ``points`` fields of a LinePrimitive): only new points are converted."""
        for a in agents:
            aid = str(a["id"])
            pts = self._paths.setdefault(aid, [])
            p = a["position"]
            pt = (float(p[0]), float(p[1]), float(p[2]))
            if pts and pts[-1] == pt:
                continue
            pts.append(pt)
            if len(pts) > self.path_max_points:
                # halve the resolution of the older part, keep the newest point; rebuild
                pts = self._paths[aid] = pts[:-1:2] + [pts[-1]]
                self._path_bytes[aid] = bytearray(b"".join(_point_bytes(q) for q in pts))
            else:
                self._path_bytes.setdefault(aid, bytearray()).extend(_point_bytes(pt))

    def _write_paths(self, t):
        # Each path is a SceneEntity with one LINE_STRIP, assembled from its encoded points
        # between the line's fixed fields (1-4: type, pose, thickness, scale_invariant) and its
        # colour (6), in field order as protobuf writes them (tests/test_foxglove_tf_bytes.py).
        stamp = _timestamp_bytes(t)
        parts = []
        for aid in self._paths:
            pts = self._path_bytes[aid]
            line_len = len(_LINE_HEAD) + len(pts) + len(_LINE_COLOR)
            b = b"".join(
                (stamp, self._path_head(aid), b"\x5a", _varint(line_len), _LINE_HEAD, pts, _LINE_COLOR)
            )
            parts.append(_ENTITIES_TAG + _varint(len(b)) + b)
        self._write(PATHS_TOPIC, b"".join(parts), t)


def _point_bytes(pt: tuple[float, float, float]) -> bytes:
    """One ``LinePrimitive.points`` field (5) holding the Point3 ``pt``."""
    x, y, z = pt
    if x and y and z:
        return _XYZ(0x2A, 27, 0x09, x, 0x11, y, 0x19, z)
    return _vector_bytes(b"\x2a", pt, _DOUBLE_TAGS[:3])


def _line_fixed_fields() -> tuple[bytes, bytes]:
    """The path line's fields before and after its points, serialized by protobuf itself."""
    line = LinePrimitive(type=LinePrimitive.LINE_STRIP, thickness=2.0, scale_invariant=True)
    _set_pose(line.pose, (0.0, 0.0, 0.0))
    color = Color()
    _set_color(color, PATH_RGBA)
    c = color.SerializeToString()
    return line.SerializeToString(), b"\x32" + _varint(len(c)) + c


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
