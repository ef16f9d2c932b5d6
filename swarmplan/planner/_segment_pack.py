"""Per-escape constants of :class:`~swarmplan.planner.segment_cost.SegmentCost` as flat arrays
for the compiled kernel (``_segment_kernel``): bodies by shape code, intents padded."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from swarmplan.geometry.bodies import body_table, code_of


def analytic(obstacles: Sequence) -> bool:
    """Whether every obstacle has a shape the kernel measures exactly (no mesh)."""
    return all(code_of(o.shape) >= 0 for o in obstacles)


def pack_bodies(obstacles: Sequence) -> dict[str, np.ndarray]:
    """Shape code, centre, rotation (local = (p - centre) @ rotation, as ``ShapeBatch``),
    identity flag, kernel parameters and bounding radius of each obstacle (all of them
    analytic): their rows of ``bodies.body_table``."""
    t = body_table(obstacles)
    return {
        "code": t.code,
        "pos": t.position,
        "rot": t.rotation,
        "ident": t.identity,
        "prm": t.prm,
        "bound": t.bound,
    }


def pack_intents(intents: Sequence, radius: float) -> dict[str, np.ndarray]:
    """Per-escape constants of the other-agents term: the intents as padded arrays (knots
    repeated past each one's end), their ellipsoid scales, contact and reach distances and
    largest speeds (``inf`` where two knots share a time)."""
    m = max((len(it.times) for it in intents), default=1)
    M = len(intents)
    times = np.zeros((M, m))
    points = np.zeros((M, m, 3))
    for j, it in enumerate(intents):
        k = len(it.times)
        times[j, :k], times[j, k:] = it.times, it.times[-1]
        points[j, :k], points[j, k:] = it.points, it.points[-1]
    # Largest speed of each: the padding adds zero moves in zero time; a move in zero time
    # (two knots at one time) has no speed bound. A little above: it bounds moves in a time.
    dt = np.diff(times, axis=1)
    dp = np.sqrt((np.diff(points, axis=1) ** 2).sum(-1))
    moving = dt > 0
    v = np.where(moving, dp / np.where(moving, dt, 1.0), np.where(dp > 0, np.inf, 0.0))
    vmax = v.max(axis=1, initial=0.0) * (1 + 1e-9)
    scale = np.array([np.asarray(it.separation, dtype=float) + radius + it.radius for it in intents]).reshape(
        M, 3
    )
    contact = np.array([radius + it.radius for it in intents], dtype=float)
    # Beyond this distance both terms vanish: the ellipsoid term needs |d / scale| < 1.2, the
    # collision term |d| < contact.
    reach = np.maximum(1.2 * scale.max(axis=1, initial=0.0), contact)
    return {
        "times": times,
        "points": points,
        "nk": np.array([len(it.times) for it in intents], dtype=np.int64),
        "scale": scale,
        "contact": contact,
        "reach": reach,
        "vmax": vmax,
    }
