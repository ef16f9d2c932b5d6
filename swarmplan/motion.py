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

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from swarmplan.world.model import Motion, Obstacle


def _waypoint_path(o: Obstacle) -> tuple[np.ndarray, np.ndarray]:
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
    pv = [pose_at(o, t) for o in obstacles]
    return np.array([p for p, _ in pv]), np.array([v for _, v in pv])
