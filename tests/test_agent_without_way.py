"""An agent whose goal no way reaches (a wall across the whole world) hovers in front of it:
its ``stuck`` events measure progress on the straight distance (no way to measure it along),
finite, and the run warns of nothing (no ``inf - inf``); the run table shows its turns as a
multirotor's (lateral acceleration), not as the curvature of millimetre steps."""

from __future__ import annotations

import copy
import math
import warnings

import pytest
from helpers import base_world, make_world

from swarmplan.cli.run import format_summary
from swarmplan.sim import Simulation


@pytest.fixture(scope="module")
def hovering():
    """(stuck events' details, summary) of the agent in front of the wall, warnings as errors."""
    wall = {"id": "wall", "shape": "box", "size": [4, 120, 70], "position": [50, 50, 25]}
    world = make_world(base_world(sim={"dt": 0.1, "max_time": 20, "goal_tolerance": 2.0}, obstacles=[wall]))
    sim = Simulation(world, planner="none")
    stuck = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.reset(seed=0)
        while True:
            r = sim.step()
            stuck += [e.detail for e in r.events if e.kind == "stuck"]
            if r.terminated or r.truncated:
                break
    return stuck, sim.summary()


def test_stuck_without_a_way_warns_of_nothing(hovering):
    stuck, _ = hovering
    assert len(stuck) >= 2
    for d in stuck:
        assert d["distance_to_go"] == d["distance_to_goal"]  # no way round: the straight line
        assert 40.0 < d["distance_to_goal"] < 80.0 and math.isfinite(d["progress"])


def _row(table: str, agent: str) -> list[str]:
    return next(line.split() for line in table.splitlines() if line.startswith(agent + " "))


def test_the_run_table_shows_a_multirotors_turns_as_lateral_acceleration(hovering):
    _, summary = hovering
    a = summary["agents"][0]
    assert a["max_curvature"] > 10.0  # what the log keeps: millimetre steps at the wall
    table = format_summary(summary, None)
    head = table.splitlines()[0]
    assert "max curv 1/m" in head and "curv limit 1/m" in head
    row = _row(table, "a")
    assert row[7:10] == ["-", "-", f"{a['max_lateral_accel']:.2f}/4.00"]
    assert f"{a['max_curvature']:.3g}" not in table and "TURN LIMIT" not in table


def test_a_broken_turn_limit_names_only_the_rules_of_its_models(hovering):
    _, summary = hovering
    rotor = copy.deepcopy(summary)
    rotor["agents"][0]["curvature_violation"] = True
    said = format_summary(rotor, None)
    assert "TURN LIMIT BROKEN (!): a (multirotor: lateral acceleration over 1.05 max_accel)" in said
    assert "fixed wing" not in said
    wing = copy.deepcopy(rotor)
    entry = wing["agents"][0]
    entry.update(lateral_accel_limit=None, max_curvature=0.031, curvature_limit=0.025)
    said = format_summary(wing, None)
    assert "TURN LIMIT BROKEN (!): a (fixed wing: curvature over 1.05 / min_turn_radius)" in said
    assert _row(said, "a")[7:9] == ["0.031", "0.025"] and "multirotor" not in said
