"""When a stuck agent plans no escape of its own (tests of :meth:`EscapePlanner.on_stuck`
besides its crowd and obstacle tests): the field is still carrying it, the guide round static
obstacles leads it, or it waits in a queue (one its last escape did not get it out of, or one
that still moves)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.core import PlanningContext
from swarmplan.flight.field_law import goal_factor, nearest, repulsion
from swarmplan.world.motion import poses_at

#: Flying agents within the reach of the field's agent term from which a stuck agent is in a
#: crowd: it plans no escape of its own (doorway, 64 agents: escapes of single agents through
#: the crowd at the gap took arrivals from 36 to 32 and the real-time factor from 11x to 3x).
CROWD = 3

#: Stuck windows in a row (with no progress towards the goal between them) for which the gates
#: of :func:`stand_down_gate` may let the field, not an escape, free an agent: after that many,
#: a stuck agent is offered its optimizer whatever those gates say (a crowd or queue that has
#: not dissolved in two windows is holding it, not passing it; a queue that still moves is
#: :func:`queue_moves`'s to judge).
STAND_DOWN_WINDOWS = 1


def under_way(sim: PlanningContext, i: int) -> bool:
    """Whether agent ``i``, one that can stop (a multirotor), still flies at half its cruise
    speed or more: the field is carrying it round something (a pillar, a crowd), not holding
    it in a local minimum, where it would come to rest; an escape only adds a detour and its
    planning time. A fixed wing flies at cruise speed in a trap too: it is never under way."""
    p = sim.params
    if p.fixed_wing[i]:
        return False
    return bool(np.linalg.norm(sim.state.velocity[i]) >= 0.5 * p.speed_cruise[i])


def guided(sim: PlanningContext, i: int) -> bool:
    """Whether the guide round static obstacles (``swarmplan.flight.guide``) leads agent ``i``
    and no moving obstacle is within the field's influence: the guide's way has no local
    minima of the static obstacles, so what holds the agent is other agents (a queue at a
    gap), whose progress dissolves it; an escape through them only adds a detour (doorway, 64
    agents: an escape took an agent from the queue at the gap to the wall beside it, where it
    stayed until the horizon)."""
    guide = getattr(sim, "guide", None)
    s = sim.state
    if guide is None or not guide.leads(i, s.position[i], s.goal[i]):
        return False
    return not mover_near(sim, i)


def mover_near(sim: PlanningContext, i: int) -> bool:
    """Whether a moving obstacle is within the field's influence of agent ``i``."""
    movers = sim.world.moving_obstacles
    if not movers:
        return False
    centres, _ = poses_at(movers, sim.state.t)
    reach = sim.world.planner_config.apf.influence + np.array([o.bounding_radius for o in movers])
    return bool((np.linalg.norm(centres - sim.state.position[i], axis=1) < reach).any())


def lining_up(sim: PlanningContext, i: int, since: float) -> bool:
    """Whether fixed wing ``i`` lines up with the way round static obstacles, left to the field
    since ``since`` (s): its line to its goal is blocked, it flies at the farthest point of its
    way in sight (``swarmplan.flight.sight``), no moving obstacle is within the field's
    influence, and less time has passed than flying that way and a full circle at its turn
    radius takes at its cruise speed. The way has no local minima of the static obstacles, but
    lining up with an opening can take a fixed wing a full circle away from its goal, window
    after window of no progress; an escape then only takes it off the way (a wall with a
    window: escapes planned while it turned took it to the far corners of the world)."""
    p = sim.params
    sight, guide = getattr(sim, "sight", None), getattr(sim, "guide", None)
    if not p.fixed_wing[i] or sight is None or guide is None:
        return False
    if not sight.sighted[i] or sight.in_sight[i]:
        return False
    s = sim.state
    way = float(guide.way_length(s.position[i][None], s.goal[i][None])[0])
    if not np.isfinite(way) or mover_near(sim, i):
        return False
    allowance = (way + 2.0 * np.pi * float(p.min_turn_radius[i])) / max(float(p.speed_cruise[i]), 1e-6)
    return s.t - since <= allowance


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


def queue_moves(sim: PlanningContext, i: int, near: np.ndarray, since: float) -> bool:
    """Whether agent ``i`` waits in a queue that moves, left to the field since ``since`` (s):
    ``CROWD`` or more flying agents are near (``near``, a mask); those of them nearer its goal
    than it is (the queue ahead, and the agents coming the other way through it) fly towards
    their own goals, on average, at least at the rate stuck detection asks
    (``stuck.min_progress`` per ``stuck.window``); and less time has passed than that queue
    takes to pass at that rate, one slot (two radii and the separation) per agent. The crowd's
    own progress dissolves such a queue; an escape through it only plans a detour (doorway, 64
    agents, seed 2: 23 escapes and yields planned in the queue at the gap, the last arrival at
    42 s against the bare field's 27 s; with this gate none, at 27 s). A queue that stops, or
    outlasts its allowance, leaves the agent to its optimizer."""
    if near.sum() < CROWD:
        return False
    s, p = sim.state, sim.params
    goal = s.goal[i]
    j = np.flatnonzero(near)
    ahead = j[np.linalg.norm(s.position[j] - goal, axis=1) < float(np.linalg.norm(goal - s.position[i]))]
    if not len(ahead):
        return False
    to_goal = s.goal[ahead] - s.position[ahead]
    dist = np.maximum(np.linalg.norm(to_goal, axis=1), 1e-9)
    rate = float(np.mean(np.einsum("ij,ij->i", s.velocity[ahead], to_goal) / dist))
    stuck = sim.world.planner_config.stuck
    if rate < stuck.min_progress / stuck.window:
        return False
    slot = 2.0 * float(p.radius[i]) + float(np.max(p.separation[i]))
    return s.t - since <= len(ahead) * slot / rate


def held_by_obstacles(sim: PlanningContext, i: int) -> bool:
    """Whether the obstacles' push (static and moving, at their poses now; the field's law,
    ``flight.field_law``) along agent ``i``'s pull towards its goal takes more than half of the
    pull."""
    w = sim.world
    if not w.obstacles:
        return False
    apf = w.planner_config.apf
    s = sim.state
    pos, goal = s.position[i], s.goal[i]
    to_goal = float(np.linalg.norm(goal - pos))
    pull = apf.k_att * min(to_goal, apf.quadratic_radius)
    d, g = sim.distances.query(pos[None], poses_at(w.obstacles, s.t)[0])
    rho = d[0] - float(sim.params.radius[i])
    near = rho < apf.influence
    if not near.any():
        return False
    gfac = float(goal_factor(np.asarray(to_goal), apf.influence, apf.goal_power))
    push = repulsion(rho[near], apf.k_rep, apf.influence, nearest(float(sim.params.radius[i]))) * gfac
    along = g[0, near] @ ((goal - pos) / max(to_goal, 1e-9))
    return bool(pull + float(push @ along) < 0.5 * pull)


def stand_down_gate(
    sim: PlanningContext,
    i: int,
    escaped_at: float | None,
    agents_near: Callable[[], np.ndarray],
    only_agents_around: Callable[[], bool],
) -> str | None:
    """The reason to let the field, not an escape, free stuck agent ``i`` this window, if any:
    ``under_way`` (it still flies at half its cruise speed or more), ``queue`` (its last escape,
    started ``escaped_at`` m from its goal, left it no nearer while others are near), ``crowd``
    (other agents, not a trap, hold it) or ``guided`` (the guide leads it round static
    obstacles). The tests run cheapest first (the same answer in any order)."""
    if under_way(sim, i):
        return "under_way"
    if escaped_at is not None and queued(sim, i, escaped_at, agents_near()):
        return "queue"
    if only_agents_around():
        return "crowd"
    if guided(sim, i):
        return "guided"
    return None


def stand_down(
    sim: PlanningContext,
    i: int,
    escaped_at: float | None,
    agents_near: Callable[[], np.ndarray],
    only_agents_around: Callable[[], bool],
    in_row: int,
    since: dict[str, dict[int, float]],
) -> str | None:
    """The reason to leave stuck agent ``i`` to the field this window, if any: a gate of
    :func:`stand_down_gate` while it has stood down fewer than ``STAND_DOWN_WINDOWS`` windows
    in a row (``in_row``: an agent still stuck after that is offered its optimizer whatever
    those gates say), else, window after window within their allowances, ``queue_moves``
    (:func:`queue_moves`) or ``lining_up`` (:func:`lining_up`). ``since``, per gate and agent
    since when it has held the agent in this row, is kept here."""
    if in_row < STAND_DOWN_WINDOWS:
        gate = stand_down_gate(sim, i, escaped_at, agents_near, only_agents_around)
        if gate is not None:
            return gate
    t = sim.state.t
    queue = since.setdefault("queue_moves", {})
    if in_row == 0:
        queue.pop(i, None)  # a new row
    if queue_moves(sim, i, agents_near(), queue.setdefault(i, t)):
        return "queue_moves"
    queue.pop(i, None)
    lining = since.setdefault("lining_up", {})
    if lining_up(sim, i, lining.setdefault(i, t)):
        return "lining_up"
    lining.pop(i, None)
    return None


class StandDowns:
    """Which stuck agents are left to the field, run by run: per agent the stand-downs in a row
    and the distance to its goal at the last of them, and per gate since when it has held it."""

    def __init__(self) -> None:
        self.in_row: dict[int, tuple[int, float]] = {}
        self.since: dict[str, dict[int, float]] = {}

    def clear(self) -> None:
        """A new run: no agent has stood down yet."""
        self.in_row.clear()
        self.since.clear()

    def decide(
        self,
        sim: PlanningContext,
        i: int,
        escaped_at: float | None,
        agents_near: Callable[[], np.ndarray],
        only_agents_around: Callable[[], bool],
    ) -> str | None:
        """:func:`stand_down` for stuck agent ``i``, counting its stand-downs in a row: those
        with the agent no nearer its goal, by ``stuck.min_progress``, than at the last of them
        (one that got on well in between starts the count again; one that swings to and fro in
        a trap does not)."""
        count, was = self.in_row.get(i, (0, np.inf))
        now = float(np.linalg.norm(sim.state.goal[i] - sim.state.position[i]))
        row = count if now > was - float(sim.world.planner_config.stuck.min_progress) else 0
        gate = stand_down(sim, i, escaped_at, agents_near, only_agents_around, row, self.since)
        if gate is None:
            self.in_row.pop(i, None)
        else:
            self.in_row[i] = (row + 1, now)
        return gate


def held_by(sim: PlanningContext, i: int) -> dict[str, object]:
    """What holds agent ``i``: the nearest of the ground (or terrain), the faces of the flight
    volume, the obstacles (at their poses now) and the other agents, by clearance from the
    agent's body. ``{"by": "ground" | "bounds" | "body" | "agent", "id": ..., "clearance": m}``
    (``id`` names the body or agent; ``by: "none"`` when the nearest lies beyond the field's
    influence: nothing holds the agent but its own field, e.g. the pull of a moving obstacle's
    predicted approach)."""
    w, s, p = sim.world, sim.state, sim.params
    pos, r = s.position[i], float(p.radius[i])
    h = float(w.terrain_height(pos[None, :2])[0])
    found: list[tuple[float, str, str | None]] = [(float(pos[2] - h) - r, "ground", None)]
    faces = np.concatenate([pos - w.bounds_min, w.bounds_max - pos])
    faces[2] = np.inf  # the floor is the ground's
    found.append((float(faces.min()) - r, "bounds", None))
    if w.obstacles:
        d, _ = sim.distances.query(pos[None], poses_at(w.obstacles, s.t)[0])
        k = int(np.argmin(d[0]))
        found.append((float(d[0, k]) - r, "body", w.obstacles[k].id))
    others = np.flatnonzero(np.arange(len(s.position)) != i)
    if len(others):
        gap = np.linalg.norm(s.position[others] - pos, axis=1) - p.radius[others] - r
        k = int(np.argmin(gap))
        found.append((float(gap[k]), "agent", str(p.ids[others[k]])))
    clearance, by, ident = min(found, key=lambda f: f[0])
    if clearance > float(w.planner_config.apf.influence):  # nothing within the field's reach
        by, ident = "none", None
    return {"by": by, "id": ident, "clearance": round(clearance, 6)}
