"""The ground's push near the ground (swarmplan.flight.field_law.ground_range) and agents passing
each other low over it: exact ranges from the agent, and RMADER's circle swap flown 1 m up home
in about the straight line's time, its 32 agents all home."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.bench.swarm_runs import run_swarmplan
from swarmplan.bench.swarm_scenarios import RMADER_ACCEL, RMADER_CIRCLE, RMADER_RADIUS, RMADER_SPEED
from swarmplan.flight.field_law import ground_range
from swarmplan.world.schema import default_min_altitude


def test_the_ground_holds_a_multirotor_at_its_floor_lowered_to_its_goal():
    r, floor = 0.4, 2.2
    # a goal above the floor: the clearance at the floor
    assert ground_range(7.0, floor, 10.0, r) == pytest.approx(floor - r)
    # a goal below it: the clearance at the goal's height, at least the radius
    assert ground_range(7.0, floor, 1.5, r) == pytest.approx(1.5 - r)
    assert ground_range(7.0, floor, 0.7, r) == pytest.approx(r)
    assert ground_range(7.0, floor, 0.45, r) == pytest.approx(r)
    # per agent, and a fixed wing keeps the influence down to three floors, at least a quarter
    got = ground_range(40.0, np.array([2.2, 5.0, 5.0]), np.array([9.0, 9.0, 1.0]), np.array([0.4, 1.0, 1.0]),
                       np.array([True, True, False]))  # fmt: skip
    np.testing.assert_allclose(got, [1.8, 4.0, 15.0])
    assert ground_range(40.0, 1.0, 9.0, 1.0, False) == pytest.approx(10.0)


def test_the_default_floor_is_the_braking_height():
    """Left out, ``min_altitude`` is the braking distance from cruise plus the radius: the range of
    the ground on an agent with a goal above it is its braking distance."""
    params = {"model": "multirotor", "speed": {"cruise": RMADER_SPEED}, "max_accel": RMADER_ACCEL,
              "radius": RMADER_RADIUS}  # fmt: skip
    floor = default_min_altitude(params)
    brake = RMADER_SPEED**2 / (2.0 * RMADER_ACCEL)
    assert ground_range(7.0, floor, 10.0, RMADER_RADIUS) == pytest.approx(brake)


def test_rmader_circle_one_metre_up_flies_about_the_straight_line():
    """10 agents 1 m up (below their 2.19 m floor, goals at 1 m): every agent home, no contact, the
    last within the straight line at cruise plus a start and a stop at ``max_accel`` (the ground
    no longer lifts them to its floor's push range and back down)."""
    row, _ = run_swarmplan("rmader_circle_1m", 10, 0, "planner")
    assert row.arrived == 10 and row.collisions == 0
    bound = 2.0 * RMADER_CIRCLE / RMADER_SPEED + 2.0 * RMADER_SPEED / RMADER_ACCEL
    assert row.last_arrival <= bound
    assert row.path_ratio < 1.05


@pytest.mark.parametrize("seed", [0, 2])
def test_rmader_circle_one_metre_up_32_agents_all_home(seed):
    """32 agents 1 m up: an agent pressed low under another is pushed aside, not down, and slides
    out from under it (the two held each other there for good)."""
    row, _ = run_swarmplan("rmader_circle_1m", 32, seed, "planner")
    assert row.arrived == 32 and row.collisions == 0
