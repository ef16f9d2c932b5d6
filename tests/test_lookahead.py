"""The fixed-wing turn-ahead guard (``swarmplan.flight.lookahead``): a fixed wing whose potential field
reacts later than it can turn must still turn away in time."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world, run_to_end

from swarmplan.flight.kinematics import AgentParams
from swarmplan.flight.lookahead import guard_commands, horizon_steps
from swarmplan.sim.metrics import NOTHING
from swarmplan.sim.safety import SafetyFilter

WALL_X = 100.0


def wall_world(influence: float = 3.0):
    """A fixed wing (15 m/s, turn radius 20 m) flying at a wall that spans the whole height,
    the goal behind it; the field's influence distance (3 m) is far shorter than the turn radius."""
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [200, 200, 60]},
        sim={"dt": 0.1, "max_time": 30, "goal_tolerance": 2.0},
        obstacles=[{"id": "wall", "shape": "box", "size": [2, 120, 60], "position": [WALL_X, 100, 30]}],
        agent_defaults={
            "model": "fixed_wing",
            "radius": 1.0,
            "speed": {"min": 12, "max": 16, "cruise": 15},
            "max_accel": 5,
            "min_turn_radius": 20,
            "max_climb_angle": 10,
            "min_altitude": 5,
            "separation": [4, 4, 2],
        },
        agents=[{"id": "a", "start": [30, 100, 30], "goal": [170, 100, 30]}],
        # The bare field (no guide: a fixed wing's line of sight would lead it round the wall).
        planner={"optimizer": {"name": "none"}, "apf": {"influence": influence, "guide": False}},
    )
    return make_world(raw)


def test_fixed_wing_turns_away_from_a_wall_its_field_sees_too_late():
    sim, summary, _ = run_to_end(wall_world(), seed=0)
    agent = summary["agents"][0]
    assert summary["collisions"] == 0, agent
    assert agent["guard_steps"] > 0
    assert agent["min_clearance"] >= 0.5 * sim.params.radius[0]


def test_without_the_guard_the_same_flight_hits_the_wall(monkeypatch):
    """Negative control: the scenario above is a real test of the guard."""
    monkeypatch.setattr(
        SafetyFilter, "guard_fixed_wings", lambda self, idx, p, v, v_cmd, *a: (v_cmd, NOTHING)
    )
    _, summary, _ = run_to_end(wall_world(), seed=0)
    assert summary["collisions"] == 1
    assert summary["agents"][0]["collided_with"] == ["wall"]


def _one_agent_params(instant: bool = False) -> AgentParams:
    """The wall world's agent; ``instant``: rolling at once (no roll rate) and keeping only its
    radius from bodies, for the closed-form figures below."""
    p = AgentParams.from_world(wall_world())
    if instant:
        p.roll_rate[:] = np.inf
        p.clearance[:] = p.radius
    return p


def _wall_clearance(points: np.ndarray, radii: np.ndarray, t: float, extra: np.ndarray) -> np.ndarray:
    """Half-space x < WALL_X - 1 (the wall's near face) as the only obstacle."""
    return (WALL_X - 1.0) - points[:, 0] - radii - extra


def test_guard_keeps_the_field_command_while_a_way_out_remains():
    """Straight at a wall, radius 20 m turns, 1.5 m per step, 1 m body, 1 m required clearance.
    The model flies a hard turn as steps of 1.5 m each turned by V dt / R = 0.075 rad (the
    position advances with the turned velocity), so it comes within D - X of the face (centre)
    with X = sum of 1.5 cos(0.075 k) over the first quarter turn (19.25 m): the body keeps
    D - X - 1 >= 1 for D >= X + 2, and each predicted position keeps the room a chord of a step
    at the top speed (1.6 m) can dip by, sqrt(2^2 + 0.8^2) - 2 = 0.154 m (centre 2 m from the
    face: clearance 1 m plus the 1 m body). The command stands while the next state (D - 1.5)
    still has that way out, i.e. down to D = X + 3.5 + 0.154; below, the guard turns at once."""
    p = _one_agent_params(instant=True)
    idx = np.array([0])
    vel = np.array([[15.0, 0.0, 0.0]])
    cmd = vel.copy()  # straight on at the wall
    required = np.array([1.0])
    k = np.arange(1, 22)
    c = np.cos(k * 0.075)
    reach = float((1.5 * c[c > 0]).sum())
    assert reach == pytest.approx(19.25, abs=0.01)
    reach += float(np.sqrt(2.0**2 + 0.8**2) - 2.0)

    def at(distance: float) -> tuple[np.ndarray, np.ndarray]:
        pos = np.array([[WALL_X - 1 - distance, 100.0, 30.0]])
        return guard_commands(p, idx, pos, vel, cmd, 0.0, 0.1, _wall_clearance, required)

    for distance in (200.0, 40.0, reach + 3.5 + 0.02):
        out, replaced = at(distance)
        assert not replaced[0] and np.allclose(out, cmd), distance
    out, replaced = at(reach + 3.5 - 0.02)
    assert replaced[0]
    # One step of a maximum-rate turn: the direction turns by V / R * dt = 15 / 20 * 0.1 rad
    # (4.3 degrees), nearly all of it in heading (a climbing or diving turn shares the budget).
    turn = np.degrees(np.arccos(out[0] @ vel[0] / (np.linalg.norm(out[0]) * 15.0)))
    assert turn == pytest.approx(np.degrees(15 / 20 * 0.1), rel=1e-3)
    heading = np.degrees(np.arctan2(out[0, 1], out[0, 0]))
    assert abs(heading) >= 0.99 * np.degrees(15 / 20 * 0.1)


def test_horizon_is_a_full_turn_plus_a_second():
    p = _one_agent_params()
    full = int(np.ceil((2 * np.pi * 20 / 15 + 1) / 0.1))
    assert horizon_steps(p, np.array([0]), np.array([15.0]), 0.1) == full


def test_predicted_positions_are_exact_arcs():
    from swarmplan.flight.lookahead import predicted_positions

    pos = np.zeros((1, 3))
    vel = np.array([[15.0, 0.0, 0.0]])
    radius = np.array([20.0])
    w = 15.0 / 20.0
    quarter = (np.pi / 2) / w
    turn = np.array([[1.0, -1.0, 1.0, 0.0]])
    turn_time = np.array([[np.inf, np.inf, quarter, 0.0]])
    gamma = np.array([[0.0, 0.0, 0.0, np.radians(10)]])
    times = np.array([np.pi / w, quarter + 1.0])
    P = predicted_positions(pos, vel, turn, turn_time, gamma, radius, times)
    assert P.shape == (1, 4, 2, 3)
    np.testing.assert_allclose(P[0, 0, 0], [0.0, 40.0, 0.0], atol=1e-9)  # half a left turn: 2 R across
    np.testing.assert_allclose(P[0, 1, 0], [0.0, -40.0, 0.0], atol=1e-9)  # half a right turn
    np.testing.assert_allclose(P[0, 2, 1], [20.0, 35.0, 0.0], atol=1e-9)  # quarter turn, then 1 s straight
    t = times[1]
    c, s = np.cos(np.radians(10)), np.sin(np.radians(10))
    np.testing.assert_allclose(P[0, 3, 1], [15 * c * t, 0.0, 15 * s * t], atol=1e-9)  # straight climb


def test_a_finite_roll_rate_makes_the_guard_turn_earlier():
    """Rolling into the turn takes steps the instant model turns in: the guard gives the
    command up farther from the wall."""
    idx, vel = np.array([0]), np.array([[15.0, 0.0, 0.0]])
    required = np.array([1.0])

    def last_standing(p: AgentParams) -> float:
        for distance in np.arange(60.0, 10.0, -0.05):
            pos = np.array([[WALL_X - 1 - distance, 100.0, 30.0]])
            _, replaced = guard_commands(p, idx, pos, vel, vel.copy(), 0.0, 0.1, _wall_clearance, required)
            if replaced[0]:
                return float(distance)
        raise AssertionError("never guarded")

    instant = _one_agent_params(instant=True)
    rolling = _one_agent_params(instant=True)
    rolling.roll_rate[:] = _one_agent_params().roll_rate
    assert last_standing(rolling) > last_standing(instant) + 0.5


def test_the_guard_keeps_the_aircrafts_clearance_from_bodies():
    """By default a fixed wing keeps half its horizontal separation from bodies (2 m here, body
    radius 1 m): the command is given up one metre farther from the wall than with its radius."""
    p = _one_agent_params()
    assert p.clearance[0] == pytest.approx(2.0)
    idx, vel, required = np.array([0]), np.array([[15.0, 0.0, 0.0]]), np.array([1.0])

    def replaced_at(params: AgentParams, distance: float) -> bool:
        pos = np.array([[WALL_X - 1 - distance, 100.0, 30.0]])
        return bool(
            guard_commands(params, idx, pos, vel, vel.copy(), 0.0, 0.1, _wall_clearance, required)[1][0]
        )

    near = _one_agent_params()
    near.clearance[:] = near.radius
    # Between the two thresholds (1 m apart) only the wider clearance gives the command up.
    gaps = np.arange(15.0, 40.0, 0.05)
    wide = next(d for d in gaps[::-1] if replaced_at(p, d))
    tight = next(d for d in gaps[::-1] if replaced_at(near, d))
    assert wide - tight == pytest.approx(1.0, abs=0.06)
