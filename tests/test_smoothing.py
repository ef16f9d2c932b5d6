"""Arc fillets of paper 004 §6 (rho = v^2/a, eq 34) on exact geometry, and the smoother's trigger."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.planner.smoothing import fillet_corner, fillet_path


def test_right_angle_gets_an_arc_of_radius_v2_over_a_tangent_to_both_legs():
    P = np.array([[0.0, 0.0, 10.0], [50.0, 0.0, 10.0], [50.0, 50.0, 10.0]])
    speed, accel = 7.0, 4.9
    rho = speed**2 / accel  # 10 m
    out = fillet_path(P, rho, max_step_deg=90 / 16).points
    np.testing.assert_allclose(out[0], P[0])
    np.testing.assert_allclose(out[-1], P[-1])
    arc = out[1:-1]
    assert len(arc) == 17
    center = np.array([50.0 - rho, rho, 10.0])
    np.testing.assert_allclose(np.linalg.norm(arc - center, axis=1), rho, atol=1e-9)
    np.testing.assert_allclose(arc[0], [50.0 - rho, 0.0, 10.0], atol=1e-9)  # tangent point, first leg
    np.testing.assert_allclose(arc[-1], [50.0, rho, 10.0], atol=1e-9)  # tangent point, second leg
    # Tangency: the radius at each tangent point is perpendicular to its leg.
    assert abs(np.dot(arc[0] - center, [1, 0, 0])) < 1e-9
    assert abs(np.dot(arc[-1] - center, [0, 1, 0])) < 1e-9
    # The arc is a quarter circle of length rho * pi / 2 (chords approach it from below).
    chords = np.linalg.norm(np.diff(arc, axis=0), axis=1).sum()
    assert rho * math.pi / 2 * 0.995 < chords < rho * math.pi / 2


def test_fillet_in_3d_stays_in_the_plane_of_the_corner():
    a, v, b = np.array([0.0, 0, 0]), np.array([30.0, 0, 0]), np.array([30.0, 20, 20])
    arc = fillet_corner(a, v, b, rho=5.0)
    n = np.cross(v - a, b - v)
    assert np.allclose((arc - v) @ n, 0.0, atol=1e-9)


def test_colliding_fillet_is_skipped_and_the_corner_kept():
    P = np.array([[0.0, 0, 10], [50.0, 0, 10], [50.0, 50, 10]])
    out = fillet_path(P, 10.0, collision_check=lambda pts: True).points
    np.testing.assert_allclose(out, P)
    calls = []
    out = fillet_path(P, 10.0, collision_check=lambda pts: calls.append(len(pts)) or False).points
    assert calls and len(out) > 3


def test_corner_with_legs_too_short_for_the_radius_is_kept():
    P = np.array([[0.0, 0, 10], [5.0, 0, 10], [5.0, 5, 10]])
    out = fillet_path(P, 10.0**2 / 2.0).points  # rho = v^2/a = 50 m
    np.testing.assert_allclose(out, P)


def test_straight_polyline_is_unchanged():
    P = np.array([[0.0, 0, 0], [1.0, 1, 1], [2.0, 2, 2], [3.0, 3, 3]])
    np.testing.assert_allclose(fillet_path(P, 25.0).points, P)


def test_smoother_flags_a_target_inside_the_turning_circle():
    from helpers import base_world, make_world

    from swarmplan.planner import RefinementPlanner
    from swarmplan.sim import Simulation

    raw = base_world()
    world = make_world(raw)
    planner = RefinementPlanner(world, "de")
    sim = Simulation(world, planner=planner)
    sim.reset(seed=0)
    i = 0
    R = sim.params.speed_cruise[i] ** 2 / sim.params.max_accel[i]
    sim.state.position[i] = np.array([50.0, 50.0, 20.0])
    sim.state.velocity[i] = np.array([sim.params.speed_cruise[i], 0.0, 0.0])
    sim.state.goal[i] = np.array([50.0, 50.0 + 0.8 * R, 20.0])  # beside the agent, inside its circle
    assert planner.smoother.check(sim, i) is not None
    sim.state.goal[i] = np.array([50.0 + 3 * R, 50.0, 20.0])  # straight ahead
    assert planner.smoother.check(sim, i) is None
