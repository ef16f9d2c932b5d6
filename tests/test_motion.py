"""Trajectories of moving obstacles: linear, waypoints (with and without loop), circle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.world.motion import pose_at, poses_at


def mover(motion, position=(50, 80, 20)):
    raw = base_world(
        obstacles=[{"id": "m", "shape": "sphere", "radius": 1, "position": list(position), "motion": motion}]
    )
    return make_world(raw).obstacles[0]


def test_linear():
    o = mover({"type": "linear", "velocity": [-2, 1, 0.5]})
    p, v = pose_at(o, 4.0)
    np.testing.assert_allclose(p, [42, 84, 22])
    np.testing.assert_allclose(v, [-2, 1, 0.5])


def test_waypoints_without_loop_stop_at_the_last():
    o = mover({"type": "waypoints", "waypoints": [[60, 80, 20], [60, 90, 20]], "speed": 2})
    np.testing.assert_allclose(pose_at(o, 0.0)[0], [50, 80, 20])
    p, v = pose_at(o, 2.5)
    np.testing.assert_allclose(p, [55, 80, 20])
    np.testing.assert_allclose(v, [2, 0, 0])
    p, v = pose_at(o, 7.0)  # 14 m along: 4 m up the second leg
    np.testing.assert_allclose(p, [60, 84, 20])
    np.testing.assert_allclose(v, [0, 2, 0])
    p, v = pose_at(o, 100.0)
    np.testing.assert_allclose(p, [60, 90, 20])
    np.testing.assert_allclose(v, 0.0)


def test_waypoints_with_loop_return_and_repeat():
    o = mover({"type": "waypoints", "waypoints": [[60, 80, 20]], "speed": 5, "loop": True})
    # 10 m out, 10 m back: period 4 s.
    np.testing.assert_allclose(pose_at(o, 1.0)[0], [55, 80, 20])
    p, v = pose_at(o, 3.0)
    np.testing.assert_allclose(p, [55, 80, 20])
    np.testing.assert_allclose(v, [-5, 0, 0])
    np.testing.assert_allclose(pose_at(o, 4.0 * 7 + 1.0)[0], [55, 80, 20], atol=1e-9)


def test_circle_starts_at_position_and_turns_counter_clockwise():
    o = mover({"type": "circle", "center": [50, 70, 25], "radius": 10, "angular_speed": 0.5})
    p, v = pose_at(o, 0.0)
    np.testing.assert_allclose(p, [50, 80, 25])  # angle of position about the centre, at the centre's height
    np.testing.assert_allclose(v, [-5, 0, 0], atol=1e-12)  # r * omega, counter-clockwise
    p, _ = pose_at(o, math.pi)  # pi s at 0.5 rad/s: a quarter turn
    np.testing.assert_allclose(p, [40, 70, 25], atol=1e-9)
    for t in np.linspace(0, 30, 17):
        p, v = pose_at(o, t)
        assert np.linalg.norm(p[:2] - [50, 70]) == pytest.approx(10)
        assert np.linalg.norm(v) == pytest.approx(5)


def test_velocity_is_the_derivative_of_position():
    for motion in (
        {"type": "linear", "velocity": [1, 2, 3]},
        {"type": "circle", "center": [40, 80, 20], "radius": 10, "angular_speed": -0.3},
        {"type": "waypoints", "waypoints": [[60, 85, 22], [40, 90, 20]], "speed": 3, "loop": True},
    ):
        o = mover(motion)
        for t in (0.7, 3.3, 9.1):
            h = 1e-5
            fd = (pose_at(o, t + h)[0] - pose_at(o, t - h)[0]) / (2 * h)
            np.testing.assert_allclose(pose_at(o, t)[1], fd, atol=1e-4)


def test_static_and_batched():
    raw = base_world(
        obstacles=[
            {"id": "s", "shape": "sphere", "radius": 1, "position": [50, 80, 20]},
            {"id": "m", "shape": "sphere", "radius": 1, "position": [50, 20, 20],
             "motion": {"type": "linear", "velocity": [1, 0, 0]}},
        ]
    )  # fmt: skip
    w = make_world(raw)
    p, v = poses_at(w.obstacles, 2.0)
    np.testing.assert_allclose(p, [[50, 80, 20], [52, 20, 20]])
    np.testing.assert_allclose(v, [[0, 0, 0], [1, 0, 0]])
    p, v = poses_at((), 1.0)
    assert p.shape == (0, 3) and v.shape == (0, 3)
