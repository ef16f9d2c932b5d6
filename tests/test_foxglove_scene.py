"""Foxglove scene channels: decodable with mcap_protobuf, one entity per agent and obstacle."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from mcap_protobuf.decoder import DecoderFactory

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world

from swarmplan.io.foxglove_scene import FoxgloveScene, file_descriptor_set


def _world(n_agents=3):
    import trimesh

    mesh = trimesh.creation.box(extents=[2, 2, 2])
    mesh.apply_translation([10, 10, 5])
    obstacles = [
        {"id": "ball", "shape": "sphere", "radius": 2, "position": [0, 10, 5]},
        {"id": "block", "shape": "box", "size": [2, 4, 6], "position": [-10, 10, 5], "rotation": [0, 0, 30]},
        {"id": "mast", "shape": "cylinder", "radius": 1, "height": 10, "position": [5, -10, 5]},
        {
            "id": "pole",
            "shape": "capsule",
            "radius": 1,
            "height": 4,
            "position": [-5, -10, 5],
            "rotation": [90, 0, 0],
        },
        {
            "id": "hangar",
            "shape": "mesh",
            "position": [10, 10, 5],
            "vertices": mesh.vertices.tolist(),
            "faces": mesh.faces.tolist(),
        },
        {
            "id": "drone",
            "shape": "sphere",
            "radius": 1,
            "position": [0, -20, 10],
            "motion": {"type": "linear"},
        },
        {
            "id": "crate",
            "shape": "box",
            "size": [1, 1, 1],
            "position": [0, 20, 10],
            "motion": {"type": "circle"},
        },
    ]
    agents = [
        {"id": f"uav{i}", "start": [-30, 3.0 * i, 10], "goal": [30, 3.0 * i, 10]} for i in range(n_agents)
    ]
    return base_world(
        agents, obstacles, terrain={"peaks": [{"center": [0, 0], "height": 5, "spread": [10, 10]}]}
    )


def _steps(world, n_steps=30, dt=0.1):
    out = []
    for k in range(n_steps):
        t = round(k * dt, 9)
        agents = [
            {
                "id": a["id"],
                "position": [a["start"][0] + 2.0 * t, a["start"][1], 10.0],
                "velocity": [2.0, 0.0, 0.0],
                "mode": "escape" if 1.0 <= t < 2.0 else "apf",
                "goal": a["goal"],
            }
            for a in world["agents"]
        ]
        obstacles = [
            {"id": "drone", "position": [t, -20, 10], "orientation": [0, 0, 0, 1]},
            {"id": "crate", "position": [0, 20, 10], "orientation": [0, 0, np.sin(t / 2), np.cos(t / 2)]},
        ]
        out.append((t, agents, obstacles))
    return out


def _write(path, world, steps, **kw):
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library="test")
        scene = FoxgloveScene(w, world, **kw)
        scene.write_world()
        for t, agents, obstacles in steps:
            scene.write_step(t, agents, obstacles)
        scene.finish()
        w.finish()
    return scene


PROTOBUF_TOPICS = ["/scene", "/scene/world", "/scene/paths", "/scene/paths/overview", "/tf"]


def _decode(path):
    out: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message in reader.iter_messages():
            if channel.topic == "/agents/speed":  # the one JSON channel
                out.setdefault(channel.topic, []).append(
                    (message.log_time, schema.name, json.loads(message.data))
                )
        for schema, channel, message, decoded in reader.iter_decoded_messages(topics=PROTOBUF_TOPICS):
            assert schema.encoding == "protobuf" and channel.message_encoding == "protobuf"
            out.setdefault(channel.topic, []).append((message.log_time, schema.name, decoded))
    return out


def test_scene_decodes_with_one_entity_per_agent_and_obstacle(tmp_path):
    world = _world(3)
    steps = _steps(world)
    path = tmp_path / "scene.mcap"
    _write(path, world, steps)
    msgs = _decode(path)
    assert {"/scene", "/scene/world", "/scene/paths", "/tf"} <= set(msgs)

    # static world at t = 0
    (t0, name, world_msg), *_ = msgs["/scene/world"]
    assert t0 == 0 and name == "foxglove.SceneUpdate"
    ents = {e.id: e for e in world_msg.entities}
    static = [o["id"] for o in world["obstacles"] if not o.get("motion")]
    for oid in static:
        assert f"obstacle/{oid}" in ents
    assert all(e.frame_id == "world" for e in world_msg.entities)
    assert len(ents["obstacle/ball"].spheres) == 1 and ents["obstacle/ball"].spheres[0].size.x == 4
    cube = ents["obstacle/block"].cubes[0]
    assert (cube.size.x, cube.size.y, cube.size.z) == (2, 4, 6)
    assert cube.pose.orientation.z == pytest.approx(np.sin(np.radians(15)))
    assert len(ents["obstacle/mast"].cylinders) == 1
    cap = ents["obstacle/pole"]
    assert len(cap.cylinders) == 1 and len(cap.spheres) == 2
    # capsule rolled 90 deg: its end spheres sit along world -y/+y
    ys = sorted(s.pose.position.y for s in cap.spheres)
    assert ys == pytest.approx([-12.0, -8.0])
    tri = ents["obstacle/hangar"].triangles[0]
    assert len(tri.points) == 8 and len(tri.indices) == 36
    assert "bounds" in ents and "terrain" in ents
    assert {f"goal/{a['id']}" for a in world["agents"]} <= set(ents)

    # dynamic scene: last message has exactly one entity per agent and per moving obstacle
    t_last, _, last = msgs["/scene"][-1]
    ids = [e.id for e in last.entities]
    expected = [f"agent/{a['id']}" for a in world["agents"]] + ["obstacle/drone", "obstacle/crate"]
    assert sorted(ids) == sorted(expected)
    assert t_last == round(steps[-1][0] * 1e9)
    agent0 = next(e for e in last.entities if e.id == "agent/uav0")
    assert agent0.spheres[0].pose.position.x == pytest.approx(steps[-1][1][0]["position"][0])
    assert agent0.spheres[0].size.x == pytest.approx(2 * world["agents"][0]["radius"])
    assert agent0.timestamp.seconds * 10**9 + agent0.timestamp.nanos == t_last
    crate = next(e for e in last.entities if e.id == "obstacle/crate")
    assert crate.cubes[0].pose.orientation.z == pytest.approx(np.sin(steps[-1][0] / 2))
    # throttled: every 0.2 s of sim time (+ final), not every step
    assert len(msgs["/scene"]) < len(steps)
    # all timestamps are simulation time
    for items in msgs.values():
        assert max(t for t, _, _ in items) <= round(steps[-1][0] * 1e9)

    # flown paths: chunks that join into every sampled point of each agent's path, ending at
    # the final position; the overview draws each path whole
    assert _joined_chunks(msgs) == _sampled(world, steps)
    _, _, overview = msgs["/scene/paths/overview"][-1]
    assert sorted(e.id for e in overview.entities) == sorted(f"path/{a['id']}" for a in world["agents"])
    line = overview.entities[0].lines[0]
    assert len(line.points) >= 2
    assert line.points[-1].x == pytest.approx(steps[-1][1][0]["position"][0])

    # speeds with each /scene message: 2 m/s along x for every agent
    speeds = msgs["/agents/speed"]
    assert [t for t, _, _ in speeds] == [t for t, _, _ in msgs["/scene"]]
    assert all(
        m["speed"] == [2.0] * len(world["agents"]) and m["max"] == m["mean"] == 2.0 for _, _, m in speeds
    )

    # a FrameTransforms message with each /scene message, a FrameTransform per agent, parent
    # "world", child = agent id, at the agent's position
    tfs = msgs["/tf"]
    assert all(name == "foxglove.FrameTransforms" for _, name, _ in tfs)
    assert [t for t, _, _ in tfs] == [t for t, _, _ in msgs["/scene"]]
    per_agent: dict[str, int] = {}
    for log_time, _, msg in tfs:
        assert [tf.child_frame_id for tf in msg.transforms] == [a["id"] for a in world["agents"]]
        for tf in msg.transforms:
            assert tf.parent_frame_id == "world"
            per_agent[tf.child_frame_id] = per_agent.get(tf.child_frame_id, 0) + 1
            assert tf.timestamp.seconds * 10**9 + tf.timestamp.nanos == log_time
    assert all(n == len(tfs) for n in per_agent.values())
    last_t, _, last_tf = tfs[-1]
    assert last_t == round(steps[-1][0] * 1e9)
    for tf, a in zip(last_tf.transforms, steps[-1][1], strict=True):
        assert (tf.translation.x, tf.translation.y, tf.translation.z) == tuple(a["position"])


def test_file_descriptor_set_is_self_contained():
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    fds = file_descriptor_set(SceneUpdate)
    names = [f.name for f in fds.file]
    assert names[-1] == "foxglove/SceneUpdate.proto"
    assert "google/protobuf/timestamp.proto" in names
    assert len(names) == len(set(names))
    # every dependency precedes its dependant
    for i, f in enumerate(fds.file):
        assert set(f.dependency) <= set(names[:i])


def _joined_chunks(msgs) -> dict[str, list[tuple[float, float, float]]]:
    """Per agent: its chunks' points in order, each chunk's first point (the one before's
    last) dropped after the first chunk."""
    out: dict[str, list] = {}
    nxt: dict[str, int] = {}
    for _, _, m in msgs["/scene/paths"]:
        for e in m.entities:
            _, aid, k = e.id.split("/")
            assert int(k) == nxt.get(aid, 0)  # chunks numbered 0, 1, ... in message order
            nxt[aid] = int(k) + 1
            pts = [(p.x, p.y, p.z) for p in e.lines[0].points]
            if aid in out:
                assert pts[0] == out[aid][-1]
                pts = pts[1:]
            out.setdefault(aid, []).extend(pts)
    return out


def _sampled(world, steps, period: float = 0.2) -> dict[str, list[tuple[float, float, float]]]:
    """Per agent: its positions at the scene's samples (every ``period`` s and the last step)."""
    out: dict[str, list] = {}
    due = -1.0
    for k, (t, agents, _) in enumerate(steps):
        if t >= due - 1e-9 or k == len(steps) - 1:
            due = t + period
            for a in agents:
                pts = out.setdefault(a["id"], [])
                if not pts or pts[-1] != tuple(a["position"]):
                    pts.append(tuple(a["position"]))
    return out


def test_path_messages_stay_bounded_and_the_overview_whole(tmp_path):
    world = _world(2)
    steps = _steps(world, n_steps=400)
    scene = _write(tmp_path / "long.mcap", world, steps, path_max_points=50, overview_points=20)
    assert all(scene.trails.count[k] <= 50 for k in scene.trails.order.values())
    msgs = _decode(tmp_path / "long.mcap")
    # a chunk per agent per second: 5 samples, plus the previous chunk's last point
    assert max(len(e.lines[0].points) for _, _, m in msgs["/scene/paths"] for e in m.entities) <= 6
    assert _joined_chunks(msgs) == _sampled(world, steps)
    _, _, overview = msgs["/scene/paths/overview"][-1]
    for e in overview.entities:
        pts = [(p.x, p.y, p.z) for p in e.lines[0].points]
        want = _sampled(world, steps)[e.id.split("/")[1]]
        assert len(pts) == 20 and pts[0] == want[0] and pts[-1] == want[-1]


def test_cost_per_step_64_agents(tmp_path):
    """Measured cost (printed with -s); generous bound so it is not flaky on a busy machine."""
    world = _world(64)
    steps = _steps(world, n_steps=100)
    t0 = time.perf_counter()
    _write(tmp_path / "bench.mcap", world, steps)
    per_step = (time.perf_counter() - t0) / len(steps)
    print(f"FoxgloveScene: {per_step * 1e3:.3f} ms/step for 64 agents (incl. world and MCAP writer)")
    assert per_step < 0.02
