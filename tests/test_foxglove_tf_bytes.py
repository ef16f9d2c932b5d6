"""/tf and the agents of /scene are written in protobuf's wire format directly: the bytes equal
what protobuf's own serializer makes of the same messages (zeros, -0.0, standing agents,
every mode's colour included)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from swarmplan.core import Mode
from swarmplan.io.foxglove_scene import MODE_COLORS, TF_TOPIC, FoxgloveScene


class _Capture:
    """The slice of mcap's Writer that FoxgloveScene uses, keeping the messages."""

    def __init__(self):
        self.messages: list[tuple[int, int, bytes]] = []

    def register_schema(self, **_):
        return 1

    def register_channel(self, topic, **_):
        return {"/tf": 10, "/scene": 12, "/scene/paths": 13, "/scene/paths/overview": 14}.get(topic, 11)

    def add_message(self, channel_id, log_time, publish_time, data):
        self.messages.append((channel_id, log_time, data))


def _reference(t: float, agents: list[dict], last: dict[str, FrameTransform]) -> bytes:
    """The /tf message built through the protobuf API (the previous implementation's rules)."""
    out = FrameTransforms()
    for a in agents:
        aid = a["id"]
        tf = last.get(aid)
        if tf is None:
            tf = last[aid] = FrameTransform(parent_frame_id="world", child_frame_id=aid)
            tf.rotation.w = 1.0
        ns = int(round(t * 1e9))
        tf.timestamp.seconds, tf.timestamp.nanos = divmod(ns, 1_000_000_000)
        tf.translation.x, tf.translation.y, tf.translation.z = (float(c) for c in a["position"])
        v = a["velocity"]
        if v[0] or v[1]:
            yaw = math.atan2(v[1], v[0]) / 2.0
            tf.rotation.z, tf.rotation.w = math.sin(yaw), math.cos(yaw)
        out.transforms.append(tf)
    return out.SerializeToString()


@pytest.mark.parametrize("seed", range(3))
def test_tf_bytes_equal_protobuf_serializer(seed):
    rng = np.random.default_rng(seed)
    ids = ["a0", "uav-1", "x" * 200, "ü"]  # a child id longer than 127 bytes: two-byte length
    world = {"agents": [{"id": i} for i in ids]}
    cap = _Capture()
    scene = FoxgloveScene(cap, world, scene_period=1e9, path_period=1e9, tf_period=0.0)
    last: dict[str, FrameTransform] = {}
    special = [0.0, -0.0, 1.0, -2.5]
    for step in range(40):
        t = step * 0.1 if step else 0.0
        agents = []
        for i in ids:
            p = rng.normal(0, 50, 3)
            v = rng.normal(0, 3, 3)
            if rng.random() < 0.4:
                p[rng.integers(3)] = special[rng.integers(4)]
            if rng.random() < 0.3:
                v[:2] = special[rng.integers(4)], special[rng.integers(4)]
            if rng.random() < 0.1:
                v[:2] = 1.0, 0.0  # yaw exactly zero: rotation.z = 0.0 is left out
            agents.append({"id": i, "position": p.tolist(), "velocity": v.tolist()})
        scene.write_step(t, agents, [])
        tf = [m for m in cap.messages if m[0] == 10]
        assert tf[-1][2] == _reference(t, agents, last)
        assert FrameTransforms.FromString(tf[-1][2]).transforms[0].child_frame_id == "a0"
    assert TF_TOPIC == "/tf"


def _reference_scene(t: float, agents: list[dict], radius: dict[str, float]) -> bytes:
    """The agents' /scene entities built through the protobuf API (the previous rules)."""
    out = SceneUpdate()
    ns = int(round(t * 1e9))
    for a in agents:
        e = SceneEntity(frame_id="world", id=f"agent/{a['id']}")
        e.timestamp.seconds, e.timestamp.nanos = divmod(ns, 1_000_000_000)
        s = e.spheres.add()
        s.size.x = s.size.y = s.size.z = 2.0 * radius[a["id"]]
        s.pose.orientation.w = 1.0
        s.pose.position.x, s.pose.position.y, s.pose.position.z = (float(c) for c in a["position"])
        s.color.r, s.color.g, s.color.b, s.color.a = MODE_COLORS.get(a["mode"], (0.8, 0.2, 0.8, 1.0))
        out.entities.append(e)
    return out.SerializeToString()


@pytest.mark.parametrize("seed", range(2))
def test_scene_agent_bytes_equal_protobuf_serializer(seed):
    rng = np.random.default_rng(seed)
    radius = {"a0": 0.5, "uav-1": 1.25, "x" * 150: 0.3}
    world = {"agents": [{"id": i, "radius": r} for i, r in radius.items()]}
    cap = _Capture()
    scene = FoxgloveScene(cap, world, scene_period=0.0, path_period=1e9, tf_period=0.0)
    modes = [str(m) for m in Mode] + ["unknown"]
    for step in range(30):
        t = step * 0.1
        agents = []
        for i in radius:
            p = rng.normal(0, 50, 3)
            if rng.random() < 0.4:
                p[rng.integers(3)] = [0.0, -0.0][rng.integers(2)]
            mode = modes[rng.integers(len(modes))]
            agents.append({"id": i, "position": p.tolist(), "velocity": [1.0, 0.0, 0.0], "mode": mode})
        scene.write_step(t, agents, [])
        msg = [m for m in cap.messages if m[0] == 12][-1][2]
        assert msg == _reference_scene(t, agents, radius)
    assert len(SceneUpdate.FromString(msg).entities) == 3


def test_varint_table_equals_the_encoding():
    from google.protobuf.internal.encoder import _VarintBytes

    from swarmplan.io.wire import varint as _varint

    for n in [0, 1, 127, 128, 300, 16383, 16384, 2**21 - 1, 2**21, 2**35 + 7]:
        assert _varint(n) == _VarintBytes(n)


class _ReferencePaths:
    """The /scene/paths and /scene/paths/overview rules through the protobuf API: per agent
    with new points a chunk ``path/<id>/<k>`` from the last chunk's last point on; the overview
    ``path/<id>`` of at most ``overview_points`` kept points (halved past ``max_points``)."""

    def __init__(self, max_points: int, overview_points: int):
        self.max_points, self.overview_points = max_points, overview_points
        self.kept: dict[str, list] = {}
        self.chunk: dict[str, list] = {}
        self.index: dict[str, int] = {}
        self.new: dict[str, bool] = {}

    def sample(self, agents):
        for a in agents:
            aid = a["id"]
            pt = tuple(float(c) for c in a["position"])
            kept = self.kept.setdefault(aid, [])
            if kept and kept[-1] == pt:
                continue
            kept.append(pt)
            if len(kept) > self.max_points:
                self.kept[aid] = kept[:-1:2] + [kept[-1]]
            self.chunk.setdefault(aid, []).append(pt)
            self.new[aid] = True

    def _entity(self, t, eid, pts, thickness):
        from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive

        e = SceneEntity(frame_id="world", id=eid)
        ns = int(round(t * 1e9))
        e.timestamp.seconds, e.timestamp.nanos = divmod(ns, 1_000_000_000)
        line = e.lines.add(type=LinePrimitive.LINE_STRIP, thickness=thickness, scale_invariant=True)
        line.pose.position.x = line.pose.position.y = line.pose.position.z = 0.0
        o = line.pose.orientation
        o.x, o.y, o.z, o.w = 0.0, 0.0, 0.0, 1.0
        for x, y, z in pts:
            line.points.add(x=x, y=y, z=z)
        line.color.r, line.color.g, line.color.b, line.color.a = (0.12, 0.47, 0.71, 0.9)
        return e

    def message(self, t: float) -> bytes | None:
        out = SceneUpdate()
        for aid in self.kept:
            if self.new.get(aid):
                k = self.index.get(aid, 0)
                out.entities.append(self._entity(t, f"path/{aid}/{k}", self.chunk[aid], 2.0))
                self.chunk[aid] = [self.chunk[aid][-1]]
                self.index[aid], self.new[aid] = k + 1, False
        return out.SerializeToString() if out.entities else None

    def overview(self, t: float) -> bytes:
        out = SceneUpdate()
        for aid, kept in self.kept.items():
            n = len(kept)
            pick = (
                range(n)
                if n <= self.overview_points
                else np.round(np.linspace(0, n - 1, self.overview_points))
            )
            out.entities.append(self._entity(t, f"path/{aid}", [kept[int(i)] for i in pick], 1.0))
        return out.SerializeToString()


@pytest.mark.parametrize("seed", range(2))
def test_path_bytes_equal_protobuf_serializer(seed):
    """Paths sampled every step, chunks and overview written every step, kept points halved
    past 6, the overview at most 4 points; repeated positions (a standing agent), zero and
    -0.0 coordinates."""
    rng = np.random.default_rng(seed)
    ids = ["a0", "b1", "y" * 140]
    cap = _Capture()
    scene = FoxgloveScene(
        cap,
        {"agents": [{"id": i} for i in ids]},
        scene_period=0.0,
        path_period=0.0,
        overview_period=0.0,
        overview_points=4,
        path_max_points=6,
    )
    ref = _ReferencePaths(6, 4)
    last = {i: rng.normal(0, 30, 3) for i in ids}
    chunks, overviews = [], []
    for step in range(40):
        t = step * 0.1
        agents = []
        for i in ids:
            if step % 10 != 5 and rng.random() < 0.7:  # otherwise it stands still: no new point
                last[i] = rng.normal(0, 30, 3)
                if rng.random() < 0.3:
                    last[i][rng.integers(3)] = [0.0, -0.0][rng.integers(2)]
            agents.append({"id": i, "position": last[i].tolist(), "velocity": [0.0, 0.0, 0.0], "mode": "apf"})
        scene.write_step(t, agents, [])
        ref.sample(agents)
        chunks.append(ref.message(t))
        overviews.append(ref.overview(t))
    assert [m[2] for m in cap.messages if m[0] == 13] == [c for c in chunks if c is not None]
    assert [m[2] for m in cap.messages if m[0] == 14] == overviews
    assert any(c is None for c in chunks)  # a step where nobody moved writes no chunk message
    assert max(len(e.lines[0].points) for e in SceneUpdate.FromString(overviews[-1]).entities) == 4


def _times():
    """Step times whose timestamps take every length: t = 0 (empty), whole seconds (no nanos),
    nanos of 4 and 5 bytes, seconds of 1 and 2 bytes."""
    return [0.0, 0.1, 0.2, 0.6, 1.0, 1.1, 2.0, 2.7, 127.9, 128.0, 128.3, 300.9, 301.0, 301.1]


@pytest.mark.parametrize("seed", range(3))
def test_templated_steps_equal_protobuf_serializer(seed):
    """Long runs of steps without zero coordinates (where /tf and the agents of /scene are
    filled into a template), broken by zeros, mode changes and timestamps of every length."""
    rng = np.random.default_rng(seed)
    radius = {"a0": 0.5, "uav-1": 1.25, "x" * 150: 0.3, "b": 2.0}
    cap = _Capture()
    scene = FoxgloveScene(
        cap,
        {"agents": [{"id": i, "radius": r} for i, r in radius.items()]},
        scene_period=0.0,
        path_period=1e9,
        tf_period=0.0,
    )
    last: dict[str, FrameTransform] = {}
    modes = {i: "apf" for i in radius}
    times = _times()
    for step in range(120):
        t = times[step % len(times)] + 1000.0 * (step // len(times))
        agents = []
        for i in radius:
            p, v = rng.normal(0, 50, 3), rng.normal(0, 3, 3)
            if rng.random() < 0.03:
                p[rng.integers(3)] = [0.0, -0.0][rng.integers(2)]
            if rng.random() < 0.03:
                v[:2] = 1.0, 0.0  # heading exactly along x: rotation.z = 0.0 is left out
            if rng.random() < 0.05:
                modes[i] = ["apf", "escape", "arrived", "smoothing"][rng.integers(4)]
            agents.append({"id": i, "position": p.tolist(), "velocity": v.tolist(), "mode": modes[i]})
        scene.write_step(t, agents, [])
        assert [m for m in cap.messages if m[0] == 10][-1][2] == _reference(t, agents, last)
        assert [m for m in cap.messages if m[0] == 12][-1][2] == _reference_scene(t, agents, radius)
    assert len(scene._tf_templates) >= 3 and len(scene._scene_templates) >= 1  # the filled path ran


def _reference_movers(t: float, obstacles: list[dict], world_obstacles: dict[str, dict]) -> bytes:
    """The movers' /scene entities through the protobuf API, built afresh each step."""
    from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity

    from swarmplan.geometry.rotation import euler_to_quaternion

    out = SceneUpdate()
    ns = int(round(t * 1e9))
    for o in obstacles:
        obst = world_obstacles[o["id"]]
        e = SceneEntity(frame_id="world", id=f"obstacle/{o['id']}")
        e.timestamp.seconds, e.timestamp.nanos = divmod(ns, 1_000_000_000)
        q = o.get("orientation")
        if q is None:
            q = euler_to_quaternion((list(obst.get("rotation") or []) + [0, 0, 0])[:3])
        shape = obst["shape"]
        prim = {"sphere": e.spheres, "box": e.cubes, "cylinder": e.cylinders}[shape].add()
        prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = (float(c) for c in o["position"])
        o_ = prim.pose.orientation
        o_.x, o_.y, o_.z, o_.w = (float(c) for c in q)
        if shape == "sphere":
            prim.size.x = prim.size.y = prim.size.z = 2.0 * obst["radius"]
        elif shape == "box":
            prim.size.x, prim.size.y, prim.size.z = (float(v) for v in obst["size"])
        else:
            prim.size.x = prim.size.y = 2.0 * obst["radius"]
            prim.size.z = float(obst["height"])
            prim.bottom_scale = prim.top_scale = 1.0
        prim.color.r, prim.color.g, prim.color.b, prim.color.a = (0.9, 0.45, 0.1, 0.85)
        out.entities.append(e)
    return out.SerializeToString()


@pytest.mark.parametrize("seed", range(3))
def test_mover_bytes_equal_protobuf_serializer(seed):
    """Moving spheres, boxes and cylinders (filled into templates per layout): poses with
    zero and -0.0 components, orientations given or from the world's rotation, timestamps of
    every length, a mover missing from some steps."""
    rng = np.random.default_rng(seed)
    world_obstacles = {
        "m0": {"id": "m0", "shape": "sphere", "radius": 4.0, "position": [0, 0, 0], "motion": {}},
        "m1": {"id": "m1", "shape": "box", "size": [1.0, 2.0, 3.0], "position": [0, 0, 0], "motion": {}},
        "m2": {
            "id": "m2",
            "shape": "cylinder",
            "radius": 1.5,
            "height": 7.0,
            "position": [0, 0, 0],
            "rotation": [0, 0, 30],
            "motion": {},
        },
        "long-" + "z" * 130: {"id": "long-" + "z" * 130, "shape": "sphere", "radius": 1.0, "motion": {}},
    }
    cap = _Capture()
    scene = FoxgloveScene(
        cap, {"agents": [], "obstacles": list(world_obstacles.values())}, scene_period=0.0, path_period=1e9
    )
    times = _times()
    for step in range(90):
        t = times[step % len(times)] + 1000.0 * (step // len(times))
        obstacles = []
        for oid in world_obstacles:
            if oid == "m1" and 30 <= step < 40:
                continue  # the set of movers changes
            p = rng.normal(0, 40, 3)
            if rng.random() < 0.1:
                p[rng.integers(3)] = [0.0, -0.0][rng.integers(2)]
            entry = {"id": oid, "position": p.tolist()}
            if oid != "m2":
                q = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.38268343236508984, 0.9238795325112867]][step % 2]
                entry["orientation"] = q if rng.random() < 0.9 else [-0.0, 0.5, 0.5, 0.7071067811865476]
            obstacles.append(entry)
        scene.write_step(t, [], obstacles)
        assert [m for m in cap.messages if m[0] == 12][-1][2] == _reference_movers(
            t, obstacles, world_obstacles
        )
    assert any(v is not False for v in scene._mover_templates.values())  # the filled path ran
