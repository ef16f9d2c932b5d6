"""Cost-model details the papers prescribe: 000 eq 5 and 002 eq 15."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.planner.cost_models import PathContext, ThreatCost
from swarmplan.planner.encodings import SplineEncoding
from swarmplan.world import parse_world


def _second_derivative_at_ends(pts: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """S'' at t = 0 and t = 1 from the samples, exact for a cubic piece.

    For a cubic, ``(p(t+h) - 2p(t) + p(t-h)) / h^2 = p''(t)`` exactly, and ``p''`` is linear,
    so ``p''(0) = 2 p''(h) - p''(2h)``.
    """

    def end(p):
        s1 = (p[2] - 2 * p[1] + p[0]) / h**2
        s2 = (p[3] - 2 * p[2] + p[1]) / h**2
        return 2 * s1 - s2

    return end(pts), end(pts[::-1])


def test_spline_encoding_is_natural_eq15():
    enc = SplineEncoding(
        np.array([0.0, 0.0, 50.0]),
        np.array([100.0, 0.0, 50.0]),
        3,
        40.0,
        20.0,
        np.array([-1e4, -1e4, -1e4]),
        np.array([1e4, 1e4, 1e4]),
        samples=601,  # 4 knot intervals of 150 samples: the first 4 samples share one piece
    )
    X = np.array([[30.0, -25.0, 10.0, 15.0, -8.0, 12.0]])
    pts = enc.decode(X)[0]
    h = 1.0 / 600
    s0, s1 = _second_derivative_at_ends(pts, h)
    # the path bends by tens of metres over a unit parameter: S'' is O(1e3) inside
    inner = np.abs((pts[302] - 2 * pts[301] + pts[300]) / h**2).max()
    assert inner > 100.0
    np.testing.assert_allclose(s0, 0.0, atol=1e-6 * inner)
    np.testing.assert_allclose(s1, 0.0, atol=1e-6 * inner)


def _threat_world():
    return parse_world(
        {
            "name": "t",
            "bounds": {"min": [0, 0, 0], "max": [10000, 4000, 1000]},
            "agents": [{"id": "a", "start": [0, 2000, 500], "goal": [10000, 2000, 500]}],
        }
    )


def test_threat_cost_length_limit_eq5():
    w = _threat_world()
    straight = np.array([[[0, 2000, 500], [5000, 2000, 500], [10000, 2000, 500]]], float)
    detour = np.array([[[0, 2000, 500], [5000, 3500, 500], [10000, 2000, 500]]], float)
    length = 2 * np.hypot(5000.0, 1500.0)  # 10440.3 m
    m = ThreatCost(PathContext(w, w.agents[0]), max_length=10200.0)
    # the straight 10 km path satisfies sum l_i <= l_max; the detour exceeds it by its excess
    assert m.extra_violation(straight)[0] == 0.0
    assert m.extra_violation(detour)[0] == pytest.approx(length - 10200.0, rel=1e-12)
    j = m.objective(detour, detour)[0]
    assert m(detour, detour)[0] == pytest.approx(j + 1000.0 * (1.0 + length - 10200.0), rel=1e-9)
    # no limit by default (000 prints no l_max): the detour is feasible
    free = ThreatCost(PathContext(w, w.agents[0]))
    assert free.extra_violation(detour)[0] == 0.0
    assert free(detour, detour)[0] == pytest.approx(free.objective(detour, detour)[0])
