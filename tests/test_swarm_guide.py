"""The guide round static obstacles (swarmplan.flight.guide): exact answers on simple geometry
(a wall with one gap, an open field), its lanes, movers that park for good, and the swarm
scenarios it exists for (every agent of a doorway swap and of the sphere with pillars home,
the default planner and pure APF alike)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world
from test_swarm_scenarios import _assert_home

from swarmplan.flight import guide as G
from swarmplan.flight.kinematics import AgentParams
from swarmplan.sim import Simulation
from swarmplan.world import motion

# A wall across the field at x = 50 (1 m thick, taller than the bounds) with one gap 6 m wide
# at y = 47..53; the agent starts west of it, its goal straight east behind the wall.
WALL = [
    {"id": "south", "shape": "box", "size": [1, 47, 60], "position": [50, 23.5, 25]},
    {"id": "north", "shape": "box", "size": [1, 47, 60], "position": [50, 76.5, 25]},
]


def wall_world(start=(30.0, 20.0, 20.0), goal=(70.0, 20.0, 20.0), agents=None, **top):
    agents = agents or [{"id": "a", "start": list(start), "goal": list(goal)}]
    return make_world(base_world(obstacles=WALL, agents=agents, **top))


def test_no_static_obstacle_no_guide():
    world = make_world(base_world())
    assert G.make_guide(world, AgentParams.from_world(world)) is None
    assert Simulation(world).guide is None


def test_a_line_through_the_wall_is_blocked_and_through_the_gap_or_open_field_not():
    world = wall_world(planner={"apf": {"influence": 10.0}})  # the squeeze: a tenth of it, 1 m
    assert G.make_guide(world, AgentParams.from_world(world)).squeeze == 1.0
    guide = G.make_guide(world, AgentParams.from_world(world))
    start = np.array([[30.0, 20.0, 20.0], [30.0, 50.0, 20.0], [10.0, 20.0, 20.0], [30.0, 46.0, 20.0]])
    end = np.array([[70.0, 20.0, 20.0], [70.0, 50.0, 20.0], [40.0, 20.0, 20.0], [70.0, 46.0, 20.0]])
    # through the wall; through the gap's middle (3 m from each edge, 2 m clearance); short of
    # the wall; through the gap 1 m from its edge (0 m clearance beyond the radius: a squeeze)
    assert guide.blocked(start, end).tolist() == [True, False, False, True]
    # An 8 m/s agent braking at 4 m/s^2 (32 m of influence: a 3.2 m squeeze) is guided through
    # the gap's middle too: the edges' push holds its bare field in front of the wall.
    fast = G.make_guide(wall_world(), AgentParams.from_world(wall_world()))
    assert fast.squeeze == pytest.approx(3.2)
    assert fast.blocked(start, end).tolist() == [True, True, False, True]


def test_behind_the_wall_the_way_leads_to_the_gap_and_through_it():
    world = wall_world()
    guide = G.make_guide(world, AgentParams.from_world(world))
    pos = np.array([[40.0, 20.0, 20.0]])
    goal = np.array([[70.0, 20.0, 20.0]])
    target, scale = guide.targets(0, np.array([0]), pos, goal, goal.copy(), np.ones(1))
    assert guide.guided[0] and scale[0] == G.REPULSION
    d = target[0] - pos[0]
    # towards the gap (north, up the y axis), not at the wall (east) beyond what the way allows
    assert d[1] > abs(d[0]) and abs(d[2]) < 1e-6 + guide.cell[2]
    # the way runs through the gap, about as long as the detour round the wall's edge (its
    # cost at least that: legs near surfaces cost more than their length)
    row = int(guide._rows_for(guide.cell_of(goal), pos, goal)[0])
    way = np.vstack([pos, guide.centres[guide._way(row, int(guide.cell_of(pos)[0]))[1:]]])
    length = np.linalg.norm(np.diff(way, axis=0), axis=1).sum()
    detour = np.hypot(10.0, 28.0) + np.hypot(20.0, 28.0)  # via the gap's edge at (50, 48)
    assert detour - 1.0 < length < 1.15 * detour + 2.0 * guide.cell.max()
    assert guide.way_length(pos, goal)[0] >= length - guide.cell.max()
    crossing = way[np.argmin(np.abs(way[:, 0] - 50.0))]
    assert 47.5 < crossing[1] < 52.5


def test_a_goal_below_the_lowest_altitude_flown_has_a_way():
    """A goal behind the wall 1.5 m up, under the agents' 5 m ``min_altitude``: the ways keep
    down to it (its height less the radius the safety filter sweeps the agent with: its 1 m body
    and its 0.2 m margin), so its cell lies in free space and the way from behind the wall ends
    there."""
    world = wall_world(goal=(70.0, 20.0, 1.5))
    params = AgentParams.from_world(world)
    guide = G.make_guide(world, params)
    assert float(params.radius[0]) == pytest.approx(1.0)
    assert guide.floor == pytest.approx(1.5 - 1.2)
    pos = np.array([[40.0, 20.0, 20.0]])
    goal = np.array([[70.0, 20.0, 1.5]])
    guide.targets(0, np.array([0]), pos, goal, goal.copy(), np.ones(1))
    assert guide.guided[0] and np.isfinite(guide.way_length(pos, goal)[0])
    source = guide._source[int(guide._rows_for(guide.cell_of(goal), pos, goal)[0])]
    assert guide.free[source]
    assert np.abs(guide.ijk[source] - guide.ijk[guide.cell_of(goal)[0]]).max() <= 1


def test_a_goal_with_no_free_cell_near_it_takes_the_nearest_free_one():
    """No free cell within two of the goal's (a block of cells marked not free): the search
    starts from the free cell of the first ring that has one nearest the goal's cell."""
    world = wall_world(goal=(70.0, 20.0, 20.0))
    guide = G.make_guide(world, AgentParams.from_world(world))
    cell = int(guide.cell_of(np.array([[70.0, 20.0, 20.0]]))[0])
    at = guide.ijk[cell]
    block = (np.abs(guide.ijk - at) <= 2).all(axis=1)
    guide.free = guide.free & ~block
    source = guide._source_of(cell, np.array([70.0, 20.0, 20.0]))
    assert guide.free[source] and np.abs(guide.ijk[source] - at).max() == 3
    ring = np.flatnonzero(guide.free & (np.abs(guide.ijk - at).max(axis=1) == 3))
    gaps = np.linalg.norm(guide.centres[ring] - guide.centres[cell], axis=1)
    assert np.linalg.norm(guide.centres[source] - guide.centres[cell]) == gaps.min()


def test_an_agent_with_a_clear_line_flies_at_its_goal():
    world = wall_world()
    guide = G.make_guide(world, AgentParams.from_world(world))
    pos = np.array([[10.0, 20.0, 20.0]])
    goal = np.array([[40.0, 20.0, 20.0]])
    target, scale = guide.targets(0, np.array([0]), pos, goal, goal.copy(), np.ones(1))
    assert not guide.guided[0]
    np.testing.assert_array_equal(target, goal)
    assert scale[0] == 1.0


def test_opposing_ways_through_a_gap_take_separate_lanes():
    """Two flows through the gap in opposite directions: their ways cross the wall apart."""
    world = wall_world()
    guide = G.make_guide(world, AgentParams.from_world(world))
    east_goal, west_goal = np.array([[70.0, 50.0, 20.0]]), np.array([[30.0, 50.0, 20.0]])
    east = guide._rows_for(guide.cell_of(east_goal), west_goal, east_goal)
    west = guide._rows_for(guide.cell_of(west_goal), east_goal, west_goal)

    def crossing(row, start):
        way = guide.centres[guide._way(int(row[0]), int(guide.cell_of(np.array([start]))[0]))]
        return way[np.argmin(np.abs(way[:, 0] - 50.0))]

    a, b = crossing(east, [30.0, 50.0, 20.0]), crossing(west, [70.0, 50.0, 20.0])
    assert np.linalg.norm(a[1:] - b[1:]) >= min(guide.cell[1:]) - 1e-9


# A box that flies into the wall's gap and parks there for good at t = 5 s.
PLUG = {
    "id": "plug",
    "shape": "box",
    "size": [2, 8, 60],
    "position": [50, 90, 25],
    "motion": {"type": "waypoints", "waypoints": [[50, 50, 25]], "speed": 8, "loop": False},
}


def test_a_mover_parked_for_good_joins_the_bodies_at_rest():
    world = make_world(base_world(obstacles=WALL + [PLUG]))
    (mover,) = world.moving_obstacles
    assert motion.parks_at(mover) == pytest.approx(40.0 / 8.0)
    assert [o.id for o in motion.resting_bodies(world, 4.9)] == ["south", "north"]
    rest = motion.resting_bodies(world, 5.0)
    assert [o.id for o in rest] == ["south", "north", "plug"] and rest[-1].motion is None
    np.testing.assert_allclose(rest[-1].position, [50, 50, 25])
    assert motion.next_rest(world, 0.0) == pytest.approx(5.0) and motion.next_rest(world, 5.0) == np.inf


def test_the_simulation_goes_round_a_mover_from_the_step_it_parks():
    world = make_world(
        base_world(obstacles=WALL + [PLUG], agents=[{"id": "a", "start": [30, 20, 20], "goal": [70, 20, 20]}])
    )
    sim = Simulation(world, planner="none")
    for run in range(2):  # a second run starts again from the bodies at rest at 0
        sim.reset(seed=0)
        seen = []
        while sim.state.t < 5.35:
            seen.append((round(sim.state.t, 6), len(sim.guide.bodies)))
            sim.step()
        before = [n for t, n in seen if t < 5.0 - 1e-9]
        after = [n for t, n in seen if t > 5.0 + 1e-9]
        assert set(before) == {2} and set(after) == {3}, run  # the plug joins when it parks
        assert sim.navigator.guide is sim.guide


def test_pure_apf_goes_round_the_wall_through_the_gap():
    """The agent behind the wall (a local minimum of the bare field) arrives, without contact."""
    world = wall_world(start=(30.0, 20.0, 20.0), goal=(70.0, 20.0, 20.0))
    sim = Simulation(world, planner="none")
    sim.reset(seed=0)
    while True:
        r = sim.step()
        if r.terminated or r.truncated:
            break
    s = sim.summary()
    assert s["success"] and s["collisions"] == 0


@pytest.mark.parametrize("planner", ["world", "none"])
def test_doorway_swap_every_agent_home(planner):
    _assert_home("doorway", 16, planner)


@pytest.mark.slow
@pytest.mark.parametrize("planner", ["world", "none"])
@pytest.mark.parametrize("name", ["doorway", "sphere_pillars"])
def test_static_obstacle_scenarios_every_agent_home_at_64(name, planner):
    _assert_home(name, 64, planner)
