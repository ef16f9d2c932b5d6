"""Threat cores a world keeps local flight out of (``threats[i].avoid``: the ball of radius
``r_min`` about the threat's position) as obstacles for the planners' segment pruning: a
shortcut, an arc or a chain that replaces part of a planned segment may not cut through one.

The test is exact geometry: a straight leg ``a -> b`` of an agent of radius ``r`` enters a core
when its closest point comes nearer the centre than ``r_min + r``. A leg that starts already that
close (an agent beside a core) enters it only when it gets closer than where it starts."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from swarmplan.geometry.collision import point_segment_distance

if TYPE_CHECKING:
    from swarmplan.core import PlanningContext
    from swarmplan.world.model import World


def avoided_cores(world: World) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]] | None:
    """(centres (K, 3), radii (K,), names ``threats[i]``) of the avoided cores, or None."""
    rows = [(i, t) for i, t in enumerate(world.threats) if t.avoid and t.r_min > 0]
    if not rows:
        return None
    centres = np.array([t.position for _, t in rows], dtype=float)
    radii = np.array([t.r_min for _, t in rows], dtype=float)
    return centres, radii, tuple(f"threats[{i}]" for i, _ in rows)


def core_hit(world: World, a: np.ndarray, b: np.ndarray, radius: float) -> str | None:
    """The avoided core (``threats[i]``) the leg ``a -> b`` of a body of ``radius`` enters, else None."""
    cores = avoided_cores(world)
    if cores is None:
        return None
    centres, radii, names = cores
    a = np.asarray(a, dtype=float).reshape(1, 3)
    b = np.asarray(b, dtype=float).reshape(1, 3)
    closest = point_segment_distance(centres, a, b)[0]
    start = np.linalg.norm(centres - a[0], axis=1)
    enters = closest < np.minimum(radii + radius, start - 1e-9)
    k = np.flatnonzero(enters)
    return names[int(k[0])] if len(k) else None


def polyline_core_hit(world: World, points: np.ndarray, radius: float) -> str | None:
    """The first avoided core a leg of the polyline ``points`` enters (see :func:`core_hit`)."""
    if avoided_cores(world) is None:
        return None
    for a, b in zip(points[:-1], points[1:], strict=True):
        hit = core_hit(world, a, b, radius)
        if hit:
            return hit
    return None


def static_leg_hit(sim: PlanningContext, a: np.ndarray, b: np.ndarray, radius: float) -> str | None:
    """What the leg ``a -> b`` of a body of ``radius`` touches among the things that stay put:
    the terrain or ground, a static obstacle (FCL) or an avoided threat core; else None."""
    col = sim.collision
    return (
        col.sweep_terrain(a, b, radius) or col.sweep_static(a, b, radius) or core_hit(sim.world, a, b, radius)
    )
