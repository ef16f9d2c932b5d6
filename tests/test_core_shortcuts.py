"""Shortcuts and arcs that prune a planned segment keep out of the threat cores a world avoids
(``threats[i].avoid``), as they keep out of obstacles: exact geometry on a straight leg."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.planner.cores import avoided_cores, core_hit
from swarmplan.planner.escape import EscapePlanner
from swarmplan.planner.global_path import shortcut_path
from swarmplan.sim import Simulation

# A detour around a core above the straight leg y = 50 from (10, 50, 20) to (90, 50, 20).
DETOUR = np.array([[10.0, 50.0, 20.0], [50.0, 35.0, 20.0], [90.0, 50.0, 20.0]])
R_MIN = 5.0
CLEAR = R_MIN + 1.0 + 1.0  # r_min + the agent's radius (1 m) + the pruning margin (1 m)


def _sim(core_y: float, avoid: bool = True) -> Simulation:
    threat = {
        "kind": "radar",
        "position": [50.0, core_y, 20.0],
        "r_min": R_MIN,
        "r_max": 15.0,
        "avoid": avoid,
    }
    sim = Simulation(make_world(base_world(threats=[threat])), planner="none")
    sim.reset(seed=0)
    return sim


@pytest.mark.parametrize(("offset", "kept"), [(CLEAR - 0.01, 3), (CLEAR + 0.01, 2)])
def test_escape_shortcut_keeps_out_of_an_avoided_core(offset, kept):
    # The straight leg passes the core's centre at ``offset``: just inside or just outside
    # r_min + radius + margin.
    sim = _sim(50.0 + offset)
    out = EscapePlanner(sim.world, "pso").shortcut(sim, 0, DETOUR, start_clearance=np.inf)
    assert len(out) == kept, out
    if kept == 3:
        np.testing.assert_array_equal(out, DETOUR)


def test_a_core_that_is_not_avoided_does_not_stop_the_shortcut():
    sim = _sim(50.0, avoid=False)
    out = EscapePlanner(sim.world, "pso").shortcut(sim, 0, DETOUR, start_clearance=np.inf)
    np.testing.assert_array_equal(out, DETOUR[[0, 2]])


@pytest.mark.parametrize(("offset", "kept"), [(CLEAR - 0.01, 3), (CLEAR + 0.01, 2)])
def test_global_route_pruning_keeps_out_of_an_avoided_core(offset, kept):
    sim = _sim(50.0 + offset)
    assert len(shortcut_path(sim, 0, DETOUR, inflate=1.0)) == kept


def test_core_hit_exact_geometry():
    world = _sim(50.0).world
    (centres, radii, names) = avoided_cores(world)
    assert names == ("threats[0]",) and radii.tolist() == [R_MIN]
    a, b = np.array([10.0, 56.0, 20.0]), np.array([90.0, 56.0, 20.0])  # passes 6 m from the centre
    assert core_hit(world, a, b, 0.99) is None  # 5 + 0.99 < 6
    assert core_hit(world, a, b, 1.01) == "threats[0]"
    # A leg that starts beside the core (closer than r_min + r) enters it only by getting closer.
    near = np.array([50.0, 53.0, 20.0])  # 3 m from the centre: inside r_min
    assert core_hit(world, near, np.array([50.0, 90.0, 20.0]), 1.0) is None  # straight out
    assert core_hit(world, near, np.array([50.0, 10.0, 20.0]), 1.0) == "threats[0]"  # deeper in
