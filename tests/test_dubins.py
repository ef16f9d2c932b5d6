"""Fixed-wing segment geometry: Dubins "turn, then straight" paths and chains
(swarmplan.geometry.polyline), and the loiter circles of holding patterns (swarmplan.planner.hold)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.geometry.polyline import curvature_with_cusps, dubins_chain, turn_then_straight
from swarmplan.planner.hold import hold_waypoints, loiter_circle


def _headings(path: np.ndarray) -> np.ndarray:
    d = np.diff(path, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def test_target_straight_ahead_is_one_straight_leg():
    pts, h = turn_then_straight(np.zeros(3), np.array([1.0, 0, 0]), np.array([100.0, 0, 10.0]), 40.0)
    np.testing.assert_allclose(pts, [[100.0, 0, 10.0]])
    np.testing.assert_allclose(h, [1.0, 0, 0], atol=1e-12)


def test_target_behind_is_a_half_turn_then_straight_with_exact_geometry():
    """Target 100 m behind, radius 40: the path turns (left or right, the same length) by more
    than 180 degrees; every arc point is on a circle of radius 40 through the start, and it
    leaves the circle along the tangent to the target."""
    R = 40.0
    pts, h = turn_then_straight(np.zeros(3), np.array([1.0, 0, 0]), np.array([-100.0, 0, 0]), R)
    arc = pts[:-2]
    side = np.sign(arc[len(arc) // 2, 1])
    c = np.array([0.0, side * R])
    np.testing.assert_allclose(np.linalg.norm(arc[:, :2] - c, axis=1), R, atol=1e-9)
    np.testing.assert_allclose(pts[-1], [-100.0, 0, 0])
    # Leaves the circle along its tangent: the last leg is perpendicular to the radius there.
    t = pts[-2, :2]
    assert abs(np.dot(t - c, np.array([-100.0, 0]) - t)) < 1e-6
    np.testing.assert_allclose(np.linalg.norm(h), 1.0)


def test_target_inside_one_turning_circle_goes_round_the_other_way():
    """(10, 30) lies inside the left circle (centre (0, 40), radius 40): the path turns right."""
    pts, _ = turn_then_straight(np.zeros(3), np.array([1.0, 0, 0]), np.array([10.0, 30.0, 0]), 40.0)
    assert pts[0, 1] < 0  # first turning right
    c = np.array([0.0, -40.0])
    np.testing.assert_allclose(np.linalg.norm(pts[:-2, :2] - c, axis=1), 40.0, atol=1e-9)


def test_chain_is_flyable_at_its_radius_and_passes_every_waypoint():
    rng = np.random.default_rng(3)
    wps = np.cumsum(rng.normal(0, 80, size=(6, 3)) * [1, 1, 0.1], axis=0)
    R = 30.0
    path = dubins_chain(np.zeros(3), np.array([0.0, 1.0, 0]), wps, R, max_step_deg=2.0)
    for w in wps:
        assert np.min(np.linalg.norm(path - w, axis=1)) < 1e-9
    flat = path.copy()
    flat[:, 2] = 0.0
    curv, cusp = curvature_with_cusps(flat)
    assert not cusp.any()
    # Discrete arcs of 2 degrees: turning angle / chord within 1e-3 of 1 / R.
    assert curv.max() <= (1.0 / R) * 1.001
    # The heading never jumps (continuous through every waypoint): at most 2 degrees a vertex
    # on the arcs, 0 where arcs meet straights.
    dpsi = np.abs((np.diff(_headings(flat)) + np.pi) % (2 * np.pi) - np.pi)
    assert np.degrees(dpsi).max() <= 2.0 + 1e-6


def test_loiter_circle_is_tangent_to_the_heading_and_closes():
    p = np.array([100.0, 50.0, 30.0])
    v = np.array([0.0, 20.0, 0.0])
    pts = loiter_circle(p, v, 50.0, 1.0)
    np.testing.assert_allclose(pts[-1], p)
    c = np.array([50.0, 50.0])  # left of a northbound heading
    np.testing.assert_allclose(np.linalg.norm(pts[:, :2] - c, axis=1), 50.0, atol=1e-9)
    assert pts[0, 0] < p[0] and pts[0, 1] > p[1]  # the first point is ahead, turning left
    np.testing.assert_allclose(pts[:, 2], 30.0)


def test_hold_picks_the_free_side_and_reports_none_when_boxed_in():
    p, v = np.zeros(3), np.array([10.0, 0, 0])
    left_blocked = lambda poly: bool((poly[:, 1] > 1.0).any())  # noqa: E731
    pts = hold_waypoints(p, v, True, 40.0, left_blocked)
    assert pts is not None and pts[:, 1].max() <= 1e-9  # the right-hand circle
    assert np.linalg.norm(pts[len(pts) // 2, :2] - np.array([0.0, -48.0])) == pytest.approx(48.0)
    assert hold_waypoints(p, v, True, 40.0, lambda poly: True) is None
    # A multirotor hovers where it is.
    np.testing.assert_allclose(hold_waypoints(p, v, False, 40.0, lambda poly: True), [p])


def test_turn_then_straight_keeps_the_height_change_linear_in_distance():
    pts, _ = turn_then_straight(np.zeros(3), np.array([1.0, 0, 0]), np.array([0.0, 200.0, 20.0]), 40.0)
    full = np.vstack([np.zeros(3), pts])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(full[:, :2], axis=0), axis=1))])
    # Left circle centre (0, 40), target 160 m from it: the tangent leaves at acos(40/160) before
    # the target's bearing, after a turn of 90 + 90 - acos(1/4) degrees, then sqrt(160^2 - 40^2).
    sweep = math.pi - math.acos(0.25)
    length = 40.0 * sweep + math.sqrt(160.0**2 - 40.0**2)
    assert s[-1] == pytest.approx(length, rel=2e-3)  # the arc's chords are a hair shorter
    np.testing.assert_allclose(full[:, 2], 20.0 * s / s[-1], atol=0.05)
