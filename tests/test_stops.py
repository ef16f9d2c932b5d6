"""Stops within the acceleration limit: arrival only at a speed one step can stop,
the braking margin that keeps the safety filter's one-step stop rare, and the count of the
hard stops that remain (``/summary`` ``hard_stops``)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world, run_to_end

from swarmplan.sim import Simulation

A_MAX = 4.0  # base_world's max_accel
DT = 0.1


def velocity_jumps(positions: list[np.ndarray], dt: float) -> np.ndarray:
    """|v[k+1] - v[k]| per step and agent, v from the recorded positions (what a vehicle flies)."""
    p = np.array(positions)
    v = np.diff(p, axis=0) / dt
    return np.linalg.norm(np.diff(v, axis=0), axis=2)


def test_arrival_comes_at_a_stoppable_speed_and_no_step_breaks_the_limit():
    w = make_world(base_world())
    sim, summary, pos = run_to_end(w, seed=0)
    a = summary["agents"][0]
    assert a["arrived"] and a["hard_stops"] == 0 and a["emergency_stops"] == 0
    # The whole flight, arrival stop and the frozen steps after it included.
    assert velocity_jumps(pos, w.dt).max() <= A_MAX * DT * (1 + 1e-9)
    k = int(round(a["arrival_time"] / w.dt))
    last_step = np.linalg.norm(pos[k] - pos[k - 1]) / w.dt
    assert 0 < last_step <= A_MAX * DT + 1e-9
    # Braked into the goal: it arrives at its first recorded position inside the tolerance
    # (the replay's convention), already slow enough to stop.
    d = np.linalg.norm(np.array(pos)[:, 0] - w.agents[0].goal, axis=1)
    assert int(np.flatnonzero(d <= w.goal_tolerance)[0]) == k
    assert d[-1] <= w.goal_tolerance


def test_fixed_wings_keep_the_tolerance_rule():
    raw = base_world(
        agents=[
            {
                "id": "fw",
                "start": [10, 50, 20],
                "goal": [90, 50, 20],
                "model": "fixed_wing",
                "speed": {"min": 4, "max": 12, "cruise": 8},
                "min_turn_radius": 10,
            }
        ]
    )
    w = make_world(raw)
    _, summary, pos = run_to_end(w, seed=0)
    a = summary["agents"][0]
    assert a["arrived"]
    k = int(round(a["arrival_time"] / w.dt))
    assert np.linalg.norm(pos[k] - pos[k - 1]) / w.dt >= 4 - 1e-9  # arrives at its flying speed


def wall_world(gap: float) -> Simulation:
    """One multirotor at x = 10 facing a box wall whose face is at x = 10 + 1 (radius) + gap."""
    raw = base_world(
        obstacles=[{"id": "wall", "shape": "box", "size": [2, 80, 40], "position": [12 + gap, 50, 25]}],
        agents=[{"id": "a", "start": [10, 50, 20], "goal": [10, 10, 20]}],
    )
    sim = Simulation(make_world(raw), planner="none")
    sim.reset(seed=0)
    return sim


@pytest.mark.parametrize("gap", [3.0, 6.0, 12.0])
def test_braking_margin_caps_the_speed_towards_a_wall_exactly(gap):
    sim = wall_world(gap)
    idx = np.array([0])
    pos0 = sim.state.position.copy()
    vel0 = np.array([[8.0, 0.0, 0.0]])
    q0, _ = sim.obstacles.poses(0.0)
    q1, _ = sim.obstacles.poses(DT)
    out = sim.safety.braking_margin(idx, pos0, vel0, np.array([[8.0, 0.0, 0.0]]), q0, q1)
    free = gap - float(sim.safety.margin(0))  # centre travel before the radius + margin touches
    need = 8.0**2 / (2 * A_MAX) + 8.0 * DT  # 8.8 m
    if free >= need:
        np.testing.assert_array_equal(out, [[8.0, 0.0, 0.0]])
        return
    v_safe = A_MAX * (np.sqrt(DT**2 + 2 * free / A_MAX) - DT)
    assert out[0, 1:] == pytest.approx([0.0, 0.0])
    # The free distance is found by bisection to 1/64 of the probe: the cap is at or below v_safe.
    assert v_safe - 0.3 <= out[0, 0] <= v_safe + 1e-9


def test_braking_margin_leaves_commands_away_from_the_wall_alone():
    sim = wall_world(3.0)
    q0, _ = sim.obstacles.poses(0.0)
    cmd = np.array([[-8.0, 0.0, 0.0]])
    out = sim.safety.braking_margin(
        np.array([0]), sim.state.position.copy(), np.array([[-8.0, 0, 0]]), cmd, q0, q0
    )
    np.testing.assert_array_equal(out, cmd)


def test_flying_at_a_wall_brakes_within_the_limit_and_never_hard_stops():
    sim = wall_world(20.0)
    sim.state.velocity[0] = [8.0, 0.0, 0.0]  # cruise, straight at the wall 20 m ahead
    positions = [sim.state.position.copy()]
    stops = 0
    for _ in range(60):
        r = sim.step()
        positions.append(r.state.position.copy())
        stops += sum(e.kind == "emergency_stop" for e in r.events)
    s = sim.summary()["agents"][0]
    assert s["collisions"] == 0 and stops == 0 and s["hard_stops"] == 0
    assert max(p[0][0] for p in positions) < 10 + 20.0  # stopped short of the face
    v0 = np.array([8.0, 0.0, 0.0])
    v = np.diff(np.array(positions)[:, 0], axis=0) / DT
    jumps = np.linalg.norm(np.diff(np.vstack([v0, v]), axis=0), axis=1)
    assert jumps.max() <= A_MAX * DT * (1 + 1e-9)


def test_an_unavoidable_stop_is_counted_as_hard():
    sim = wall_world(0.5)
    sim.state.velocity[0] = [8.0, 0.0, 0.0]  # 0.5 m from the face at 8 m/s: no brake fits
    r = sim.step()
    kinds = [e.kind for e in r.events]
    assert "emergency_stop" in kinds and "collision" not in kinds
    a = sim.summary()["agents"][0]
    assert a["emergency_stops"] == 1 and a["hard_stops"] == 1


def test_a_slow_stop_is_not_hard():
    sim = wall_world(0.5)
    sim.state.velocity[0] = [A_MAX * DT, 0.0, 0.0]  # one step's braking stops it
    for _ in range(5):
        sim.step()
    a = sim.summary()["agents"][0]
    assert a["collisions"] == 0 and a["hard_stops"] == 0
