"""Fixed wings and the guide round static obstacles (``swarmplan.flight.guide``): a fixed wing
is never guided along the grid's way (it cannot fly a way that hugs corners), but one flying at
its goal along a clear straight line flies it without the static bodies' push, and one whose
line is blocked flies straight at the farthest point of its way it sees. Its turn-ahead guard
keeps its clearance from the bodies.

A fixed wing whose whole straight line to its goal is clear (through a window, a gap) flies it
without the static bodies' push, which would turn it away in front of the opening; one whose
line is blocked flies straight at the farthest point of its way that it sees (lining up with
the opening the way runs through). Its line is checked as a guided agent's (every ``RECHECK``
steps, ``swarmplan.flight.guide``)."""

from __future__ import annotations

import numpy as np

from swarmplan.flight.guide import RECHECK, StaticGuide

SIGHT_REPULSION = 0.0
"""Scale of the static repulsion of a fixed wing flying a clear line (its guard keeps clear)."""


class Sight:
    """Per fixed wing: whether its straight line to its goal is clear and, for one whose line
    is blocked, the farthest point of its way in clear sight (reset with :meth:`reset`, and
    with every new guide)."""

    def __init__(self, n: int):
        self.in_sight = np.zeros(n, dtype=bool)
        self.sighted = np.zeros(n, dtype=bool)
        self.point = np.zeros((n, 3))

    def reset(self) -> None:
        self.in_sight[:] = False
        self.sighted[:] = False

    def targets(
        self,
        guide: StaticGuide,
        step: int,
        idx: np.ndarray,
        pos: np.ndarray,
        goal: np.ndarray,
        target: np.ndarray,
        scale: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``target`` and ``scale`` of agents ``idx`` at ``pos`` (n, 3) (``guide.targets``'s answers)
        with those of the fixed wings among them flying at their goal: :func:`fixed_wings_in_sight`."""
        if guide.can_stop[idx].all():
            return target, scale
        same = target == goal
        to_goal = same[:, 0] & same[:, 1] & same[:, 2]
        return fixed_wings_in_sight(self, guide, step, idx, pos, goal, to_goal, target, scale)


def fixed_wings_in_sight(
    sight: Sight,
    guide: StaticGuide,
    step: int,
    idx: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    to_goal: np.ndarray,
    target: np.ndarray,
    scale: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``target`` and ``scale`` for the fixed wings flying at their goal (checked every
    ``RECHECK`` steps): one with a clear straight line to it flies that line without the
    static bodies' push (``SIGHT_REPULSION``): through a window or a gap its line passes,
    the edges' push would turn it away in front of the opening; one whose line is blocked
    flies straight, the same way, at the farthest point of its way on the grid that it
    sees (it lines up with the opening the way runs through). Its turn-ahead guard keeps
    its clearance from the bodies."""
    fixed = to_goal & ~guide.can_stop[idx]
    due = np.flatnonzero(fixed & ((idx + step) % RECHECK == 0))
    if len(due):
        who = idx[due]
        sight.in_sight[who] = ~guide.blocked(pos[due], goal[due])
        for r in due[~sight.in_sight[who]].tolist():
            point = farthest_seen(guide, pos[r], goal[r])
            sight.sighted[idx[r]] = point is not None
            if point is not None:
                sight.point[idx[r]] = point
    seen = fixed & (sight.in_sight[idx] | sight.sighted[idx])
    rows = np.flatnonzero(seen)
    if not len(rows):
        return target, scale
    scale = scale.copy()
    scale[rows] = np.minimum(scale[rows], SIGHT_REPULSION)
    aim = np.flatnonzero(seen & ~sight.in_sight[idx])
    if len(aim):
        target = np.array(target, dtype=float)
        target[aim] = sight.point[idx[aim]]
    return target, scale


def farthest_seen(guide: StaticGuide, pos: np.ndarray, goal: np.ndarray) -> np.ndarray | None:
    """The farthest cell centre of the way from ``pos`` to ``goal`` (3,) whose straight line
    from ``pos`` is clear, or None (no way, or no point of it in sight)."""
    row = int(guide._rows_for(guide.cell_of(goal[None]), pos[None], goal[None])[0])
    way = guide._way(row, int(guide.cell_of(pos[None])[0]))
    if len(way) < 2 or way[-1] != guide._source[row]:
        return None
    pts = guide.centres[np.array(way[1:])]
    clear = np.flatnonzero(~guide.blocked(np.repeat(pos[None], len(pts), axis=0), pts))
    return None if not len(clear) else pts[int(clear[-1])].copy()
