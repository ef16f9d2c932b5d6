"""Holding patterns: where an agent waits when no escape can be planned, before trying again.

A multirotor hovers where it is (its potential field still pushes it away from moving
obstacles and other agents while it waits). A fixed wing cannot hover: it flies a loiter
circle, tangent to its current heading so it can enter it at once, of radius at least its
minimum turn radius, on whichever side (and at the smallest radius of 1.2, 1.6, 2.4 x R_min)
the swept check finds clear of static obstacles, terrain and the bounds; the circle's points
are spaced at most 10 degrees apart. None fits where it is: it flies towards the nearest free
volume (:func:`free_volume_waypoints`: a turn at its minimum radius, then straight, to the
clearest of the points around it at the distance of a loiter's diameter), holds there and
plans again; a fixed wing never gives up in the air.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from swarmplan.geometry.polyline import dubins_chain

LOITER_FACTORS = (1.2, 1.6, 2.4)
"""Loiter radii tried, in multiples of the minimum turn radius."""

FREE_HEADINGS = 16
"""Headings (evenly spaced) of the points a fixed wing looks at for free volume."""

FREE_CLIMBS = (0.0, 0.5, -0.5)
"""Flight-path angles of those points, in fractions of the climb limit (level first)."""


def loiter_circle(position: np.ndarray, velocity: np.ndarray, radius: float, side: float) -> np.ndarray:
    """One full level circle of ``radius`` through ``position``, tangent to the horizontal part
    of ``velocity``, turning left (``side`` = 1) or right (-1): its points after ``position``,
    ending back at it."""
    h = np.array([velocity[0], velocity[1]], float)
    n = float(np.hypot(*h))
    h = h / n if n > 1e-9 else np.array([1.0, 0.0])
    left = np.array([-h[1], h[0]])
    c = position[:2] + side * radius * left
    theta0 = math.atan2(position[1] - c[1], position[0] - c[0])
    k = 36
    ang = theta0 + side * 2.0 * math.pi * np.arange(1, k + 1) / k
    pts = np.column_stack([c[0] + radius * np.cos(ang), c[1] + radius * np.sin(ang), np.full(k, position[2])])
    pts[-1] = position
    return pts


def hold_waypoints(
    position: np.ndarray,
    velocity: np.ndarray,
    fixed_wing: bool,
    min_turn_radius: float,
    blocked: Callable[[np.ndarray], bool],
) -> np.ndarray | None:
    """Waypoints (after ``position``) of the agent's holding pattern, or None when every
    candidate is ``blocked`` (``blocked(polyline from position)``)."""
    p = np.asarray(position, float)
    if not fixed_wing:
        return p[None].copy()
    for factor in LOITER_FACTORS:
        for side in (1.0, -1.0):
            pts = loiter_circle(p, velocity, factor * min_turn_radius, side)
            if not blocked(np.vstack([p[None], pts])):
                return pts
    return None


def free_volume_waypoints(
    position: np.ndarray,
    velocity: np.ndarray,
    min_turn_radius: float,
    climb_limit: float,
    clearance: Callable[[np.ndarray], np.ndarray],
    blocked: Callable[[np.ndarray], bool],
) -> np.ndarray | None:
    """A fixed wing's way (points after ``position``) towards the nearest free volume: of the
    points at the distance of the widest loiter's diameter around it (``FREE_HEADINGS``
    headings, ``FREE_CLIMBS`` flight-path angles), the one of largest ``clearance(points)``
    whose Dubins path (turn at ``min_turn_radius``, then straight) is not ``blocked``; at half
    and a quarter of that distance when none is. None when no such path is free."""
    p = np.asarray(position, float)
    v = np.asarray(velocity, float)
    psi = np.arange(FREE_HEADINGS) * (2.0 * math.pi / FREE_HEADINGS)
    for scale in (1.0, 0.5, 0.25):
        reach = 2.0 * LOITER_FACTORS[-1] * min_turn_radius * scale
        pts = []
        for f in FREE_CLIMBS:
            g = f * climb_limit
            c = math.cos(g)
            u = np.column_stack([c * np.cos(psi), c * np.sin(psi), np.full(len(psi), math.sin(g))])
            pts.append(p + reach * u)
        pts = np.concatenate(pts)
        clear = clearance(pts)
        for k in np.argsort(-clear, kind="stable").tolist():
            if clear[k] <= 0.0:
                break
            way = dubins_chain(p, v, pts[k][None], min_turn_radius)
            if not blocked(way):
                return way[1:]
    return None


def holding_pattern(
    position: np.ndarray,
    velocity: np.ndarray,
    fixed_wing: bool,
    min_turn_radius: float,
    climb_limit: float,
    clearance: Callable[[np.ndarray], np.ndarray],
    blocked: Callable[[np.ndarray], bool],
) -> tuple[np.ndarray | None, bool]:
    """:func:`hold_waypoints`, or for a fixed wing with no free circle
    :func:`free_volume_waypoints`; and whether the latter answered."""
    pts = hold_waypoints(position, velocity, fixed_wing, min_turn_radius, blocked)
    if pts is not None:
        return pts, False
    pts = free_volume_waypoints(position, velocity, min_turn_radius, climb_limit, clearance, blocked)
    return pts, pts is not None
