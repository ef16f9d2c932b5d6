"""Deconfliction at every scale: each agent keeps a safety margin scaled to its own body, a pair
already that close that parts is let go (never frozen for good), and a lab swarm swapping its
take-off grid through the room's centre gets every agent home without contact."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import fly_metered, make_world, run_to_end

from swarmplan.bench import swarm_scenarios as S
from swarmplan.bench.swarm_runs import ContactMeter
from swarmplan.flight.kinematics import MAX_MARGIN, safety_margin
from swarmplan.sim import Simulation


def test_the_safety_margin_follows_the_body():
    r = np.array([0.05, 0.5, 1.0, 5.0])
    assert safety_margin(r) == pytest.approx([0.01, 0.1, 0.2, MAX_MARGIN])


def _pair(gap: float, radius: float) -> dict:
    """Two multirotors of ``radius`` whose centres start ``gap`` apart on x, flying apart along
    x to goals 2 m away each."""
    return {
        "name": "pair",
        "bounds": {"min": [-4.0, -2.0, 0.0], "max": [4.0, 2.0, 3.0]},
        "sim": {"dt": 0.05, "max_time": 20.0, "goal_tolerance": radius},
        "agent_defaults": {
            "model": "multirotor",
            "radius": radius,
            "speed": {"min": 0.0, "max": 1.0, "cruise": 1.0},
            "max_accel": 2.0,
            "separation": [0.0, 0.0, 0.0],
        },
        "agents": [
            {"id": "a", "start": [-gap / 2, 0.0, 1.5], "goal": [-gap / 2 - 2.0, 0.0, 1.5]},
            {"id": "b", "start": [gap / 2, 0.0, 1.5], "goal": [gap / 2 + 2.0, 0.0, 1.5]},
        ],
        "planner": {"optimizer": {"name": "none"}},
        "log": {"foxglove": False},
    }


@pytest.mark.parametrize("radius", [0.05, 0.5])
def test_a_pair_inside_its_margins_parts_and_flies_home(radius, tmp_path):
    """Centres a hair's breadth more than two bodies apart: inside both safety margins. The pair
    parts; stopping it there would freeze it for good."""
    gap = 2.0 * radius + 0.5 * safety_margin(radius)
    _, summary, pos = run_to_end(make_world(_pair(gap, radius)), seed=0, log_path=tmp_path / "run.mcap")
    assert summary["arrived"] == 2 and summary["collisions"] == 0, summary
    assert all(a["emergency_stops"] == 0 for a in summary["agents"]), summary["agents"]
    d = np.linalg.norm(np.array(pos)[:, 0] - np.array(pos)[:, 1], axis=1)
    assert np.all(np.diff(d) >= -1e-12)  # never closer than they started


def _fly(raw: dict, seed: int) -> tuple[Simulation, ContactMeter]:
    sim = Simulation(make_world(raw))
    return sim, fly_metered(sim, seed)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_lab_room_swaps_its_grid_with_every_agent_home(seed):
    """Eight 5 cm drones (1 m/s, 2 m/s², tolerance their radius) 0.5 m apart swap their take-off
    grid through its centre, a downwash ellipsoid as their separation: every agent home, no
    contact, no emergency stop, within the straight flight's time plus a few seconds."""
    raw = S.crazyswarm_room(8, seed)
    sim, meter = _fly(raw, seed)
    s = sim.summary()
    assert s["arrived"] == 8, [(a["id"], a["final_mode"]) for a in s["agents"] if not a["arrived"]]
    assert s["collisions"] == 0 and not meter.pairs and meter.min_gap > 0.0
    assert all(a["emergency_stops"] == 0 for a in s["agents"])
    straight = max(np.linalg.norm(np.subtract(a["goal"], a["start"])) for a in raw["agents"])
    assert sim.state.t <= straight / S.CRAZYFLIE_SPEED + 5.0
