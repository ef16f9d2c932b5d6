"""Kinematic limits under random commands: multirotor speed/acceleration, fixed-wing speed
band, turn radius and climb angle — both on the limiter functions and on whole simulated runs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import base_world, make_world, run_to_end

from swarmplan.flight.kinematics import (
    AgentParams,
    initial_velocity,
    limit_fixed_wing,
    limit_multirotor,
    limit_velocity,
)

TOL = 1e-9


def test_multirotor_random_commands_respect_speed_and_accel():
    rng = np.random.default_rng(0)
    n, dt = 16, 0.1
    vmax = rng.uniform(3, 20, n)
    amax = rng.uniform(1, 8, n)
    v = np.zeros((n, 3))
    max_speed_ratio = max_accel_ratio = 0.0
    for _ in range(3000):
        # Mix of huge, small and sudden reversals of command.
        cmd = rng.normal(size=(n, 3)) * rng.choice([0.5, 5, 50, 500], size=(n, 1))
        v1 = limit_multirotor(v, cmd, vmax, amax, dt)
        speed = np.linalg.norm(v1, axis=1)
        acc = np.linalg.norm(v1 - v, axis=1) / dt
        assert np.all(speed <= vmax + TOL)
        assert np.all(acc <= amax + TOL)
        max_speed_ratio = max(max_speed_ratio, float((speed / vmax).max()))
        max_accel_ratio = max(max_accel_ratio, float((acc / amax).max()))
        v = v1
    # The limits are reached, not merely respected by a sluggish model.
    assert max_speed_ratio > 0.99 and max_accel_ratio > 0.99


def test_multirotor_reaches_a_feasible_command_exactly():
    v0 = np.zeros((1, 3))
    cmd = np.array([[3.0, 4.0, 0.0]])  # 5 m/s
    v = v0
    for k in range(20):
        v = limit_multirotor(v, cmd, np.array([10.0]), np.array([5.0]), 0.1)
        if k < 9:
            assert np.linalg.norm(v) == pytest.approx(0.5 * (k + 1))
    np.testing.assert_allclose(v, cmd, atol=1e-12)
    # Over-speed commands are clipped to vmax along the commanded direction.
    v = limit_multirotor(
        np.array([[0.0, 0, 9.9]]), np.array([[0.0, 0, 100]]), np.array([10.0]), np.array([5.0]), 1
    )
    np.testing.assert_allclose(v, [[0, 0, 10.0]])


def _heading(v):
    return np.arctan2(v[:, 1], v[:, 0])


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _angle(a, b):
    """Angle (rad) between the rows of ``a`` and ``b``."""
    c = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.arccos(np.clip(c, -1.0, 1.0))


def test_fixed_wing_random_commands_respect_envelope():
    rng = np.random.default_rng(1)
    n, dt = 12, 0.1
    vmin = rng.uniform(8, 12, n)
    vmax = vmin + rng.uniform(5, 15, n)
    amax = rng.uniform(1, 5, n)
    radius = rng.uniform(15, 60, n)
    climb = np.radians(rng.uniform(10, 40, n))
    v = (vmin + vmax)[:, None] / 2 * np.array([1.0, 0, 0])
    min_radius_ratio = math.inf
    for _ in range(3000):
        cmd = rng.normal(size=(n, 3)) * rng.choice([0.1, 5, 50], size=(n, 1))
        cmd[rng.random(n) < 0.1] = 0.0  # zero commands happen (e.g. at a saddle point)
        v1 = limit_fixed_wing(v, cmd, vmin, vmax, amax, radius, climb, dt)
        s0, s1 = np.linalg.norm(v, axis=1), np.linalg.norm(v1, axis=1)
        assert np.all(s1 >= vmin - 1e-9) and np.all(s1 <= vmax + 1e-9)
        assert np.all(np.abs(s1 - s0) <= amax * dt + 1e-9)
        # Flight-path angle within the climb/dive limit.
        gamma = np.arcsin(np.clip(v1[:, 2] / s1, -1, 1))
        assert np.all(np.abs(gamma) <= climb + 1e-9)
        # 3D turn radius: the distance flown at the slower speed over the angle the direction turned.
        turn = _angle(v, v1)
        dist = np.minimum(s0, s1) * dt
        turning = turn > 1e-9
        r_est = dist[turning] / turn[turning]
        assert np.all(r_est >= radius[turning] * (1 - 1e-9)), (r_est / radius[turning]).min()
        if turning.any():
            min_radius_ratio = min(min_radius_ratio, float((r_est / radius[turning]).min()))
        v = v1
    # Tight turns were actually flown (the limit is active, not just never approached).
    assert min_radius_ratio < 1.2


def test_fixed_wing_climb_angle_is_rate_limited():
    """Level flight commanded straight up: the flight-path angle ramps at V / R per second (no
    jump to the climb limit), the heading is kept, and the climb limit is never passed."""
    R, V, dt, climb = 40.0, 20.0, 0.1, math.radians(15)
    lim = [np.array([x]) for x in (10.0, 30.0, 2.0, R, climb)]
    v = np.array([[V, 0.0, 0.0]])
    gammas = []
    for _ in range(30):
        v = limit_fixed_wing(v, np.array([[0.0, 0.0, 50.0]]), *lim, dt)
        gammas.append(math.atan2(v[0, 2], math.hypot(v[0, 0], v[0, 1])))
        assert abs(_heading(v)[0]) < 1e-12
    g = np.array(gammas)
    assert g[0] == pytest.approx(V * dt / R, rel=1e-6)
    assert g.max() == pytest.approx(climb, abs=1e-9) and (g <= climb + 1e-12).all()
    ramp = int(math.ceil(climb / (V * dt / R)))
    assert g[ramp - 1] == pytest.approx(climb, abs=1e-9) and g[ramp - 2] < climb


def test_fixed_wing_climbing_turn_keeps_the_3d_radius():
    """Heading reversal while climbing to the limit: every step turns the direction by at most
    V dt / R (the 3D curvature of the flown path is <= 1 / R)."""
    R, V, dt, climb = 30.0, 15.0, 0.1, math.radians(25)
    lim = [np.array([x]) for x in (10.0, 20.0, 2.0, R, climb)]
    v = np.array([[V, 0.0, 0.0]])
    cmd = np.array([[-V * math.cos(climb), 1e-3, V * math.sin(climb)]])
    worst = 0.0
    for _ in range(200):
        v1 = limit_fixed_wing(v, cmd, *lim, dt)
        worst = max(worst, float(_angle(v, v1)[0]) / (V * dt / R))
        v = v1
    assert worst <= 1.0 + 1e-9 and worst > 0.99
    np.testing.assert_allclose(v[0] / np.linalg.norm(v[0]), cmd[0] / np.linalg.norm(cmd[0]), atol=1e-6)


def test_fixed_wing_never_stalls_on_a_stop_command():
    v = np.array([[12.0, 0, 0]])
    for _ in range(200):
        v = limit_fixed_wing(v, np.zeros((1, 3)), *(np.array([x]) for x in (10.0, 20, 3, 30, 0.3)), 0.1)
        assert np.linalg.norm(v) >= 10.0 - 1e-9


def test_fixed_wing_u_turn_takes_the_turn_radius():
    """A command straight behind: the heading turns at V/R per second, no faster."""
    R, V, dt = 40.0, 15.0, 0.1
    v = np.array([[V, 0, 0]])
    steps = 0
    lim = [np.array([x]) for x in (10.0, 20.0, 2.0, R, math.radians(30))]
    while _heading(v)[0] < math.pi - 1e-6 and _heading(v)[0] >= 0 and steps < 1000:
        v = limit_fixed_wing(v, np.array([[-V, 1e-6, 0]]), *lim, dt)
        steps += 1
    # pi radians at V/R rad/s.
    assert steps * dt == pytest.approx(math.pi * R / V, abs=dt + 1e-9)


def test_initial_velocity_models():
    raw = base_world(
        agents=[
            {"id": "mr", "start": [10, 10, 20], "goal": [90, 10, 20]},
            {
                "id": "fw",
                "start": [10, 50, 20],
                "goal": [10, 90, 40],
                "model": "fixed_wing",
                "speed": {"min": 6, "max": 14, "cruise": 10},
            },
        ]
    )
    w = make_world(raw)
    p = AgentParams.from_world(w)
    start = np.array([a.start for a in w.agents])
    goal = np.array([a.goal for a in w.agents])
    v = initial_velocity(p, start, goal)
    np.testing.assert_allclose(v[0], 0.0)
    np.testing.assert_allclose(v[1], [0, 10, 0])  # level, at cruise, towards the goal
    # limit_velocity dispatches per model.
    out = limit_velocity(p, v, np.array([[100.0, 0, 0], [0, 0, 0]]), 0.1, np.array([0, 1]))
    assert np.linalg.norm(out[0]) == pytest.approx(0.4)  # max_accel 4 * dt
    assert np.linalg.norm(out[1]) >= 6 - 1e-9


# ----------------------------------------------------------------------------- in the simulator


def test_multirotor_limits_hold_in_a_simulated_run():
    raw = base_world(
        obstacles=[{"id": "s", "shape": "sphere", "radius": 6, "position": [50, 52, 20]}],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "b", "start": [50, 10, 20], "goal": [50, 90, 25]},
        ],
    )
    w = make_world(raw)
    sim, summary, pos = run_to_end(w, seed=0)
    assert summary["collisions"] == 0
    p = np.array(pos)
    v = np.diff(p, axis=0) / w.dt
    speed = np.linalg.norm(v, axis=2)
    assert speed.max() <= 12 + 1e-6
    acc = np.linalg.norm(np.diff(v, axis=0), axis=2) / w.dt
    # Emergency stops may brake beyond max_accel; this open layout needs none.
    assert sum(a["emergency_stops"] for a in summary["agents"]) == 0
    for i, a in enumerate(summary["agents"]):
        assert a["arrived"]
        # Arrival zeroes the velocity (the agent is done): only steps while flying count.
        k_end = int(round(a["arrival_time"] / w.dt))
        assert acc[: k_end - 1, i].max() <= 4 + 1e-6, f"agent {i}: accel {acc[: k_end - 1, i].max()}"


def test_fixed_wing_limits_hold_in_a_simulated_run():
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [400, 400, 120]},
        sim={"dt": 0.1, "max_time": 90, "goal_tolerance": 6.0},
        agent_defaults={
            "model": "fixed_wing",
            "radius": 1.0,
            "speed": {"min": 8, "max": 16, "cruise": 12},
            "max_accel": 3,
            "min_turn_radius": 25,
            "max_climb_angle": 15,
            "min_altitude": 5,
        },
        # A tower on the straight line and a higher goal: the aircraft must turn and climb.
        obstacles=[
            {"id": "tower", "shape": "cylinder", "radius": 15, "height": 120, "position": [200, 203, 60]}
        ],
        agents=[{"id": "fw", "start": [330, 200, 30], "goal": [70, 200, 70]}],
    )
    w = make_world(raw)
    sim, summary, pos = run_to_end(w, seed=0)
    p = np.array(pos)[:, 0]
    k_end = len(p) - 1
    if summary["agents"][0]["arrival_time"] is not None:
        k_end = int(round(summary["agents"][0]["arrival_time"] / w.dt))
    v = np.diff(p[: k_end + 1], axis=0) / w.dt  # velocity of each flown step
    s = np.linalg.norm(v, axis=1)
    assert s.min() >= 8 - 1e-5 and s.max() <= 16 + 1e-5
    gamma = np.degrees(np.arcsin(np.clip(v[:, 2] / s, -1, 1)))
    assert np.abs(gamma).max() <= 15 + 1e-4
    turn = _angle(v[1:], v[:-1])
    turning = turn > 1e-6
    assert turning.sum() > 10, "the run should include turns"
    # 3D radius of every step pair: heading and flight-path angle turn within one budget.
    r_est = np.minimum(s[1:], s[:-1])[turning] * w.dt / turn[turning]
    assert r_est.min() >= 25 * (1 - 1e-4)
    # The flight-path angle changes by at most what that radius allows, too.
    dgamma = np.abs(np.diff(np.radians(gamma)))
    assert (dgamma <= np.minimum(s[1:], s[:-1]) * w.dt / 25 * (1 + 1e-4)).all()
    assert summary["agents"][0]["arrived"], "the fixed wing should turn around and reach its goal"
