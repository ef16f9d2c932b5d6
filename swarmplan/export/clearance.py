"""How far points of the swarm's paths are from what they must not touch: every body of the log's
world (its surface; moving bodies at their recorded poses at the points' times) and the ground
or terrain (the height above it). ``--check`` counts contacts with these distances, and the
waypoint reduction of a mission bounds each leg's deviation with them (:func:`leg_allowance`).

The body distances are the replay's shape distances (``swarmplan.replay.metrics``): exact
outside every primitive, exact minima for meshes and lower bounds elsewhere, so every distance
here is at most the true one. A distance to a surface changes by at most the distance moved
(it is 1-Lipschitz); the height above a terrain of slopes up to G changes by at most
sqrt(1 + G^2) times the distance moved, G bounded over the terrain's Gaussian peaks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from swarmplan.replay import Recording
from swarmplan.replay.geometry import terrain_height
from swarmplan.replay.metrics import obstacle_distances


def body_distances(
    rec: Recording, ids: list[str], times: np.ndarray, pos: np.ndarray, radii: np.ndarray
) -> dict[str, np.ndarray]:
    """Signed distance (A, T) from each point ``pos`` (A, T, 3) at ``times`` (T,) to every body
    surface of the log's world, by body id (moving bodies where the log recorded them)."""
    shadow = Recording(
        file=rec.file,
        world=rec.world,
        times=np.asarray(times, float),
        agent_ids=list(ids),
        positions=pos,
        velocities=np.full_like(pos, np.nan),
        modes=np.full(pos.shape[:2], "apf"),
        goals=pos[:, -1].copy(),
        radii=np.asarray(radii, float),
        obstacle_tracks=rec.obstacle_tracks,
    )
    return obstacle_distances(shadow)


def heights(world: dict[str, Any], pos: np.ndarray) -> np.ndarray:
    """Height of points ``pos`` (..., 3) above the ground or terrain under them (...)."""
    p = np.asarray(pos, float)
    return p[..., 2] - terrain_height(world, p[..., :2].reshape(-1, 2)).reshape(p.shape[:-1])


def terrain_slope(world: dict[str, Any]) -> float:
    """An upper bound of the terrain's slope: a Gaussian peak of height H and spread s rises at
    most H sqrt(2 / e) / s, and the slopes of the peaks add up at most."""
    g = 0.0
    for pk in (world.get("terrain") or {}).get("peaks") or []:
        spread = min(abs(float(v)) for v in (pk.get("spread") or [1, 1])[:2])
        g += abs(float(pk["height"])) * math.sqrt(2.0 / math.e) / max(spread, 1e-12)
    return g


def densify_path(
    times: np.ndarray, pos: np.ndarray, spacing: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along the polyline ``pos`` (K, 3) at most ``spacing`` apart (every recorded one
    among them), with their times (linear in each segment) and the segment each begins or lies
    on (the last point on segment K - 2)."""
    seg = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    n = np.maximum(1, np.ceil(seg / max(spacing, 1e-12)).astype(int))  # sub-steps per segment
    k = np.repeat(np.arange(len(seg)), n)
    u = np.concatenate([np.arange(m) / m for m in n])
    k = np.append(k, len(seg) - 1)
    u = np.append(u, 1.0)
    p = pos[k] + u[:, None] * (pos[k + 1] - pos[k])
    t = times[k] + u * (times[k + 1] - times[k])
    return t, p, k


def leg_allowance(
    rec: Recording, agent_id: str, times: np.ndarray, pos: np.ndarray, radius: float, margin: float
) -> np.ndarray:
    """For each segment of a flown path (``times`` (K,), ``pos`` (K, 3)): how far a straight leg
    spanning it may lie from the path and keep ``radius + margin`` from every body (K - 1,),
    never below 0: a point of a leg within D of a point p of the path is at least d(p) - D from
    a body (d is 1-Lipschitz). The path is sampled at most ``radius / 2`` apart along each
    segment, so every point of it lies within ``radius / 4`` of a sample; a segment allows the
    least d - radius - margin of its samples (and its end) less that quarter radius."""
    spacing = _spacing(pos, radius)
    t, p, seg = densify_path(times, pos, spacing)
    free = np.full(len(p), np.inf)
    for d in body_distances(rec, [agent_id], t, p[None], np.array([radius])).values():
        free = np.minimum(free, np.where(np.isfinite(d[0]), d[0], np.inf) - (radius + margin))
    return np.maximum(_per_segment(free, seg, len(pos) - 1) - 0.5 * spacing, 0.0)


TERRAIN_TOLERANCE = 0.01
"""Of the agent's radius: how far below its samples' heights a leg over terrain may dip between them."""


def terrain_test(
    world: dict[str, Any], pos: np.ndarray, radius: float, margin: float
) -> Callable[[int, int], bool] | None:
    """A test of a straight leg from ``pos[a]`` to ``pos[b]`` over terrain: it keeps the height
    ``radius + margin``, or where the path between flew lower, the lowest height it flew there
    (the path's points at most ``radius / 2`` apart). The leg is sampled ``2 t radius / L``
    apart (t = TERRAIN_TOLERANCE, L = sqrt(1 + G^2), G the slope bound), so between its samples
    it is at most ``t radius`` lower than they are. None on flat ground: there a leg is never
    lower than its lower end."""
    slope = terrain_slope(world)
    if slope == 0.0:
        return None
    spacing = _spacing(pos, radius)
    _, p, seg = densify_path(np.zeros(len(pos)), pos, spacing)
    low = _per_segment(heights(world, p), seg, len(pos) - 1)
    keep = radius + margin
    step = 4.0 * TERRAIN_TOLERANCE * spacing / math.sqrt(1.0 + slope**2)  # 2 t radius / L

    def fits(a: int, b: int) -> bool:
        target = min(keep, float(low[a:b].min()))
        n = int(np.ceil(np.linalg.norm(pos[b] - pos[a]) / step)) + 1
        chord = pos[a] + np.linspace(0.0, 1.0, n)[:, None] * (pos[b] - pos[a])
        return bool(heights(world, chord).min() >= target)

    return fits


def _spacing(pos: np.ndarray, radius: float) -> float:
    """Half the agent's radius (a thousandth of the path's extent for a point agent)."""
    return max(0.5 * radius if radius > 0 else float(np.linalg.norm(np.ptp(pos, axis=0))) / 1000.0, 1e-6)


def _per_segment(values: np.ndarray, seg: np.ndarray, n: int) -> np.ndarray:
    """The least of ``values`` of the points on each of ``n`` segments and at its end."""
    out = np.full(n, np.inf)
    np.minimum.at(out, seg, values)
    starts = np.flatnonzero(np.diff(seg) > 0) + 1  # each segment's end is the next one's start
    np.minimum.at(out, seg[starts] - 1, values[starts])
    return out
