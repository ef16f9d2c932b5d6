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


def test_identity_rotation_of_vectors_equals_scipy_exactly():
    """``rotate`` by the identity (computed without scipy) gives scipy's answer bit for bit, the
    zeros' signs included; other rotations and vectors holding -0.0 go to scipy."""
    from swarmplan.geometry.rotation import rotate

    rng = np.random.default_rng(0)
    v = rng.normal(0, 10, (50, 3))
    v[::5, 0] = 0.0
    v[1::5, :2] = 0.0
    v[2::7] = -0.0  # scipy's way with signed zeros
    for q in ((0.0, 0.0, 0.0, 1.0), (-0.0, 0.0, -0.0, 1.0), tuple(euler_to_quaternion((0, 0, 0)))):
        plain = v[~(np.signbit(v) & (v == 0.0)).any(axis=1)]  # the fast path's batch
        for batch in (v, plain):
            ref = Rotation.from_quat(q).apply(batch)
            np.testing.assert_array_equal(rotate(q, batch).view(np.int64), ref.view(np.int64))
        for row in v:
            np.testing.assert_array_equal(
                rotate(q, row).view(np.int64), Rotation.from_quat(q).apply(row).view(np.int64)
            )
    q = tuple(euler_to_quaternion((10, 20, 30)))
    np.testing.assert_array_equal(rotate(q, v), Rotation.from_quat(q).apply(v))
