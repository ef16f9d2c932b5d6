"""Foxglove ``SceneEntity`` shapes built through the protobuf API: obstacles (static and the
moving ones no faster encoding covers), and the world's static scene (bounds box, terrain,
goals). The per-step channels that use them are in :mod:`swarmplan.io.foxglove_scene`."""

from __future__ import annotations

from typing import Any

import numpy as np
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity

from swarmplan.geometry.rotation import euler_to_quaternion, rotate
from swarmplan.io.wire import DOUBLE, Patched, join_records, record_starts, varint

FRAME = "world"
OBSTACLE_RGBA = (0.55, 0.58, 0.65, 0.8)
MOVING_RGBA = (0.9, 0.45, 0.1, 0.85)
# Shapes drawn with one primitive (a moving one keeps its layout: only time and pose change).
ONE_PRIMITIVE = ("sphere", "box", "cylinder", "ellipsoid")


def set_pose(pose, position, quat=(0.0, 0.0, 0.0, 1.0)) -> None:
    pose.position.x, pose.position.y, pose.position.z = (float(c) for c in position[:3])
    o = pose.orientation
    o.x, o.y, o.z, o.w = (float(c) for c in quat)


def set_color(color, rgba) -> None:
    color.r, color.g, color.b, color.a = rgba


def set_time(ts, t: float) -> None:
    ns = int(round(t * 1e9))
    ts.seconds, ts.nanos = divmod(ns, 1_000_000_000)


def entity(eid: str, t: float | None) -> SceneEntity:
    """An entity in the frame ``FRAME``; ``t`` None leaves its timestamp unset (its bytes,
    field 1, then go in front of the serialized rest)."""
    e = SceneEntity(frame_id=FRAME, id=eid)
    if t is not None:
        set_time(e.timestamp, t)
    return e


def rest_orientation(obst: dict[str, Any]) -> tuple[float, ...]:
    """The quaternion of an obstacle's ``rotation`` (Euler degrees), as the world file gives it."""
    return tuple(euler_to_quaternion((list(obst.get("rotation") or []) + [0, 0, 0])[:3]))


def obstacle_entity(
    obst: dict[str, Any], t: float | None, position=None, quat=None, rgba=OBSTACLE_RGBA
) -> SceneEntity:
    e = entity(f"obstacle/{obst['id']}", t)
    fill_obstacle(e, obst, position, quat, rgba)
    return e


def fill_obstacle(e, obst, position=None, quat=None, rgba=OBSTACLE_RGBA) -> None:
    shape = obst.get("shape")
    pos = np.asarray(obst.get("position", [0, 0, 0]) if position is None else position, float)
    q = tuple(quat) if quat is not None else rest_orientation(obst)
    if shape == "sphere":
        s = e.spheres.add()
        set_pose(s.pose, pos, q)
        d = 2.0 * float(obst["radius"])
        s.size.x = s.size.y = s.size.z = d
        set_color(s.color, rgba)
    elif shape == "ellipsoid":  # a sphere primitive sized per axis
        s = e.spheres.add()
        set_pose(s.pose, pos, q)
        s.size.x, s.size.y, s.size.z = (2.0 * float(v) for v in obst["semi_axes"])
        set_color(s.color, rgba)
    elif shape == "box":
        c = e.cubes.add()
        set_pose(c.pose, pos, q)
        c.size.x, c.size.y, c.size.z = (float(v) for v in obst["size"])
        set_color(c.color, rgba)
    elif shape in ("cylinder", "capsule"):
        r = float(obst["radius"])
        h = float(obst.get("height", obst.get("length", 0.0)))
        c = e.cylinders.add()
        set_pose(c.pose, pos, q)
        c.size.x = c.size.y = 2.0 * r
        c.size.z = h
        c.bottom_scale = c.top_scale = 1.0
        set_color(c.color, rgba)
        if shape == "capsule":
            for sign in (-1.0, 1.0):
                s = e.spheres.add()
                set_pose(s.pose, pos + rotate(q, [0.0, 0.0, sign * h / 2.0]), q)
                s.size.x = s.size.y = s.size.z = 2.0 * r
                set_color(s.color, rgba)
    elif shape == "mesh" and "vertices" in obst:
        tri = e.triangles.add()
        v = np.asarray(obst["vertices"], float)
        if position is not None:  # moving mesh: vertices are its pose at t = 0
            v = v - np.asarray(obst.get("position", [0, 0, 0]), float)
            set_pose(tri.pose, pos, q if quat is not None else (0.0, 0.0, 0.0, 1.0))
        else:
            set_pose(tri.pose, (0.0, 0.0, 0.0))
        for x, y, z in v:
            tri.points.add(x=float(x), y=float(y), z=float(z))
        tri.indices.extend(int(i) for i in np.asarray(obst["faces"], int).ravel())
        set_color(tri.color, rgba)


def world_entities(world: dict[str, Any], obstacles: list[dict[str, Any]], t: float) -> list[SceneEntity]:
    """The ``/scene/world`` entities: static obstacles, bounds, terrain and goals."""
    entities = []
    for obst in obstacles:
        if not obst.get("motion"):
            entities.append(obstacle_entity(obst, t))
    b = world.get("bounds") or {}
    if b.get("min") is not None and b.get("max") is not None:
        lo, hi = np.asarray(b["min"], float), np.asarray(b["max"], float)
        e = entity("bounds", t)
        line = e.lines.add(type=LinePrimitive.LINE_LIST, thickness=2.0, scale_invariant=True)
        set_pose(line.pose, (0.0, 0.0, 0.0))
        corners = [
            np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])
        ]
        for i in range(8):
            for j in range(i + 1, 8):
                if np.count_nonzero(corners[i] != corners[j]) == 1:
                    for p in (corners[i], corners[j]):
                        line.points.add(x=float(p[0]), y=float(p[1]), z=float(p[2]))
        set_color(line.color, (0.6, 0.6, 0.6, 1.0))
        entities.append(e)
        terrain = terrain_entity(world, lo, hi, t)
        if terrain is not None:
            entities.append(terrain)
    for a in world.get("agents") or []:
        if a.get("goal") is None:
            continue
        e = entity(f"goal/{a['id']}", t)
        s = e.spheres.add()
        set_pose(s.pose, a["goal"])
        tol = float((world.get("sim") or {}).get("goal_tolerance", 1.0) or 1.0)
        s.size.x = s.size.y = s.size.z = 2.0 * tol
        set_color(s.color, (0.17, 0.63, 0.17, 0.35))
        entities.append(e)
    return entities


def terrain_entity(world: dict[str, Any], lo, hi, t: float, n: int = 32) -> SceneEntity | None:
    peaks = (world.get("terrain") or {}).get("peaks") or []
    if not peaks:
        return None
    xs, ys = np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)
    X, Y = np.meshgrid(xs, ys)
    Z = np.zeros_like(X)
    for pk in peaks:
        cx, cy = pk["center"][:2]
        sx, sy = (pk.get("spread") or [1, 1])[:2]
        Z += float(pk["height"]) * np.exp(-(((X - cx) / sx) ** 2) - ((Y - cy) / sy) ** 2)
    e = entity("terrain", t)
    tri = e.triangles.add()
    set_pose(tri.pose, (0.0, 0.0, 0.0))
    for x, y, z in zip(X.ravel(), Y.ravel(), Z.ravel(), strict=True):
        tri.points.add(x=float(x), y=float(y), z=float(z))
    idx = []
    for r in range(n - 1):
        for c in range(n - 1):
            a, b2, c2, d = r * n + c, r * n + c + 1, (r + 1) * n + c, (r + 1) * n + c + 1
            idx += [a, b2, d, a, d, c2]
    tri.indices.extend(idx)
    set_color(tri.color, (0.45, 0.6, 0.35, 0.5))
    return e


_ENTITIES_TAG = b"\x12"  # SceneUpdate.entities: field 2, wire type 2


def entity_record(e: SceneEntity) -> bytes:
    """A serialized entity as a ``SceneUpdate.entities`` field."""
    b = e.SerializeToString()
    return _ENTITIES_TAG + varint(len(b)) + b


def mover_template(known: list[tuple[dict, dict]], stamp: bytes, present: np.ndarray) -> Patched | bool:
    """The /scene records of one-primitive movers with the pose components ``present`` (m, 7)
    (x, y, z, qx, qy, qz, qw) and a timestamp of ``len(stamp)`` bytes: each entity is serialized
    once by protobuf (without its timestamp, field 1, which goes in front) with distinct marker
    values in the pose, whose places the numbers then take. False when a marker is not unique."""
    bodies, places = [], []
    for (_, obst), mask in zip(known, present.tolist(), strict=True):
        marks = [1.5e-300 * (k + 1) if m else 0.0 for k, m in enumerate(mask)]
        body = obstacle_entity(obst, None, marks[:3], marks[3:], MOVING_RGBA).SerializeToString()
        found = [body.find(DOUBLE(v)) for v, m in zip(marks, mask, strict=True) if m]
        if any(body.count(DOUBLE(v)) != 1 for v, m in zip(marks, mask, strict=True) if m):
            return False
        bodies.append(body)
        places.append(found)
    lengths = [len(stamp) + len(b) for b in bodies]
    data = join_records(_ENTITIES_TAG, lengths, stamp, [b""] * len(bodies), bodies)
    stamp_at = record_starts(lengths)
    at = np.concatenate(
        [s + len(stamp) + np.asarray(p, dtype=np.intp) for s, p in zip(stamp_at, places, strict=True)]
    )
    return Patched(data, stamp_at, len(stamp), at)
