"""When a stuck agent plans no escape of its own (tests of :meth:`EscapePlanner.on_stuck`
besides its crowd and obstacle tests): the field is still carrying it, or it waits in a queue."""

from __future__ import annotations

import numpy as np

from swarmplan.core import PlanningContext

#: Flying agents within the reach of the field's agent term from which a stuck agent is in a
#: crowd: it plans no escape of its own (doorway, 64 agents: escapes of single agents through
#: the crowd at the gap took arrivals from 36 to 32 and the real-time factor from 11x to 3x).
CROWD = 3


def under_way(sim: PlanningContext, i: int) -> bool:
    """Whether agent ``i``, one that can stop (a multirotor), still flies at half its cruise
    speed or more: the field is carrying it round something (a pillar, a crowd), not holding
    it in a local minimum, where it would come to rest; an escape only adds a detour and its
    planning time. A fixed wing flies at cruise speed in a trap too: it is never under way."""
    p = sim.params
    if p.fixed_wing[i]:
        return False
    return bool(np.linalg.norm(sim.state.velocity[i]) >= 0.5 * p.speed_cruise[i])


def queued(sim: PlanningContext, i: int, escaped_at: float, near: np.ndarray) -> bool:
    """Whether agent ``i`` waits in a queue: other agents are near (``near``, a mask), and its
    last escape (or attempt at one), started ``escaped_at`` m from its goal, left it no nearer
    by ``stuck.min_progress``. What holds it then is the queue at the way out (a gap the others
    fly through first), which their progress dissolves; another escape plans the same detour."""
    if not near.any():
        return False
    s = sim.state
    progress = escaped_at - float(np.linalg.norm(s.goal[i] - s.position[i]))
    return progress < sim.world.planner_config.stuck.min_progress
