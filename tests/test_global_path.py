"""plan_global_routes: config validation, a valid plan, the FCL-checked fallback."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.planner.global_path import GlobalRoutePlanner, global_config, plan_global_routes
from swarmplan.sim import Simulation
from swarmplan.world import WorldError, parse_world


class _Rec:
    def __init__(self):
        self.events, self.optimizer = [], []

    def write_event(self, e):
        self.events.append(e)

    def write_optimizer(self, m):
        self.optimizer.append(m)

    def write_world(self, *a):
        pass

    def write_state(self, *a):
        pass


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
    rec = _Rec()
    sim = Simulation(w, recorder=rec)
    sim.reset(3)
    routes = plan_global_routes(sim, "rscdwoa", sim.rng)
    assert list(routes) == [0]
    route = routes[0]
    assert np.allclose(route[-1], w.agents[0].goal)
    # FCL: the flown route from the start touches nothing static.
    path = np.vstack([w.agents[0].start, route])
    for p0, p1 in zip(path[:-1], path[1:], strict=True):
        assert sim.collision.first_hit(p0, p1, 1.0, np.zeros((0, 3)), np.zeros((0, 3))) is None
    assert [m["purpose"] for m in rec.optimizer] == ["global"]
    assert rec.optimizer[0]["evaluations"] == 20 * 40
    assert [e["kind"] for e in rec.events] == ["global_plan"]


def test_impossible_plan_falls_back_with_an_event():
    wall = [{"id": "wall", "shape": "box", "size": [4, 100, 60], "position": [100, 50, 30]}]
    w = _world(obstacles=wall)
    rec = _Rec()
    sim = Simulation(w, recorder=rec)
    sim.reset(0)
    assert plan_global_routes(sim, "random", sim.rng) == {}
    assert rec.events[0]["kind"] == "global_plan_invalid"
    assert "no route" in rec.events[0]["detail"]["fallback"]
    # Planned again before giving up: 1 + retries runs, the budget growing by 1.5 each time.
    assert rec.events[0]["detail"]["attempts"] == 3
    assert [m["evaluations"] for m in rec.optimizer] == [800, 1200, 1800]


def test_sim_flies_the_route_to_arrival():
    w = _world()
    sim = Simulation(w, planner=GlobalRoutePlanner(w, "rscdwoa"))
    sim.reset(1)
    assert sim.state.route[0] is not None
    while True:
        r = sim.step()
        if r.terminated or r.truncated:
            break
    s = sim.summary()
    assert s["success"], s
