"""The world format's Euler conversions, computed without scipy, equal scipy's bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarmplan.geometry.rotation import euler_to_quaternion, matrix_to_quaternion, rotation_matrix


@pytest.mark.parametrize("seed", range(3))
def test_euler_conversions_equal_scipy_exactly(seed):
    rng = np.random.default_rng(seed)
    angles = rng.uniform(-360, 360, (400, 3))
    angles[::4] = np.round(angles[::4] / 15) * 15  # round angles too (quarter turns, zeros)
    angles[1::8, :2] = 0.0  # yaw only
    for rpy in angles:
        ref = Rotation.from_euler("ZYX", rpy[::-1], degrees=True)
        np.testing.assert_array_equal(rotation_matrix(rpy), ref.as_matrix())
        np.testing.assert_array_equal(euler_to_quaternion(rpy), ref.as_quat())
    np.testing.assert_array_equal(rotation_matrix((0, 0, 0)), np.eye(3))
    np.testing.assert_array_equal(matrix_to_quaternion(np.eye(3)), Rotation.from_matrix(np.eye(3)).as_quat())
