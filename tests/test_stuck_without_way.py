"""An agent whose goal no way reaches (a wall across the whole world): its ``stuck`` events say
so (``distance_to_go`` infinite, ``progress`` not a number: nothing measurable) while
``distance_to_goal`` stays the straight distance, and the run warns of nothing."""

from __future__ import annotations

import math
import warnings

from helpers import base_world, make_world

from swarmplan.sim import Simulation


def test_stuck_without_a_way_warns_of_nothing():
    wall = {"id": "wall", "shape": "box", "size": [4, 120, 70], "position": [50, 50, 25]}
    world = make_world(base_world(sim={"dt": 0.1, "max_time": 12, "goal_tolerance": 2.0}, obstacles=[wall]))
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
    assert len(stuck) >= 2
    for d in stuck:
        assert d["distance_to_go"] == math.inf and math.isnan(d["progress"])
        assert 40.0 < d["distance_to_goal"] < 80.0  # the straight distance: finite
