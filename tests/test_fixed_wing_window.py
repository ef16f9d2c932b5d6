"""Fixed wings through a window (``worlds/fixed_wing_window.yaml``: a thin wall, a 40 m x 30 m
opening, 40 m turn radius): the aircraft whose straight line runs through the opening flies
it straight (path within 1.2 x the straight line) whatever the optimizer and seed, the one whose
line the wall blocks lines up with the opening and goes through, left to the field while it
lines up (no escape takes it off its way); nothing is touched."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import run_to_end

from swarmplan.optimizers import available
from swarmplan.planner import make_planner
from swarmplan.world import load_world

WORLD = Path(__file__).resolve().parents[1] / "worlds" / "fixed_wing_window.yaml"


def _fly(optimizer: str | None, seed: int) -> tuple[dict, float]:
    world = load_world(WORLD)
    _, summary, pos = run_to_end(world, seed=seed, planner=make_planner(world, optimizer))
    pos = np.array(pos)[:, 0]
    aligned = summary["agents"][0]
    k = int(round(aligned["arrival_time"] / world.dt)) if aligned["arrived"] else len(pos) - 1
    flown = float(np.linalg.norm(np.diff(pos[: k + 1], axis=0), axis=1).sum())
    return summary, flown / float(np.linalg.norm(world.agents[0].goal - world.agents[0].start))


@pytest.mark.parametrize("seed", [1, 2])
def test_both_fixed_wings_go_through_the_window(seed):
    summary, ratio = _fly(None, seed)
    assert summary["arrived"] == summary["agents_total"] == 2, summary["agents"]
    assert summary["collisions"] == 0
    assert ratio <= 1.2, ratio
    for a in summary["agents"]:
        assert a["min_obstacle_clearance"] >= 0.5 * 10.0 - 1e-6, a  # half the 10 m separation


@pytest.mark.slow
@pytest.mark.parametrize("optimizer", available())
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_both_go_through_and_the_aligned_one_flies_straight_on_every_optimizer_and_seed(optimizer, seed):
    summary, ratio = _fly(optimizer, seed)
    assert summary["arrived"] == summary["agents_total"] == 2, summary["agents"]
    assert summary["collisions"] == 0, summary["agents"]
    assert ratio <= 1.2, ratio


def test_a_fixed_wing_lining_up_with_the_window_is_left_to_the_field():
    """The aircraft whose line the wall blocks turns away from its goal to line up with the
    opening (window after window of no progress): it is left to the field for as long as its
    way and a full circle take at cruise speed; the aligned one, whose line is clear, is not
    lining up."""
    from swarmplan.planner.escape_gates import lining_up
    from swarmplan.sim import Simulation

    world = load_world(WORLD)
    sim = Simulation(world, planner=make_planner(world, None))
    sim.reset(seed=2)
    while sim.state.t < 16.0 - 1e-9:
        sim.step()
    s, sight = sim.state, sim.sight
    assert sight.sighted[1] and not sight.in_sight[1]
    assert np.linalg.norm(s.goal[1] - s.position[1]) > 360.0  # it flew away from its goal
    way = float(sim.guide.way_length(s.position[1][None], s.goal[1][None])[0])
    allowance = (way + 2.0 * np.pi * 40.0) / 22.0
    assert lining_up(sim, 1, s.t)
    assert lining_up(sim, 1, s.t - allowance + 0.05)
    assert not lining_up(sim, 1, s.t - allowance - 0.05)
    assert sight.in_sight[0] and not lining_up(sim, 0, s.t)
