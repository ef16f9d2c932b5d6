"""The terrain of world-format: a sum of Gaussian peaks, z(x, y) = sum h exp(-u^2 - v^2)
with u = (x - cx) / sx, v = (y - cy) / sy. The one place the formula is written."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def height(peaks: Sequence[Any], xy: np.ndarray) -> np.ndarray:
    """Terrain height at ``xy`` (..., 2) for ``peaks`` (objects with center, height, spread)."""
    xy = np.asarray(xy, dtype=float)
    z = np.zeros(xy.shape[:-1])
    for pk in peaks:
        u = (xy[..., 0] - pk.center[0]) / pk.spread[0]
        v = (xy[..., 1] - pk.center[1]) / pk.spread[1]
        z = z + pk.height * np.exp(-(u * u) - v * v)
    return z


def gradient(peaks: Sequence[Any], xy: np.ndarray) -> np.ndarray:
    """(dz/dx, dz/dy) of the terrain at ``xy`` (..., 2)."""
    xy = np.asarray(xy, dtype=float)
    g = np.zeros(xy.shape)
    for pk in peaks:
        u = (xy[..., 0] - pk.center[0]) / pk.spread[0]
        v = (xy[..., 1] - pk.center[1]) / pk.spread[1]
        e = pk.height * np.exp(-(u * u) - v * v)
        g[..., 0] += -2 * u / pk.spread[0] * e
        g[..., 1] += -2 * v / pk.spread[1] * e
    return g
