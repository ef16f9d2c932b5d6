"""Polylines: lengths, turn and climb angles, curvature, resampling. Batched functions take
``(n, K, 3)`` arrays (n polylines of K points); the others one ``(K, 3)`` polyline."""

from __future__ import annotations

import numpy as np


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
