"""Rotations of the world format (scipy): R = Rz(yaw) Ry(pitch) Rx(roll), quaternions [x, y, z, w]."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.geometry.rotation import euler_to_quaternion, matrix_to_quaternion, rotate, rotation_matrix


def _rz_ry_rx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    r, p, y = (math.radians(a) for a in (roll, pitch, yaw))
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_exact_quarter_turns():
    np.testing.assert_allclose(rotation_matrix([0, 0, 90]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rotation_matrix([0, 90, 0]) @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(rotation_matrix([90, 0, 0]) @ [0, 1, 0], [0, 0, 1], atol=1e-15)


@pytest.mark.parametrize("seed", range(5))
def test_matches_the_world_format_product_and_the_quaternion_agrees(seed):
    rpy = np.random.default_rng(seed).uniform(-180, 180, 3)
    R = rotation_matrix(rpy)
    np.testing.assert_allclose(R, _rz_ry_rx(*rpy), atol=1e-14)
    q = euler_to_quaternion(rpy)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(np.abs(q @ matrix_to_quaternion(R)), 1.0, atol=1e-12)  # same up to sign
    v = np.array([1.0, -2.0, 0.5])
    np.testing.assert_allclose(rotate(q, v), R @ v, atol=1e-12)
