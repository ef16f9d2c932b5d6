"""Goals anywhere reachable are reached, at every scale, with defaults from the agent.

The worlds are the ones a lab or a field team writes first: a goal a few metres above the
ground with a tight tolerance, a 5 cm drone in a room, a quadrotor's goal 1 m up. Every
default (influence, repulsion gain, quadratic radius, floor, separation, tolerance) comes
from the agents, so none of these sets a planner key.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import audit, make_world, run_to_end

from swarmplan.world import WorldError
from swarmplan.world.schema import default_min_altitude


def _single(bounds, start, goal, radius, speed, accel, tolerance, dt=0.1, max_time=60.0, **agent):
    return {
        "name": "one",
        "bounds": {"min": [float(v) for v in bounds[0]], "max": [float(v) for v in bounds[1]]},
        "sim": {"dt": dt, "max_time": max_time, "goal_tolerance": tolerance},
        "agent_defaults": {
            "model": "multirotor",
            "radius": radius,
            "speed": {"min": 0, "max": speed, "cruise": speed},
            "max_accel": accel,
            **agent,
        },
        "agents": [{"id": "a", "start": list(start), "goal": list(goal)}],
        "planner": {"optimizer": {"name": "none"}},
        "log": {"foxglove": False},
    }


CASES = {
    # a 5 m/s drone descending to a goal 6 m up (its default floor is 2.9 m), tolerance 0.3 m
    "field_goal_6m": (((-20, -20, 0), (20, 20, 25)), (-10, 0, 20), (10, 0, 6), 0.4, 5.0, 4.0, 0.3),
    # a 5 cm lab drone at 0.8 m/s in a 4 x 4 x 2 m room, tolerance 5 cm
    "lab_room": (((0, 0, 0), (4, 4, 2)), (0.8, 0.8, 0.3), (3.2, 3.2, 1.0), 0.05, 0.8, 2.0, 0.05),
    # the same drone in a 40 m room (the room's size must not matter)
    "lab_big_room": (((0, 0, 0), (40, 40, 20)), (0.8, 0.8, 0.3), (3.2, 3.2, 1.0), 0.05, 0.8, 2.0, 0.05),
    # an indoor quadrotor to a goal 1 m up, tolerance 0.2 m
    "hall_goal_1m": (((0, 0, 0), (20, 20, 6)), (3, 3, 2), (15, 12, 1.0), 0.25, 1.5, 2.0, 0.2),
    # a goal half a metre above the ground
    "goal_half_metre_up": (((0, 0, 0), (30, 30, 10)), (5, 5, 4), (25, 20, 0.5), 0.2, 3.0, 3.0, 0.1),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_goal_near_the_ground_is_reached_at_every_scale(name, tmp_path):
    bounds, start, goal, radius, speed, accel, tol = CASES[name]
    straight = math.dist(start, goal)
    raw = _single(bounds, start, goal, radius, speed, accel, tol, max_time=3 * straight / speed + 30)
    world = make_world(raw)
    _, summary, _ = run_to_end(world, seed=0, log_path=tmp_path / "run.mcap")
    agent = summary["agents"][0]
    assert agent["arrived"], f"{name}: stopped {agent.get('distance_to_goal')} m from its goal"
    assert agent["collisions"] == 0
    # a straight flight with braking: within the straight-line time at cruise plus the two ramps
    assert agent["arrival_time"] <= straight / speed + 2 * speed / accel + 2.0
    assert agent["max_lateral_accel"] <= accel * (1 + 1e-6)
    problems, _, _ = audit(tmp_path / "run.mcap")
    assert problems == []


def test_defaults_come_from_the_agent():
    raw = _single(((0, 0, 0), (4, 4, 2)), (1, 1, 0.5), (3, 3, 1.0), 0.05, 0.8, 2.0, 0.05)
    del raw["sim"]["goal_tolerance"]
    w = make_world(raw)
    apf = w.planner_config.apf
    rho0 = 2 * 0.8**2 / 2.0  # four braking distances from cruise
    assert apf.influence == pytest.approx(rho0)
    assert apf.k_rep == pytest.approx(0.5 * rho0**2)
    assert apf.quadratic_radius == pytest.approx(rho0)
    a = w.agents[0]
    assert a.min_altitude == pytest.approx(0.8**2 / 4.0 + 0.05)
    assert np.allclose(a.separation, [0.1, 0.1, 0.1])
    assert w.goal_tolerance == pytest.approx(0.05)
    # at an influence of 10 m the scaled gains are the classic 50 and 10 m
    field = _single(((0, 0, 0), (100, 100, 50)), (10, 10, 20), (90, 90, 20), 0.5, 5.0, 5.0, 2.0)
    apf = make_world(field).planner_config.apf
    assert (apf.influence, apf.k_rep, apf.quadratic_radius) == (10.0, 50.0, 10.0)


def test_fixed_wing_defaults():
    params = {
        "model": "fixed_wing",
        "radius": 2.0,
        "speed": {"min": 15, "max": 30, "cruise": 20},
        "max_accel": 3,
        "min_turn_radius": 40.0,
        "max_climb_angle": 30.0,
    }
    assert default_min_altitude(params) == pytest.approx(40.0 * (1 - math.cos(math.radians(30))) + 2.0)
    raw = _single(((0, 0, 0), (1000, 1000, 200)), (100, 100, 80), (900, 900, 80), 2.0, 20, 3, 1.0)
    raw["agent_defaults"] = {**params}
    del raw["sim"]["goal_tolerance"]
    assert make_world(raw).goal_tolerance == pytest.approx(10.0)


@pytest.mark.parametrize("key", ["start", "goal"])
def test_overlapping_agents_are_refused_naming_both(key):
    raw = _single(((0, 0, 0), (20, 20, 10)), (2, 2, 3), (15, 15, 3), 0.4, 3.0, 3.0, 0.3)
    other = {"id": "b", "start": [10, 2, 3], "goal": [2, 15, 3]}
    other[key] = [v + d for v, d in zip(raw["agents"][0][key], (0.5, 0.0, 0.0), strict=True)]
    raw["agents"].append(other)
    with pytest.raises(WorldError) as err:
        make_world(raw)
    text = str(err.value)
    assert f"agents[0].{key}: overlaps agent 'b'" in text
    assert "0.5 m apart" in text and "0.8 m" in text
    # just clear of each other: accepted
    other[key] = [v + d for v, d in zip(raw["agents"][0][key], (0.81, 0.0, 0.0), strict=True)]
    make_world(raw)


def test_a_stuck_agent_gets_its_optimizer_after_one_stood_down_window(monkeypatch):
    """Whatever a gate says, an agent still stuck a window later is offered an escape."""
    from helpers import default_planner

    from swarmplan.io.runner import run_episode
    from swarmplan.planner import escape_gates
    from swarmplan.sim import Simulation

    # the U-shaped pocket: the bare field holds the agent in front of the wall
    raw = _single(((0, 0, 0), (60, 40, 30)), (10, 20, 15), (50, 20, 15), 1.0, 7.0, 4.0, 2.0)
    raw["obstacles"] = [
        {"id": "back", "shape": "box", "size": [2, 24, 20], "position": [30, 20, 15]},
        {"id": "top", "shape": "box", "size": [12, 2, 20], "position": [25, 31, 15]},
        {"id": "bottom", "shape": "box", "size": [12, 2, 20], "position": [25, 9, 15]},
    ]
    raw["planner"] = {"optimizer": {"name": "pso", "population": 10, "iterations": 20},
                      "apf": {"guide": False}}  # fmt: skip
    raw["sim"]["max_time"] = 20.0
    world = make_world(raw)
    monkeypatch.setattr(escape_gates, "stand_down_gate", lambda *args: "crowd")
    kinds: list[str] = []
    runs: list[int] = []

    class Events:
        def on_reset(self, result):
            pass

        def on_step(self, result):
            kinds.extend(e.kind for e in result.events)
            if result.optimizer_runs and not runs:
                runs.append(len(result.optimizer_runs))

    sim = Simulation(world, planner=default_planner(world))
    run_episode(sim, 0, observers=[Events()])
    # the first stuck window stood down by the (forced) gate, the second offered the optimizer
    offered = ("escape_start", "escape_deferred", "hold")
    assert kinds[:2] == ["stuck", "escape_stood_down"], kinds[:6]
    assert kinds[2] == "stuck" and kinds[3] in offered, kinds[:6]
    assert runs and runs[0] > 0, "no optimizer run was recorded"


def test_overlaps_found_in_a_large_swarm():
    """Above 64 agents the pairs come from a k-d tree: the same answer as every pair."""
    raw = _single(((0, 0, 0), (100, 100, 20)), (1, 1, 5), (99, 99, 5), 0.4, 3.0, 3.0, 0.3)
    raw["agents"] = [
        {"id": f"a{k}", "start": [5.0 + 2 * (k % 10), 5.0 + 2 * (k // 10), 5.0],
         "goal": [5.0 + 2 * (k % 10), 80.0 - 2 * (k // 10), 5.0]}
        for k in range(70)
    ]  # fmt: skip
    make_world(raw)
    raw["agents"][69]["start"] = [5.3, 5.0, 5.0]  # onto a0's start
    with pytest.raises(WorldError) as err:
        make_world(raw)
    assert str(err.value).count("overlaps agent") == 1
    assert "agents[0].start: overlaps agent 'a69'" in str(err.value)
