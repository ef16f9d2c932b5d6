"""Trajectories of moving obstacles: position and velocity at any simulation time.

Conventions (documented in the README's world reference):
- ``linear``: ``position + velocity * t``.
- ``waypoints``: the path starts at ``position`` and visits the waypoints in order at
  ``speed``; with ``loop`` it returns to ``position`` and repeats, otherwise it stops at
  the last waypoint.
- ``circle``: horizontal circle of ``radius`` about ``center`` (at the centre's height),
  starting at the angle of ``position`` about the centre, turning at ``angular_speed``
  rad/s (positive = counter-clockwise seen from above).
Orientation stays the obstacle's ``rotation`` (the motions translate only).
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from swarmplan.world.model import Motion, Obstacle, World


_CACHE_SIZE = 256
"""Entries of each per-object cache below (the object is kept with its entry, so its id
cannot be reused while cached)."""
_PATHS: dict[int, tuple[Obstacle, np.ndarray, np.ndarray]] = {}


def _waypoint_path(o: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """The path's vertices and cumulative lengths (built once per obstacle: every pose asked for)."""
    hit = _PATHS.get(id(o))
    if hit is not None and hit[0] is o:
        return hit[1], hit[2]
    pts, cum = _build_waypoint_path(o)
    pts.flags.writeable = cum.flags.writeable = False
    if len(_PATHS) >= _CACHE_SIZE:  # obstacles of worlds long gone: start over
        _PATHS.clear()
    _PATHS[id(o)] = (o, pts, cum)
    return pts, cum


def _build_waypoint_path(o: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    m = o.motion
    pts = [o.position] + [w for w in m.waypoints]
    if m.loop:
        pts.append(o.position)
    pts = np.array(pts)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    pts = pts[keep]
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    return pts, cum


def pose_at(o: Obstacle, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(position, velocity) of obstacle ``o`` at time ``t``."""
    m: Motion | None = o.motion
    if m is None:
        return o.position.copy(), np.zeros(3)
    if m.type == "linear":
        return o.position + m.velocity * t, m.velocity.copy()
    if m.type == "circle":
        rel = o.position[:2] - m.center[:2]
        phi0 = math.atan2(rel[1], rel[0]) if np.linalg.norm(rel) > 1e-9 else 0.0
        phi = phi0 + m.angular_speed * t
        pos = np.array(
            [m.center[0] + m.radius * math.cos(phi), m.center[1] + m.radius * math.sin(phi), m.center[2]]
        )
        vel = m.radius * m.angular_speed * np.array([-math.sin(phi), math.cos(phi), 0.0])
        return pos, vel
    pts, cum = _waypoint_path(o)
    total = cum[-1]
    if total <= 0:
        return pts[0].copy(), np.zeros(3)
    s = m.speed * t
    if m.loop:
        s = s % total
    elif s >= total:
        return pts[-1].copy(), np.zeros(3)
    k = int(np.searchsorted(cum, s, side="right") - 1)
    k = min(k, len(pts) - 2)
    seg = pts[k + 1] - pts[k]
    length = cum[k + 1] - cum[k]
    u = (s - cum[k]) / length
    return pts[k] + u * seg, seg / length * m.speed


def max_speed(o: Obstacle) -> float:
    """Highest speed obstacle ``o`` ever moves at (0 for static ones)."""
    m = o.motion
    if m is None:
        return 0.0
    if m.type == "linear":
        return float(np.linalg.norm(m.velocity))
    if m.type == "circle":
        return abs(m.radius * m.angular_speed)
    return float(m.speed)


def poses_at(obstacles: tuple[Obstacle, ...] | list[Obstacle], t: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions (M, 3) and velocities (M, 3) of ``obstacles`` at time ``t``."""
    if not obstacles:
        return np.zeros((0, 3)), np.zeros((0, 3))
    linear = _linear_rows(obstacles)
    if linear is None:
        pv = [pose_at(o, t) for o in obstacles]
        return np.array([p for p, _ in pv]), np.array([v for _, v in pv])
    # Every obstacle moves linearly: position + velocity * t for all at once (the same
    # arithmetic per element as pose_at).
    start, velocity = linear
    return start + velocity * t, velocity.copy()


_LINEAR: dict[int, tuple[object, tuple[np.ndarray, np.ndarray] | None]] = {}


def _linear_rows(obstacles: tuple[Obstacle, ...] | list[Obstacle]) -> tuple[np.ndarray, np.ndarray] | None:
    """Stacked start positions and velocities when every obstacle of ``obstacles`` moves
    linearly (cached per sequence object), else None."""
    hit = _LINEAR.get(id(obstacles))
    if hit is not None and hit[0] is obstacles:
        return hit[1]
    rows = None
    if isinstance(obstacles, tuple) and all(
        o.motion is not None and o.motion.type == "linear" for o in obstacles
    ):
        rows = (
            np.array([o.position for o in obstacles], dtype=float),
            np.array([o.motion.velocity for o in obstacles], dtype=float),
        )
        rows[0].flags.writeable = rows[1].flags.writeable = False
    if isinstance(obstacles, tuple):  # a list may change under us: not cached
        if len(_LINEAR) >= _CACHE_SIZE:
            _LINEAR.clear()
        _LINEAR[id(obstacles)] = (obstacles, rows)
    return rows


def parks_at(o: Obstacle) -> float | None:
    """When moving obstacle ``o`` comes to rest for good (waypoints without ``loop``: at its last
    waypoint), else None."""
    m = o.motion
    if m is None or m.type != "waypoints" or m.loop or m.speed <= 0:
        return None
    pts = np.vstack([o.position, *m.waypoints])
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) / float(m.speed)


def resting_bodies(world: World, t: float) -> tuple[Obstacle, ...]:
    """The obstacles at rest for good at time ``t``: the static ones and the movers parked by
    then (as static bodies at their last waypoint)."""
    out = list(world.static_obstacles)
    for o in world.moving_obstacles:
        park = parks_at(o)
        if park is not None and park <= t:
            out.append(
                dataclasses.replace(o, position=np.asarray(o.motion.waypoints[-1], dtype=float), motion=None)
            )
    return tuple(out)


def next_rest(world: World, t: float) -> float:
    """The first time after ``t`` at which a mover comes to rest for good (inf when none does)."""
    times = [p for p in (parks_at(o) for o in world.moving_obstacles) if p is not None and p > t]
    return min(times, default=math.inf)
