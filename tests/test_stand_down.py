"""When a stuck agent is left to the field and when it gets its optimizer: stuck detection's
measure of progress, the stand-downs counted in a row, and the queue that still moves."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from helpers import base_world, make_world

from swarmplan.core import Mode
from swarmplan.flight.kinematics import AgentParams
from swarmplan.planner import escape_gates
from swarmplan.sim.navigation import Navigator, initial_state


class _Guide:
    """A guide whose way is the straight line plus a fixed detour, leading whom ``guided`` says."""

    def __init__(self, n: int, detour: float):
        self.guided = np.zeros(n, dtype=bool)
        self.detour = detour

    def way_length(self, pos: np.ndarray, goal: np.ndarray) -> np.ndarray:
        return np.linalg.norm(goal - pos, axis=1) + self.detour


def _navigator(detour: float):
    world = make_world(base_world())  # one agent, 80 m from its goal
    params = AgentParams.from_world(world)
    guide = _Guide(1, detour)
    nav = Navigator(world, params, guide)
    s = initial_state(world, params)
    nav.reset(s)
    stuck: list[int] = []
    return world, nav, s, guide, lambda i: (stuck.append(i), (None, ()))[1], stuck


def test_an_agent_the_guide_starts_to_lead_is_not_stuck_while_it_closes_on_its_goal():
    world, nav, s, guide, on_stuck, stuck = _navigator(detour=30.0)
    window = world.planner_config.stuck.window
    # a window flown straight at the goal, 15 m nearer; the guide leads it from now on (its
    # way, 30 m longer than the line, measures what is left)
    s.position[0] += np.array([15.0, 0.0, 0.0])
    s.t = window
    guide.guided[0] = True
    nav.detect_stuck(s, on_stuck)
    assert stuck == []
    # led at both ends of the next window, it is measured along the way: no progress is stuck
    s.t = 2 * window
    nav.detect_stuck(s, on_stuck)
    assert stuck == [0]
    # a window closing 15 m along the way is progress again
    s.position[0] += np.array([15.0, 0.0, 0.0])
    s.t = 3 * window
    nav.detect_stuck(s, on_stuck)
    assert stuck == [0] and s.mode[0] == Mode.APF


def _stuck_context(goal_distance: float) -> SimpleNamespace:
    stuck = SimpleNamespace(window=3.0, min_progress=0.5)
    state = SimpleNamespace(t=0.0, goal=np.array([[goal_distance, 0.0, 0.0]]), position=np.zeros((1, 3)))
    return SimpleNamespace(
        state=state,
        world=SimpleNamespace(planner_config=SimpleNamespace(stuck=stuck)),
    )


def test_stand_downs_count_in_a_row_until_the_agent_gets_nearer_its_goal(monkeypatch):
    rows: list[int] = []

    def gate(sim, i, escaped_at, near, crowd, in_row, since):
        rows.append(in_row)
        return "crowd"

    monkeypatch.setattr(escape_gates, "stand_down", gate)
    downs = escape_gates.StandDowns()
    sim = _stuck_context(50.0)
    for x in (0.0, 0.3, -0.2):  # swinging to and fro: in a row
        sim.state.position[0, 0] = x
        downs.decide(sim, 0, None, lambda: None, lambda: None)
    sim.state.position[0, 0] = 0.6  # 0.8 m nearer than at the last stand-down: a new row
    downs.decide(sim, 0, None, lambda: None, lambda: None)
    downs.decide(sim, 0, None, lambda: None, lambda: None)
    assert rows == [0, 1, 2, 0, 1]


def _queue(speed: float, ahead: int = 4) -> tuple[SimpleNamespace, np.ndarray]:
    """Agent 0 at the origin bound for x = 100 m, ``ahead`` agents ahead of it 2 m apart flying
    at ``speed`` towards their goals along +x, and one behind it."""
    n = ahead + 2
    pos = np.zeros((n, 3))
    pos[1 : ahead + 1, 0] = 2.0 * np.arange(1, ahead + 1)
    pos[-1, 0] = -2.0
    goal = np.tile([100.0, 0.0, 0.0], (n, 1))
    vel = np.zeros((n, 3))
    vel[1:, 0] = speed
    stuck = SimpleNamespace(window=3.0, min_progress=0.5)
    sim = SimpleNamespace(
        state=SimpleNamespace(t=10.0, position=pos, goal=goal, velocity=vel),
        params=SimpleNamespace(radius=np.full(n, 0.5), separation=np.full((n, 3), 1.0)),
        world=SimpleNamespace(planner_config=SimpleNamespace(stuck=stuck)),
    )
    near = np.ones(n, dtype=bool)
    near[0] = False
    return sim, near


def test_a_queue_that_moves_holds_the_agent_for_as_long_as_it_takes_to_pass():
    sim, near = _queue(speed=1.0)
    # 4 agents ahead, one 2 m slot each (two radii and the separation), passing at 1 m/s: 8 s
    assert escape_gates.queue_moves(sim, 0, near, since=10.0)
    assert escape_gates.queue_moves(sim, 0, near, since=2.0)
    assert not escape_gates.queue_moves(sim, 0, near, since=1.9)


def _holds(speed: float, ahead: int = 4) -> bool:
    sim, near = _queue(speed, ahead)
    return escape_gates.queue_moves(sim, 0, near, since=10.0)


def test_a_queue_that_stands_still_or_a_few_agents_do_not_hold_the_agent():
    rate = 0.5 / 3.0  # the rate stuck detection asks
    assert not _holds(0.9 * rate) and _holds(1.1 * rate)
    assert not _holds(1.0, ahead=1)  # fewer than CROWD agents near
    sim, near = _queue(speed=1.0)
    sim.state.velocity[1:5, 0] = -1.0  # the agents ahead back away from their goals
    assert not escape_gates.queue_moves(sim, 0, near, since=10.0)
