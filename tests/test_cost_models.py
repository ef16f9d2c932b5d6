"""Exact values of the papers' cost models on simple geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.planner.cost_models import (
    EnergyCost,
    McfoCost,
    PathContext,
    ThreatCost,
    fillet_violation,
    height_std,
    polyline_length,
    threat_probability,
    turn_angles,
)
from swarmplan.planner.encodings import PlaneEncoding, SplineEncoding, resample_uniform, se_frame
from swarmplan.world import parse_world


def _world(**extra):
    raw = {
        "name": "t",
        "bounds": {"min": [0, 0, 0], "max": [200, 200, 100]},
        "agent_defaults": {"radius": 1.0, "min_altitude": 5},
        "agents": [{"id": "a", "start": [0, 100, 20], "goal": [100, 100, 20]}],
    }
    raw.update(extra)
    return parse_world(raw)


def _line(a, b, k=11):
    s = np.linspace(0, 1, k)[:, None]
    return (np.asarray(a, float) + s * (np.subtract(b, a)))[None]


def test_straight_level_line_terms():
    w = _world()
    ctx = PathContext(w, w.agents[0])
    nodes = _line([0, 100, 20], [100, 100, 20])
    m = McfoCost(ctx)
    jp, jh, js = m.terms(nodes)
    assert jp[0] == pytest.approx(100.0, abs=1e-12)  # length = distance exactly
    assert jh[0] == 0.0  # height std of a level path
    assert js[0] == pytest.approx(0.0, abs=1e-6)  # no turning
    assert m(nodes, nodes)[0] == pytest.approx(0.6 * 100.0, abs=1e-9)


def test_mcfo_terms_on_a_corner():
    w = _world()
    ctx = PathContext(w, w.agents[0])
    nodes = np.array([[[0, 100, 20], [50, 100, 30], [100, 100, 20]]], float)
    jp, jh, js = McfoCost(ctx).terms(nodes)
    assert jp[0] == pytest.approx(2 * math.hypot(50, 10))
    assert jh[0] == pytest.approx(np.std([20, 30, 20]))
    assert js[0] == pytest.approx(100.0 * 2 * math.atan(10 / 50))  # (x_n - x_1) * turn angle


def test_infeasible_path_is_penalized():
    w = _world(obstacles=[{"id": "s", "shape": "sphere", "radius": 10, "position": [50, 100, 20]}])
    ctx = PathContext(w, w.agents[0])
    nodes = _line([0, 100, 20], [100, 100, 20])
    m = McfoCost(ctx)
    v = m.violation(nodes, resample_uniform(nodes, 201))
    assert v[0] > 10  # penetrates the sphere ~11 m deep
    assert m(nodes, resample_uniform(nodes, 201))[0] > 1000 * m.objective(nodes, nodes)[0]


def test_threat_probabilities_eqs_2_3():
    d = np.array([0.5, 2.0, 5.0, 200.0])
    assert threat_probability("radar", d, 1.0, 100.0).tolist() == [1.0, 1 / 16, 1 / 625, 0.0]
    assert threat_probability("missile", d, 1.0, 100.0).tolist() == [1.0, 0.5, 0.2, 0.0]


def test_path_through_radar_band_gets_the_eq_value():
    # Radar 2 km beside a level 10 km path (threat_unit = 1000 m = 1 paper km), band 1..3 km:
    # W = δ_O L + Σ_seg l (1/5) Σ_k δ_R / d_k^4 with d_k = sqrt(2^2 + (x_k - 5)^2).
    raw = {
        "name": "t",
        "bounds": {"min": [0, 0, 0], "max": [10000, 4000, 1000]},
        "agents": [{"id": "a", "start": [0, 2000, 500], "goal": [10000, 2000, 500]}],
        "threats": [
            {"kind": "radar", "position": [5000, 0, 500], "r_min": 1000, "r_max": 3000, "weight": 0.3}
        ],
    }
    w = parse_world(raw)
    m = ThreatCost(PathContext(w, w.agents[0]))
    nodes = np.array([[[0, 2000, 500], [5000, 2000, 500], [10000, 2000, 500]]], float)
    expected = 0.1 * 10.0
    for x0, x1 in ((0, 5), (5, 10)):
        pts = [x0 + (x1 - x0) * k / 5 for k in range(1, 6)]
        ws = []
        for x in pts:
            d = math.hypot(2.0, x - 5.0)
            ws.append(0.3 / d**4 if 1.0 <= d <= 3.0 else 0.0)
        expected += 5.0 * sum(ws) / 5
    assert m.objective(nodes, nodes)[0] == pytest.approx(expected, rel=1e-12)


def test_threat_cost_terrain_and_climb_terms():
    w = _world()
    m = ThreatCost(PathContext(w, w.agents[0]), threat_unit=1.0, max_climb_angle=45)
    steep = np.array([[[0, 100, 20], [10, 100, 40]]], float)  # 63° climb: P_B = 1 on the segment
    length = math.hypot(10, 20)
    assert m.objective(steep, steep)[0] == pytest.approx(0.1 * length + length * 1.0)
    high = np.array([[[0, 100, 150], [10, 100, 150]]], float)  # above the bounds' top: P_H = 1
    assert m.objective(high, high)[0] == pytest.approx(0.1 * 10 + 10 * 1.0)


def test_energy_cost_eqs_2_8():
    w = _world()
    m = EnergyCost(PathContext(w, w.agents[0]), alpha1=0.4, alpha2=0.6, xi1=1.0, xi2=3.0,
                   payload=2.0, payload_max=4.0, payload_penalty_max=2.0)  # fmt: skip
    assert m.payload_factor == pytest.approx(1.5)  # (2 - 1)/4 * 2 + 1
    nodes = np.array([[[0, 100, 20], [30, 140, 20], [30, 140, 30]]], float)
    length = 50.0 + 10.0
    energy = 1.5 * (1.0 * (30 + 40) + 3.0 * 10)
    assert m.objective(nodes, nodes)[0] == pytest.approx(0.4 * length + 0.6 * energy)


def test_energy_turn_limit_is_a_constraint():
    w = _world()
    m = EnergyCost(PathContext(w, w.agents[0]), max_turn_angle=45)
    sharp = np.array([[[0, 100, 20], [50, 100, 20], [50, 150, 20]]], float)  # 90° turn
    assert m.extra_violation(sharp)[0] > 0
    gentle = np.array([[[0, 100, 20], [50, 100, 20], [100, 120, 20]]], float)
    assert m.extra_violation(gentle)[0] == 0


def test_geometry_helpers():
    P = np.array([[[0, 0, 0], [3, 4, 0], [3, 4, 12]]], float)
    assert polyline_length(P)[0] == pytest.approx(17.0)
    assert turn_angles(P)[0, 0] == pytest.approx(math.pi / 2)
    assert height_std(P)[0] == pytest.approx(np.std([0, 0, 12]))
    # A right angle between 100 m legs admits R <= 100 (R tan 45° <= 50 fails beyond 50).
    corner = np.array([[[0, 0, 0], [100, 0, 0], [100, 100, 0]]], float)
    assert fillet_violation(corner, 50.0)[0] == 0.0
    assert fillet_violation(corner, 80.0)[0] == pytest.approx(30.0)


def test_plane_encoding_eq1_and_vectorized():
    s, g = np.array([0.0, 0, 0]), np.array([30.0, 40, 0])
    F = se_frame(s, g)
    assert np.allclose(F @ F.T, np.eye(3))
    assert np.allclose(F[0], [0.6, 0.8, 0])
    enc = PlaneEncoding(s, g, 4, 10, 10, [-100] * 3, [100] * 3)
    X = np.zeros((3, 8))
    nodes = enc.decode(X)
    assert nodes.shape == (3, 6, 3)
    assert np.allclose(nodes[0], np.linspace(s, g, 6))
    X[1, 0] = 5.0  # lateral offset of the first waypoint
    assert np.allclose(enc.decode(X)[1, 1], np.linspace(s, g, 6)[1] + 5 * F[1])
    assert enc.dense(X).shape[:2] == (3, enc.dense_count)


def test_spline_encoding_passes_through_ends():
    s, g = np.array([1.0, 1, 1]), np.array([99.0, 99, 20])
    enc = SplineEncoding(s, g, 3, 20, 20, [0] * 3, [100] * 3, samples=25)
    X = np.random.default_rng(0).uniform(enc.lower, enc.upper, (4, enc.dim))
    P = enc.decode(X)
    assert P.shape == (4, 25, 3)
    assert np.allclose(P[:, 0], s) and np.allclose(P[:, -1], g)
    assert np.allclose(enc.decode(np.zeros((1, enc.dim)))[0], np.linspace(s, g, 25))
