"""Polylines: lengths, turn and climb angles, curvature, resampling, arc fillets. Batched functions take
``(n, K, 3)`` arrays (n polylines of K points); the others one ``(K, 3)`` polyline."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

_EPS = 1e-9


def polyline_length(P: np.ndarray) -> np.ndarray:
    """Length of each polyline (n, K, 3) → (n,) (004 eq 3, 002 eq 4)."""
    return np.linalg.norm(np.diff(P, axis=1), axis=-1).sum(axis=1)


def turn_angles(P: np.ndarray) -> np.ndarray:
    """Angle (rad) between consecutive segments at every interior node → (n, K-2); 0 for zero-length."""
    d = np.diff(P, axis=1)
    a, b = d[:, :-1], d[:, 1:]
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    c = np.sum(a * b, axis=-1) / np.maximum(na * nb, 1e-12)
    ang = np.arccos(np.clip(c, -1.0, 1.0))
    return np.where((na > 1e-9) & (nb > 1e-9), ang, 0.0)


def horizontal_turn_angles(P: np.ndarray) -> np.ndarray:
    """Heading change (rad) at interior nodes in the horizontal plane (002 eq 10) → (n, K-2)."""
    return turn_angles(np.concatenate([P[..., :2], np.zeros_like(P[..., :1])], axis=-1))


def climb_angles(P: np.ndarray) -> np.ndarray:
    """Flight-path angle (rad) of every segment, signed (002 eq 11) → (n, K-1)."""
    d = np.diff(P, axis=1)
    return np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))


def resample_uniform(P: np.ndarray, count: int) -> np.ndarray:
    """``count`` points evenly spaced in arc length along each polyline of ``P`` (n, K, 3).

    Each row is resampled on its own (the result for a path never depends on the rest of
    the batch, so a cost is the same whether a candidate is scored alone or in a population).
    """
    seg = np.linalg.norm(np.diff(P, axis=1), axis=-1)  # (n, K-1)
    cum = np.concatenate([np.zeros((len(P), 1)), np.cumsum(seg, axis=1)], axis=1)  # (n, K)
    q = np.linspace(0.0, 1.0, count)[None, :] * cum[:, -1:]  # (n, count)
    j = np.clip((cum[:, None, 1:-1] <= q[:, :, None]).sum(axis=-1), 0, P.shape[1] - 2)  # segment
    c0 = np.take_along_axis(cum, j, axis=1)
    sl = np.take_along_axis(seg, j, axis=1)
    u = np.clip((q - c0) / np.maximum(sl, 1e-12), 0.0, 1.0)[..., None]
    a = np.take_along_axis(P, j[..., None], axis=1)
    b = np.take_along_axis(P, j[..., None] + 1, axis=1)
    return a + u * (b - a)


def resample_route(path: np.ndarray, spacing: float) -> np.ndarray:
    """Points along one polyline (K, 3) every ``spacing`` metres of arc length, ending at its end."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 1e-12:
        return path[-1:].copy()
    count = max(1, int(np.ceil(s[-1] / max(spacing, 1e-9))))
    q = np.linspace(0.0, s[-1], count + 1)
    return np.stack([np.interp(q, s, path[:, k]) for k in range(3)], axis=1)


def path_curvature(points: np.ndarray, min_step: float = 1e-3) -> np.ndarray:
    """Discrete curvature (1/m) at the interior vertices of a polyline: turning angle / mean step.

    Steps shorter than ``min_step`` are dropped first (hovering, arrival) so noise cannot
    produce huge curvatures.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) < 3:
        return np.zeros(0)
    d = np.diff(pts, axis=0)
    n = np.linalg.norm(d, axis=1)
    keep = n > min_step
    d, n = d[keep], n[keep]
    if len(d) < 2:
        return np.zeros(0)
    u = d / n[:, None]
    cosang = np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0)
    return np.arccos(cosang) / (0.5 * (n[1:] + n[:-1]))


def fillet_corner(
    a: np.ndarray, v: np.ndarray, b: np.ndarray, rho: float, max_step_deg: float = 10.0
) -> np.ndarray | None:
    """Arc of radius ``rho`` replacing corner ``v`` of a → v → b (paper 004 §6), tangent to both legs.

    Returns the arc's points from the tangent point on a–v to the one on v–b, spaced at most
    ``max_step_deg`` apart (dense enough for a waypoint follower to fly the arc, not its chord),
    or None when the legs are straight or reversed (a cusp has no arc), or when the tangent
    length ``rho·tan(θ/2)`` exceeds half of either leg (the neighbouring corner needs the other
    half): 004's "special broken point", where the vehicle stops and turns.
    """
    d1 = v - a
    d2 = b - v
    l1, l2 = float(np.linalg.norm(d1)), float(np.linalg.norm(d2))
    if l1 < _EPS or l2 < _EPS or rho <= 0.0:
        return None
    d1, d2 = d1 / l1, d2 / l2
    theta = math.acos(float(np.clip(np.dot(d1, d2), -1.0, 1.0)))  # deflection angle
    if theta < 1e-6 or theta > math.pi - 1e-6:
        return None
    tangent = rho * math.tan(theta / 2)
    if tangent > min(l1, l2) / 2 + 1e-12:
        return None
    p1 = v - d1 * tangent
    p2 = v + d2 * tangent
    bis = d2 - d1
    center = v + bis / np.linalg.norm(bis) * (rho / math.cos(theta / 2))
    u1 = (p1 - center) / rho
    u2 = (p2 - center) / rho
    # Slerp from u1 to u2 (the arc subtends theta, the deflection angle).
    n = max(1, math.ceil(math.degrees(theta) / max_step_deg - 1e-9))
    s = np.linspace(0.0, 1.0, n + 1)[:, None]
    arc = (np.sin((1 - s) * theta) * u1 + np.sin(s * theta) * u2) / math.sin(theta)
    return center + rho * arc


@dataclass(frozen=True)
class Fillet:
    """A filleted polyline: its points, and how many corners got an arc or stayed broken."""

    points: np.ndarray
    arcs: int
    broken: int


def fillet_path(
    waypoints: np.ndarray,
    rho: float,
    collision_check: Callable[[np.ndarray], bool] | None = None,
    max_step_deg: float = 10.0,
) -> Fillet:
    """Polyline with every corner replaced by an arc of radius ``rho`` (paper 004 §6, eq 34:
    ρ = v²/a for a multirotor; a fixed wing's minimum turn radius).

    ``collision_check(points)`` returns True when the polyline ``points`` (the corner's
    tangent point, the arc, the other tangent point) collides; such corners, and those whose
    arc does not fit (:func:`fillet_corner`), keep the sharp corner (004's "special broken
    points"). Straight (collinear) vertices are kept as they are and not counted. Endpoints
    are kept exactly.
    """
    P = np.asarray(waypoints, dtype=float)
    if len(P) < 3:
        return Fillet(P.copy(), 0, 0)
    out = [P[:1]]
    arcs = broken = 0
    for k in range(1, len(P) - 1):
        d1, d2 = P[k] - P[k - 1], P[k + 1] - P[k]
        n1, n2 = float(np.linalg.norm(d1)), float(np.linalg.norm(d2))
        straight = n1 < _EPS or n2 < _EPS or float(np.dot(d1, d2)) >= n1 * n2 * (1.0 - 1e-12)
        arc = None if straight else fillet_corner(P[k - 1], P[k], P[k + 1], rho, max_step_deg)
        if arc is not None and collision_check is not None and collision_check(arc):
            arc = None
        if arc is None:
            out.append(P[k : k + 1])
            broken += not straight
        else:
            out.append(arc)
            arcs += 1
    out.append(P[-1:])
    return Fillet(np.concatenate(out), arcs, broken)


def densify(path: np.ndarray, spacing: float) -> np.ndarray:
    """``path`` (K, 3) with every leg longer than ``spacing`` split evenly; all vertices kept
    (unlike :func:`resample_route`, arcs and broken corners stay exactly where they are)."""
    P = np.asarray(path, dtype=float)
    if len(P) < 2:
        return P.copy()
    out = [P[:1]]
    for a, b in zip(P[:-1], P[1:], strict=True):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / max(spacing, 1e-9) - 1e-9))
        s = np.arange(1, n + 1)[:, None] / n
        out.append(a + s * (b - a))
    return np.concatenate(out)


CUSP_ANGLE_DEG = 150.0


def curvature_with_cusps(
    points: np.ndarray,
    min_step: float = 1e-3,
    cusp_angle_deg: float = CUSP_ANGLE_DEG,
    with_steps: bool = False,
) -> tuple[np.ndarray, ...]:
    """(curvature, cusp mask) at the interior vertices of a flown path.

    Points closer than ``min_step`` to the last kept one are dropped first (hovering, a stop),
    so a stop-and-reverse shows as two consecutive steps in opposite directions. Curvature is
    the turning angle over the mean length of the two steps; a vertex turning by more than
    ``cusp_angle_deg`` is a **cusp** (stop and reverse: no circle of any radius passes there,
    its "curvature" is only 1/step length), and so is a vertex where the agent stood still for
    a step or more (points dropped after it) and then left in another direction: a stop and
    turn, where the velocity passed through zero and no turn radius applies. Report cusps as
    a count and the max curvature over the other vertices (``curv[~cusp]``). With
    ``with_steps``, also the mean length of the two steps at each vertex (the curvature's
    denominator) and the vertex's *pace*: the two steps' mean speed over the one of steps that
    each took a single sampling interval, divided by the intervals the turn took (each step
    spans as many intervals as points were dropped in it, plus one); 1 where no point was
    dropped, below 1 for a slow agent whose short steps were merged.
    """
    pts = np.asarray(points, dtype=float)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 3:
        return _no_vertices(with_steps)
    keep = [0]
    for k in range(1, len(pts)):
        if np.linalg.norm(pts[k] - pts[keep[-1]]) >= min_step:
            keep.append(k)
    return _vertex_curvature(pts[keep], np.asarray(keep), cusp_angle_deg, with_steps)


def _no_vertices(with_steps: bool) -> tuple[np.ndarray, ...]:
    return (np.zeros(0), np.zeros(0, dtype=bool)) + ((np.zeros(0), np.zeros(0)) if with_steps else ())


def _vertex_curvature(
    p: np.ndarray, kept: np.ndarray, cusp_angle_deg: float, with_steps: bool
) -> tuple[np.ndarray, ...]:
    """:func:`curvature_with_cusps` of the kept points ``p`` (their indices ``kept``)."""
    if len(p) < 3:
        return _no_vertices(with_steps)
    a, b = p[1:-1] - p[:-2], p[2:] - p[1:-1]
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", a, b) / (la * lb), -1.0, 1.0))
    mean = 0.5 * (la + lb)
    gaps = np.diff(kept)
    stopped = (gaps[1:] > 1) & (angle > 1e-9)
    out = (angle / mean, (angle > math.radians(cusp_angle_deg)) | stopped)
    if not with_steps:
        return out
    # A step over k sampling intervals (slow points dropped) is flown at its length over k
    # intervals, and its turn takes the two steps' mean number of intervals: 1 when neither
    # dropped a point.
    k1, k2 = gaps[:-1], gaps[1:]
    pace = (la / k1 + lb / k2) / (la + lb) / (0.5 * (k1 + k2))
    return out + (mean, pace)


def curvatures_with_cusps(
    paths: np.ndarray, min_step: float = 1e-3, cusp_angle_deg: float = CUSP_ANGLE_DEG
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`curvature_with_cusps` (``with_steps``) of every path of ``paths`` (T, N, 3): per
    path (the second axis) its (curvature, cusp mask, mean step, pace), the same arrays.

    The points to keep are chosen for all paths at once, step by step (a point is kept when it
    lies ``min_step`` or more from its path's last kept one); a distance within rounding of
    ``min_step`` is measured again as the one-path loop measures it, so every choice is its."""
    P = np.asarray(paths, dtype=float)
    if P.ndim != 3 or P.shape[2] != 3:
        raise ValueError(f"paths: expected an array (T, N, 3), got shape {P.shape}")
    steps, n = P.shape[:2]
    finite = np.isfinite(P).all(axis=(0, 2))
    keep = np.zeros((steps, n), dtype=bool)
    if steps:
        keep[0] = True
        last = P[0].copy()
        for k in range(1, steps):
            diff = P[k] - last
            d = np.sqrt(np.einsum("ij,ij->i", diff, diff))
            take = d >= min_step
            for i in np.flatnonzero(np.abs(d - min_step) <= 1e-9 * min_step).tolist():
                take[i] = np.linalg.norm(P[k, i] - last[i]) >= min_step
            keep[k] = take
            last[take] = P[k, take]
    out = []
    for i in range(n):
        if not finite[i]:  # rows with a non-finite value are dropped first: the one-path way
            out.append(curvature_with_cusps(P[:, i], min_step, cusp_angle_deg, with_steps=True))
            continue
        kept = np.flatnonzero(keep[:, i])
        out.append(_vertex_curvature(P[kept, i], kept, cusp_angle_deg, True))
    return out


def turn_then_straight(
    start: np.ndarray, heading: np.ndarray, target: np.ndarray, rho: float, max_step_deg: float = 10.0
) -> tuple[np.ndarray, np.ndarray]:
    """The shorter Dubins "turn, then straight" path in the horizontal plane from ``start`` (3,)
    flying ``heading`` (3,) to ``target`` (3,): an arc of radius ``rho`` to the left or right,
    then the tangent line to the target. Height changes linearly with the distance flown.

    Returns the path's points after ``start`` (arc points at most ``max_step_deg`` apart, the
    tangent point, the target) and the unit heading on arrival. The two turning circles touch
    at ``start``, so the target lies outside at least one of them: such a path always exists.
    """
    p, q = np.asarray(start, float), np.asarray(target, float)
    h = np.array([heading[0], heading[1]], float)
    nh = float(np.hypot(h[0], h[1]))
    d_xy = q[:2] - p[:2]
    if nh < _EPS:
        nd = float(np.hypot(*d_xy))
        h = d_xy / nd if nd > _EPS else np.array([1.0, 0.0])
    else:
        h = h / nh
    left = np.array([-h[1], h[0]])
    best = None
    for side in (1.0, -1.0):
        c = p[:2] + side * rho * left
        d = q[:2] - c
        dist = float(np.hypot(d[0], d[1]))
        if dist < rho * (1.0 + 1e-9):
            continue
        alpha = math.acos(rho / dist)
        theta_t = math.atan2(d[1], d[0]) - side * alpha
        theta0 = math.atan2(p[1] - c[1], p[0] - c[0])
        sweep = ((theta_t - theta0) * side) % (2.0 * math.pi)
        if sweep > 2.0 * math.pi - 1e-9:
            sweep = 0.0
        length = rho * sweep + math.sqrt(max(dist**2 - rho**2, 0.0))
        if best is None or length < best[0]:
            best = (length, side, c, theta0, sweep)
    if best is None:  # degenerate (target on the start): go straight there
        u = q - p
        n = float(np.linalg.norm(u[:2]))
        return q[None].copy(), np.array([*(u[:2] / n if n > _EPS else h), 0.0])
    length, side, c, theta0, sweep = best
    n = max(1, math.ceil(math.degrees(sweep) / max_step_deg - 1e-9)) if sweep > 1e-9 else 0
    ang = theta0 + side * sweep * np.arange(1, n + 1) / max(n, 1)
    arc = np.stack([c[0] + rho * np.cos(ang), c[1] + rho * np.sin(ang)], axis=1) if n else np.zeros((0, 2))
    pts_xy = np.vstack([arc, q[None, :2]])
    flown = np.concatenate([rho * sweep * np.arange(1, n + 1) / max(n, 1), [length]])
    z = p[2] + (q[2] - p[2]) * flown / max(length, _EPS)
    pts = np.column_stack([pts_xy, z])
    pts[-1] = q
    last = pts[-2, :2] if n else p[:2]
    out_dir = q[:2] - last
    nd = float(np.hypot(*out_dir))
    if nd < _EPS:  # the target is the tangent point: heading along the circle there
        a = theta0 + side * sweep
        out_dir = side * np.array([-math.sin(a), math.cos(a)])
        nd = 1.0
    return pts, np.array([out_dir[0] / nd, out_dir[1] / nd, 0.0])


def dubins_chain(
    start: np.ndarray,
    heading: np.ndarray,
    waypoints: np.ndarray,
    rho: float,
    max_step_deg: float = 10.0,
) -> np.ndarray:
    """A path through ``waypoints`` (K, 3) that a vehicle at ``start`` flying ``heading``, with
    turn radius ``rho``, can fly: from each pose a :func:`turn_then_straight` to the next
    waypoint, arriving with the heading of its straight leg. Curvature <= 1 / rho everywhere
    in the horizontal plane and the heading is continuous. Returns ``start`` then the points."""
    out = [np.asarray(start, float)[None]]
    p, h = np.asarray(start, float), np.asarray(heading, float)
    for q in np.asarray(waypoints, float):
        if float(np.linalg.norm(q - p)) < _EPS:
            continue
        pts, h = turn_then_straight(p, h, q, rho, max_step_deg)
        out.append(pts)
        p = q
    return np.concatenate(out)
