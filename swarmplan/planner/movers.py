"""Moving obstacles in escape planning: where they will be while an escape is flown.

An escape is planned from a stuck agent; it is flown later, over several seconds, while the
moving obstacles go on along their motions (:mod:`swarmplan.world.motion`; a ``waypoints`` mover
without ``loop`` parks at its last waypoint and stays there). So the escape's sub-goal, its
clearance checks and its FCL validation look at each mover at its *predicted* pose at the
time the agent would be there:

- :class:`EscapeClock` is that time: the agent accelerates from its present speed at
  ``max_accel`` to cruise speed and keeps it (the potential field never commands more than
  cruise speed, so the agent is rarely earlier than this, often later: turns slow it down);
- :func:`timing_slack` widens each predicted time into a window, early by ``EARLY`` s,
  late by ``LATE_BASE`` s plus ``LATE_RATE`` of the time flown, at most ``LATE_MAX`` s;
  a mover counts wherever it is in that window (a parked one: one pose, no cost);
- :func:`moving_clearance` is the clearance of points to the movers over such windows;
- :func:`moving_leg_hit` sweeps an escape leg with FCL against the movers at those times.

Motions translate only (orientation stays the obstacle's ``rotation``), so a mover at a
predicted centre is its reference shape shifted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.geometry.bodies import code_of
from swarmplan.geometry.collision import segment_segment_min_distance
from swarmplan.geometry.shapes import DISTANCE, distance_and_gradient
from swarmplan.geometry.vec3 import norm3
from swarmplan.world.motion import _waypoint_path

EARLY = 0.5  # s the agent may be ahead of the clock
LATE_BASE = 0.5  # s it may be behind at the start
LATE_RATE = 0.25  # ... plus this fraction of the time flown
LATE_MAX = 3.0  # s, at most
STEP = 0.2  # s between the predicted poses looked at


def positions_at(obstacles, times: np.ndarray) -> np.ndarray:  # noqa: ANN001 - Obstacle sequence
    """Centres of ``obstacles`` at ``times`` (T,) → (T, M, 3); the same poses as
    :func:`swarmplan.world.motion.pose_at` (times before 0 count as 0), vectorized over time."""
    times = np.maximum(np.asarray(times, dtype=float).reshape(-1), 0.0)
    out = np.empty((len(times), len(obstacles), 3))
    for j, o in enumerate(obstacles):
        m = o.motion
        if m is None:
            out[:, j] = o.position
        elif m.type == "linear":
            out[:, j] = o.position + times[:, None] * m.velocity
        elif m.type == "circle":
            rel = o.position[:2] - m.center[:2]
            phi0 = np.arctan2(rel[1], rel[0]) if np.linalg.norm(rel) > 1e-9 else 0.0
            phi = phi0 + m.angular_speed * times
            out[:, j, 0] = m.center[0] + m.radius * np.cos(phi)
            out[:, j, 1] = m.center[1] + m.radius * np.sin(phi)
            out[:, j, 2] = m.center[2]
        else:
            pts, cum = _waypoint_path(o)
            total = cum[-1]
            if total <= 0:
                out[:, j] = pts[0]
                continue
            s = m.speed * times
            s = s % total if m.loop else np.minimum(s, total)
            for k in range(3):
                out[:, j, k] = np.interp(s, cum, pts[:, k])
    return out


@dataclass(frozen=True)
class EscapeClock:
    """When agent ``i`` would be ``s`` metres along an escape that starts now."""

    t0: float
    v0: float
    accel: float
    cruise: float

    @classmethod
    def of(cls, sim, i: int) -> EscapeClock:  # noqa: ANN001 - PlanningContext
        p = sim.params
        cruise = max(float(p.speed_cruise[i]), 0.1)
        v0 = min(float(np.linalg.norm(sim.state.velocity[i])), cruise)
        return cls(float(sim.state.t), v0, max(float(p.max_accel[i]), 1e-3), cruise)

    def __call__(self, s: np.ndarray | float) -> np.ndarray:
        """Absolute time at arc length ``s`` (any shape)."""
        s = np.maximum(np.asarray(s, dtype=float), 0.0)
        v0, a, v = self.v0, self.accel, self.cruise
        s_acc = (v * v - v0 * v0) / (2 * a)
        t_acc = (np.sqrt(v0 * v0 + 2 * a * np.minimum(s, s_acc)) - v0) / a
        return self.t0 + t_acc + np.maximum(s - s_acc, 0.0) / v


def timing_slack(elapsed: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """(early, late) seconds around a predicted time ``elapsed`` s into the escape."""
    elapsed = np.maximum(np.asarray(elapsed, dtype=float), 0.0)
    late = np.minimum(LATE_BASE + LATE_RATE * elapsed, LATE_MAX)
    return np.full_like(late, EARLY), late


_POSE_PAIRS = 200_000
"""(point, pose) pairs measured per array pass in :func:`moving_clearance`."""


def _mover_indices(sim) -> np.ndarray:  # noqa: ANN001
    return np.flatnonzero(sim.moving_mask)


def moving_clearance(
    sim,  # noqa: ANN001 - PlanningContext
    pts: np.ndarray,
    radius: float,
    t_lo: np.ndarray | float,
    t_hi: np.ndarray | float,
    cap: float = np.inf,
) -> np.ndarray:
    """Clearance (surface distance minus ``radius``) of each point to the moving obstacles at
    every predicted pose in its time window ``t_lo``..``t_hi`` (the worst one).

    Values above ``cap`` are only known to be above it (movers that cannot come within
    ``cap`` are skipped); with no movers the clearance is infinite."""
    pts = np.atleast_2d(np.asarray(pts, dtype=float))
    n = len(pts)
    out = np.full(n, np.inf)
    idx = _mover_indices(sim)
    if not len(idx) or not n:
        return out
    lo = np.broadcast_to(np.asarray(t_lo, dtype=float), (n,))
    hi = np.maximum(np.broadcast_to(np.asarray(t_hi, dtype=float), (n,)), lo)
    k = np.ceil((hi.max() - lo.min()) / STEP)
    grid = lo.min() + np.arange(int(k) + 1) * STEP
    # Each point sees the poses inside its window, and at least the one nearest its window.
    inside = (grid[None, :] >= lo[:, None] - 1e-9) & (grid[None, :] <= hi[:, None] + 1e-9)
    nearest = np.clip(np.round((lo - grid[0]) / STEP).astype(int), 0, len(grid) - 1)
    inside[np.arange(n), nearest] = True
    obstacles = [sim.world.obstacles[j] for j in idx]
    centers = positions_at(obstacles, grid)  # (T, M, 3)
    for m, (j, o) in enumerate(zip(idx, obstacles, strict=True)):
        # A parked mover has one distinct pose over the whole window: measure it once.
        poses, which = _distinct_poses(centers[:, m].round(9))
        reach = cap + radius + o.bounding_radius
        if o.shape == "sphere" and np.array_equal(o.rotation, np.eye(3)):
            # Every (point, pose) pair at once: the sphere's distance (``shapes.DISTANCE``), as
            # distance_and_gradient gives it (its product with the identity is exact).
            # Only points within reach of the poses' box can be within reach of a pose (a margin
            # covers the rounding of the norms).
            slack = reach * (1.0 + 1e-9) + 1e-9
            rows = np.flatnonzero(
                ((pts >= poses.min(axis=0) - slack) & (pts <= poses.max(axis=0) + slack)).all(axis=1)
            )
            if not len(rows):
                continue
            chunk = max(1, _POSE_PAIRS // len(rows))  # poses per pass: small temporaries
            # sees[:, u]: the point's window holds a grid time at pose u (columns grouped by pose).
            order = np.argsort(which, kind="stable")
            starts = np.flatnonzero(np.r_[True, np.diff(which[order]) != 0])
            sees_all = np.logical_or.reduceat(inside[rows][:, order], starts, axis=1)
            for u0 in range(0, len(poses), chunk):
                part = poses[u0 : u0 + chunk]
                sees = sees_all[:, u0 : u0 + len(part)]
                rel = pts[rows, None, :] - part[None, :, :]
                body = DISTANCE[code_of("sphere")](rel, np.array([o.radius, 0.0, 0.0]))
                d = np.where(sees & (norm3(rel) <= reach), body - radius, np.inf).min(axis=1)
                out[rows] = np.minimum(out[rows], d)
            continue
        for u, c in enumerate(poses):
            sel = np.flatnonzero(inside[:, which == u].any(axis=1))
            sel = sel[np.linalg.norm(pts[sel] - c, axis=1) <= reach]
            if len(sel):
                grid_j = sim.distances.mesh_grids.get(int(j))
                d = distance_and_gradient(o, pts[sel], c, grid_j)[0] - radius
                out[sel] = np.minimum(out[sel], d)
    return out


def _distinct_poses(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(poses, which): the runs of equal consecutive rows of ``c`` (T, 3) and, per row, its run.

    A mover's poses along the grid repeat only while it is parked, i.e. in consecutive rows;
    a pose it comes back to later is measured twice, which changes no minimum. (Was
    ``np.unique(axis=0)``, which sorts rows as structured values: ~40 % of an escape's
    validation time with 32 movers.)"""
    change = np.r_[True, (c[1:] != c[:-1]).any(axis=1)]
    return c[change], np.cumsum(change) - 1


def predicted_window(clock: EscapeClock, s: np.ndarray, detour: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Time window in which the agent would be ``s`` metres along its escape: from the clock
    (minus the early slack) to the clock at ``detour`` × ``s`` (plus the late slack)."""
    t_fast = clock(s)
    t_slow = clock(detour * np.asarray(s, dtype=float))
    early, _ = timing_slack(t_fast - clock.t0)
    _, late = timing_slack(t_slow - clock.t0)
    return t_fast - early, t_slow + late


def moving_leg_hit(
    sim,  # noqa: ANN001 - PlanningContext
    clock: EscapeClock,
    a: np.ndarray,
    b: np.ndarray,
    s_a: float,
    radius: float,
) -> str | None:
    """Id of a mover that a sphere of ``radius`` flying ``a`` → ``b`` (``s_a`` metres into the
    escape, timed by ``clock``) touches at any time in its slack window, else None.

    The leg is cut into pieces of ``STEP`` s; each piece is swept by FCL against every mover
    moving as predicted during that piece, shifted by every multiple of ``STEP`` in the slack
    window. The sphere grows by half of the largest distance a mover covers in ``STEP`` s
    (nothing for parked movers), which covers the shifts between the multiples."""
    idx = _mover_indices(sim)
    if not len(idx):
        return None
    col = sim.collision
    length = float(np.linalg.norm(b - a))
    s = s_a + np.array([0.0, length])
    t_ab = clock(s)
    n = max(1, int(np.ceil((t_ab[1] - t_ab[0]) / STEP)))
    u = np.linspace(0.0, 1.0, n + 1)
    P = a + u[:, None] * (b - a)  # piece ends (n+1, 3)
    T = clock(s_a + u * length)
    early, late = timing_slack(T - clock.t0)
    shifts = np.arange(-np.ceil(early.max() / STEP), np.ceil(late.max() / STEP) + 1) * STEP  # (O,)
    Q = positions_at(col.moving, (T[:, None] + shifts[None, :]).reshape(-1)).reshape(
        n + 1, len(shifts), -1, 3
    )
    # Mover displacement between neighbouring shifts (= in STEP s) bounds what the grid misses.
    grow = 0.5 * float(np.linalg.norm(np.diff(Q, axis=1), axis=-1).max(initial=0.0))
    rr = radius + grow
    ok = (shifts[None, :] >= -early[:, None] - 1e-9) & (shifts[None, :] <= late[:, None] + 1e-9)
    ok = ok[:-1] | ok[1:]  # (n, O): a shift counts for a piece when it counts at either end
    p0 = np.broadcast_to(P[:-1, None, None, :], Q[:-1].shape)
    p1 = np.broadcast_to(P[1:, None, None, :], Q[:-1].shape)
    bound = np.array([o.bounding_radius for o in col.moving])
    gap = segment_segment_min_distance(p0, p1, Q[:-1], Q[1:]) - bound - rr  # (n, O, M)
    near = np.any(gap <= 1e-6, axis=-1) & ok
    for k, o in zip(*np.nonzero(near), strict=True):
        hit = col.sweep_moving(P[k], P[k + 1], rr, Q[k, o], Q[k + 1, o])
        if hit:
            return hit
    return None
