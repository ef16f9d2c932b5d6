"""Speeds and steps near surfaces, for the safety filter (``swarmplan.sim.safety``): the speed a
stop fits in, the factor that caps a speed, and the steps of an agent already within its safety
margin of a surface."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class SweptChecks(Protocol):
    """What :func:`keeping_clearance` asks of the safety filter (``safety.SafetyFilter``)."""

    params: Any
    world: Any
    checked_radius: np.ndarray

    def steps_free(
        self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, q0: np.ndarray, q1: np.ndarray
    ) -> np.ndarray: ...


def stoppable_speed(room: np.ndarray, amax: np.ndarray, dt: float) -> np.ndarray:
    """The largest speed ``v`` with ``v^2 / (2 amax) + v dt <= room``: one more step at ``v``,
    then braking at ``amax``, stays within ``room``."""
    return amax * (np.sqrt(dt**2 + 2.0 * room / amax) - dt)


def shrink(speed: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """Per-row factor (n, 1) scaling vectors of norm ``speed`` down to at most ``cap``."""
    return np.minimum(1.0, cap / np.maximum(speed, 1e-12))[:, None]


def keeping_clearance(
    safety: SweptChecks,
    i: int,
    p0: np.ndarray,
    cands: list[np.ndarray],
    poses: tuple[np.ndarray, np.ndarray],
) -> list[np.ndarray]:
    """The velocities of ``cands`` whose step from ``p0`` keeps multirotor ``i`` at least as
    clear as staying put does (the obstacles at ``poses``, the step's start and end), for an
    agent already within its safety margin of a surface (the end of an approach rounded inside
    it, a mover come closer): there every step, one away from the surface too, touches with the
    margin, and it would stop for good. Its clearance is the largest swept radius, between its
    radius and its radius with the margin, at which staying put touches nothing (bisected to a
    millionth of the margin); none when staying put already touches its body."""
    q0, q1 = poses
    r = float(safety.params.radius[i])
    lo, hi = r, float(safety.checked_radius[i])

    def stays_free(radius: float) -> bool:
        return bool(safety.steps_free(p0[None], p0[None], np.array([radius]), q0, q1)[0])

    if not stays_free(lo):
        return []
    while hi - lo > 1e-6 * (safety.checked_radius[i] - r):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stays_free(mid) else (lo, mid)
    ends = p0 + np.array(cands) * safety.world.dt
    starts = np.repeat(p0[None], len(cands), axis=0)
    free = safety.steps_free(starts, ends, np.full(len(cands), lo), q0, q1)
    return [v for v, f in zip(cands, free, strict=True) if f]
