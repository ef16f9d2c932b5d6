"""The turn-ahead guard's clearance of predicted positions (``SafetyFilter.guard_fixed_wings``):
the numpy formulation (:func:`guard_clearance`, which also measures meshes; compiled:
``_guard_kernel.clearances``, the same bits) and the moving obstacles' centres at the
predicted times, kept from step to step (:class:`MoverCentres`)."""

from __future__ import annotations

import numpy as np

from swarmplan.geometry.batch import ShapeBatch
from swarmplan.world.model import World
from swarmplan.world.motion import poses_at


def guard_clearance(
    batch: ShapeBatch,
    points: np.ndarray,
    radii: np.ndarray,
    extra: np.ndarray,
    ground: np.ndarray,
    bmin: np.ndarray,
    bmax: np.ndarray,
    static: np.ndarray,
    movers: np.ndarray,
    origin: np.ndarray,
    centers: np.ndarray,
    row: np.ndarray,
) -> np.ndarray:
    """The turn-ahead guard's clearance of ``points`` (P, 3) of body radii ``radii``: the least
    of the height above ``ground`` (P,) and the distance inside the bounds ``bmin``..``bmax``
    (each less the radius) and of the distances to the bodies ``static`` and ``movers`` of
    ``batch`` (less the radius and ``extra`` (P,), the gap kept from bodies). Mover
    ``movers[k]`` started at ``origin[k]`` and is at ``centers[row[i], k]`` at point i's time:
    movers translate, so a point's distance to one is that of the point shifted back by the
    mover's way to the mover where it started. The numpy twin of ``_guard_kernel.clearances``
    (the same bits; it also measures meshes)."""
    c = points[:, 2] - ground - radii
    # Leaving the flight volume counts as a collision ('bounds') as well.
    inside = np.minimum(points - bmin, bmax - points).min(axis=1)
    c = np.minimum(c, inside - radii)
    if len(static):
        c = np.minimum(c, batch.distance(points, None, static).min(axis=1) - radii - extra)
    for k, j in enumerate(movers.tolist()):
        shifted = points - (centers[row, k] - origin[k])
        dj = batch.distance(shifted, None, np.array([j]))[:, 0]
        c = np.minimum(c, dj - radii - extra)
    return c


class MoverCentres:
    """The moving obstacles' centres by step number (times ``k * dt``), kept as a table from the
    first step asked for on."""

    def __init__(self, world: World):
        self.world = world
        self.table = np.zeros((0, len(world.moving_obstacles), 3))
        self.base = 0

    def at_steps(self, first: int, last: int) -> tuple[np.ndarray, int]:
        """The moving obstacles' centres (T, movers, 3) at the step numbers ``first`` to at
        least ``last`` (times ``k * dt``, row ``k - first``) and ``first``, kept from call to
        call: the guard's predictions of one step overlap the next one's but for a step or two
        (those before ``first`` are dropped; the missing ones computed)."""
        table, base = self.table, self.base
        end = base + len(table)
        if last < base or first > end:  # nothing in common: start afresh
            table, base, end = table[:0], first, first
        movers, dt = self.world.moving_obstacles, self.world.dt
        head = [poses_at(movers, k * dt)[0][None] for k in range(first, base)]
        tail = [poses_at(movers, k * dt)[0][None] for k in range(end, last + 1)]
        table = table[max(first - base, 0) :]
        if head or tail:
            table = np.concatenate([*head, table, *tail])
        self.table, self.base = table, first
        return table, first
