"""A multirotor already within its safety margin of a surface (an approach rounded inside it)
is not frozen there: the safety filter lets it take the steps that keep it at least as clear as
staying put, and still refuses the steps closer."""

from __future__ import annotations

import numpy as np
from helpers import base_world, make_world

from swarmplan.flight.kinematics import safety_margin
from swarmplan.sim import Simulation
from swarmplan.sim.braking import keeping_clearance

# A box whose face x = 50 looks west; the agent (radius 1 m, margin 0.2 m) floats west of it.
BOX = [{"id": "box", "shape": "box", "size": [10, 10, 10], "position": [55, 50, 20]}]


def _filter():
    world = make_world(base_world(obstacles=BOX))
    sim = Simulation(world)
    sim.reset(0)
    q0 = sim.obstacles.poses(0.0)[0]
    return sim.safety, q0, float(safety_margin(np.array([1.0]))[0])


def test_inside_the_margin_steps_away_and_along_are_kept_and_closer_refused():
    safety, q, margin = _filter()
    p0 = np.array([50.0 - 1.0 - 0.5 * margin, 50.0, 20.0])  # half its margin off the face
    away, along, closer = np.array([-1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0.5, 0, 0])
    # With the whole margin, every step touches, staying put too.
    ends = p0 + np.array([away, along, closer, [0, 0, 0]]) * 0.1
    radii = np.full(4, 1.0 + margin)
    assert not safety.steps_free(np.repeat(p0[None], 4, 0), ends, radii, q, q).any()
    kept = keeping_clearance(safety, 0, p0, [away, along, closer], (q, q))
    assert [tuple(v) for v in kept] == [tuple(away), tuple(along)]


def test_touching_its_body_nothing_is_kept():
    safety, q, margin = _filter()
    p0 = np.array([50.0 - 0.99, 50.0, 20.0])  # its body inside the box
    assert keeping_clearance(safety, 0, p0, [np.array([-1.0, 0, 0])], (q, q)) == []
