"""The weight of a predicted conflict between agents (``field_law.urgency``): exact values, flat
at the horizon's edge, and what that buys a crowd converging on one point (RMADER's circle): no
agent brakes in the step its conflicts enter the horizon, and the swap is within the travel-time
target of the lab rows on several seeds and altitudes."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.bench.swarm_lab import TRAVEL_TARGET
from swarmplan.bench.swarm_runs import run_swarmplan
from swarmplan.flight.field_law import urgency


def test_urgency_exact_values():
    h = 4.0
    got = urgency(np.array([0.0, 1.0, 2.0, 3.0, 4.0]), h)
    np.testing.assert_allclose(got, [1.0, 0.5625, 0.25, 0.0625, 0.0], atol=1e-8)


def test_urgency_is_flat_at_the_horizon():
    """Its slope at the horizon is zero: a conflict entering the horizon adds second-order
    nothing, where a linear weight added dtau / horizon at once."""
    h = 4.0
    for d in (1e-2, 1e-3, 1e-4):
        assert urgency(np.array([h - d]), h)[0] <= 1.01 * (d / h) ** 2


@pytest.mark.parametrize("altitude, seed", [(1.0, 0), (1.0, 4), (5.0, 5)])
def test_the_circle_swap_is_within_the_travel_target(altitude, seed):
    """10 agents swap across a 10 m circle: all home, no contact, the last at most the lab rows'
    travel-time target."""
    name = f"rmader_circle_{altitude:g}m"
    row, _ = run_swarmplan(name, 10, seed, "planner")
    assert row.arrived == 10 and row.collisions == 0
    assert row.last_arrival <= TRAVEL_TARGET
