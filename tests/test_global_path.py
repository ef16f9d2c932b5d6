"""plan_global_routes: config validation, a valid plan, the FCL-checked fallback."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.planner import RefinementPlanner
from swarmplan.planner.global_path import global_config, plan_global_routes
from swarmplan.sim import Simulation
from swarmplan.world import WorldError, parse_world

TOWER = [{"id": "tower", "shape": "cylinder", "radius": 12, "height": 60, "position": [100, 50, 30]}]


def _world(glob=None, obstacles=None):
    return parse_world(
        {
            "name": "g",
            "bounds": {"min": [0, 0, 0], "max": [200, 100, 60]},
            "obstacles": obstacles
            if obstacles is not None
            else [
                {"id": "tower", "shape": "cylinder", "radius": 12, "height": 60, "position": [100, 50, 30]}
            ],
            "agent_defaults": {"radius": 1.0, "min_altitude": 5},
            "agents": [{"id": "a", "start": [10, 50, 20], "goal": [190, 50, 20]}],
            "planner": {
                "mode": "global",
                "global": glob or {"cost": "mcfo", "waypoints": 6},
                "apf": {"influence": 6.0},
                "optimizer": {"name": "rscdwoa", "population": 20, "iterations": 40},
            },
        }
    )


@pytest.mark.parametrize(
    "glob, fragment",
    [
        ({"cost": "nope"}, "planner.global.cost"),
        ({"encoding": "bezier"}, "planner.global.encoding"),
        ({"waypoints": 0}, "planner.global.waypoints"),
        ({"waypoints": 2.5}, "whole number"),
        ({"lateral": -1}, "planner.global.lateral"),
        ({"colour": 1}, "planner.global.colour: unknown key"),
        ({"weights": {"w9": 1}}, "planner.global.weights.w9"),
        ({"weights": {"w1": 0.9}}, "w1 + w2 + w3 must be 1"),
        ({"cost": "iafsa", "weights": {"alpha1": 0.9}}, "alpha1 + alpha2"),
        ({"warm_start": "yes"}, "planner.global.warm_start: expected true or false"),
    ],
)
def test_bad_config_is_reported(glob, fragment):
    with pytest.raises(WorldError) as exc:
        global_config(_world(glob))
    assert any(fragment in p for p in exc.value.problems), exc.value.problems


def test_defaults():
    cfg = global_config(_world({"cost": "iafsa"}))
    assert cfg.encoding == "spline" and cfg.waypoints == 8


@pytest.mark.parametrize("cost", ["mcfo", "iba", "iafsa"])
def test_plan_is_valid_and_recorded(cost):
    w = _world({"cost": cost, "waypoints": 6})
    sim = Simulation(w, planner="none")
    sim.reset(3)
    routes = plan_global_routes(sim, "rscdwoa")
    assert list(routes) == [0]
    route = routes[0]
    assert np.allclose(route[-1], w.agents[0].goal)
    # FCL: the flown route from the start touches nothing static.
    path = np.vstack([w.agents[0].start, route])
    for p0, p1 in zip(path[:-1], path[1:], strict=True):
        assert sim.collision.first_hit(p0, p1, 1.0, np.zeros((0, 3)), np.zeros((0, 3))) is None
    # Planned after reset: the run and the events go out with the next step's result.
    r = sim.step()
    assert [m.purpose for m in r.optimizer_runs] == ["global"]
    assert r.optimizer_runs[0].evaluations == 20 * 40 and r.optimizer_runs[0].t == 0.0
    assert [e.kind for e in r.events if e.kind.startswith("global")] == ["global_plan"]
    assert sim.step().optimizer_runs == []


def test_impossible_plan_falls_back_with_an_event():
    wall = [{"id": "wall", "shape": "box", "size": [4, 100, 60], "position": [100, 50, 30]}]
    w = _world(obstacles=wall)
    sim = Simulation(w, planner="none")
    sim.reset(0)
    assert plan_global_routes(sim, "random") == {}
    r = sim.step()
    event = r.events[0].to_json()
    assert event["kind"] == "global_plan_invalid"
    assert "no route" in event["detail"]["fallback"]
    # Planned again before giving up: 1 + retries runs, the budget growing by 1.5 each time.
    assert event["detail"]["attempts"] == 3
    assert [m.to_json()["evaluations"] for m in r.optimizer_runs] == [800, 1200, 1800]


def test_sim_flies_the_route_to_arrival():
    w = _world()
    sim = Simulation(w, planner=RefinementPlanner(w, "rscdwoa"))
    sim.reset(1)
    assert sim.state.route[0] is not None
    while True:
        r = sim.step()
        if r.terminated or r.truncated:
            break
    s = sim.summary()
    assert s["success"], s


def test_shortcut_prunes_free_detours_and_keeps_the_one_around_the_tower():
    from swarmplan.planner.global_path import shortcut_path

    w = _world()
    sim = Simulation(w, planner="none")
    sim.reset(0)
    # Free zig-zag before the tower, then round it (y = 75: 25 m from its axis), then to the goal.
    path = np.array(
        [[10, 50, 20], [30, 80, 20], [50, 20, 20], [70, 75, 20], [100, 75, 20], [130, 75, 20], [190, 50, 20]],
        float,
    )
    out = shortcut_path(sim, 0, path, 1.0)
    # The zig-zag vertices are skippable; the legs that pass the tower must stay 25 m off its
    # axis, which start → goal does not.
    np.testing.assert_array_equal(out[0], path[0])
    np.testing.assert_array_equal(out[-1], path[-1])
    assert len(out) < len(path)
    for a, b in zip(out[:-1], out[1:], strict=True):
        assert sim.collision.sweep_static(a, b, 2.0) is None
    # Straight start → goal hits the tower, so at least one vertex stays.
    assert sim.collision.sweep_static(path[0], path[-1], 2.0) == "tower"
    assert len(out) >= 3
    # A path with nothing to prune is unchanged.
    np.testing.assert_array_equal(shortcut_path(sim, 0, out, 1.0), out)


def test_shortcut_respects_the_climb_angle():
    from swarmplan.planner.global_path import shortcut_path

    w = _world(obstacles=[])
    sim = Simulation(w, planner="none")
    sim.reset(0)
    # Two 20° legs in line: the direct leg also climbs 20° (max 45°), so the middle vertex goes.
    path = np.array([[10, 50, 20], [20, 50, 23.64], [30, 50, 27.28]], float)
    assert len(shortcut_path(sim, 0, path, 1.0)) == 2
    # A shallow leg, then a steep one: the direct leg would climb 55° > 45°, so the vertex stays.
    steep = np.array([[10, 50, 10], [30, 50, 17], [31, 50, 40]], float)
    assert len(shortcut_path(sim, 0, steep, 1.0)) == 3


def test_warm_start_rows_are_the_straight_line_and_smooth_detours():
    from swarmplan.planner.encodings import PlaneEncoding

    enc = PlaneEncoding(
        np.array([0.0, 0.0, 10.0]),
        np.array([100.0, 0.0, 10.0]),
        5,
        40.0,
        20.0,
        np.zeros(3),
        np.full(3, 200.0),
    )
    X = enc.warm_start()
    assert X.shape == (9, enc.dim)
    assert np.all(X >= enc.lower) and np.all(X <= enc.upper)
    nodes = enc.decode(X)
    # Row 0: every waypoint on the straight line start -> goal.
    assert np.allclose(nodes[0, :, 1], 0.0) and np.allclose(nodes[0, :, 2], 10.0)
    # The widest lateral detour peaks at the full lateral range mid-way, both sides.
    assert np.max(np.abs(X[3, : enc.D])) == pytest.approx(40.0 * np.sin(np.pi * 3 / 6))
    assert np.allclose(X[3], -X[6])
