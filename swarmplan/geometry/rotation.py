"""Rotations of the world format: roll, pitch, yaw in degrees, R = Rz(yaw) Ry(pitch) Rx(roll)
(intrinsic z-y'-x''), with quaternions as [qx, qy, qz, qw].

Euler angles to quaternion and matrix are computed here with the arithmetic of
``scipy.spatial.transform.Rotation.from_euler("ZYX", ..., degrees=True)`` (elementary
quaternions composed in the same order, the same matrix formula): the values are scipy's bit
for bit (tests/test_geometry_rotation_fast.py), without importing scipy.spatial at start-up
(~0.3-0.8 s: it pulls in scipy.sparse and scipy.linalg). The less common conversions still
use scipy, imported where they run.
"""

from __future__ import annotations

import math

import numpy as np


def _elementary(axis: int, angle: float) -> list[float]:
    q = [0.0, 0.0, 0.0, math.cos(angle / 2.0)]
    q[axis] = math.sin(angle / 2.0)
    return q


def _compose(p: list[float], q: list[float]) -> list[float]:
    cx = p[1] * q[2] - p[2] * q[1]
    cy = p[2] * q[0] - p[0] * q[2]
    cz = p[0] * q[1] - p[1] * q[0]
    return [
        p[3] * q[0] + q[3] * p[0] + cx,
        p[3] * q[1] + q[3] * p[1] + cy,
        p[3] * q[2] + q[3] * p[2] + cz,
        p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2],
    ]


def _quat_from_rpy(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> list[float]:
    # Intrinsic Z, then Y', then X'' is Rz(yaw) Ry(pitch) Rx(roll).
    r, p, y = (float(a) * (math.pi / 180.0) for a in roll_pitch_yaw_deg)
    return _compose(_compose(_elementary(2, y), _elementary(1, p)), _elementary(0, r))


def rotation_matrix(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles in degrees."""
    x, y, z, w = _quat_from_rpy(roll_pitch_yaw_deg)
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array(
        [
            [x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
            [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
            [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2],
        ]
    )


def euler_to_quaternion(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """Roll, pitch, yaw in degrees -> quaternion [qx, qy, qz, qw]."""
    return np.array(_quat_from_rpy(roll_pitch_yaw_deg))


def rotate(quaternion: np.ndarray | tuple[float, ...], v: np.ndarray) -> np.ndarray:
    """``v`` (..., 3) rotated by the quaternion [qx, qy, qz, qw]."""
    v = np.asarray(v, dtype=float)
    q = [float(c) for c in quaternion]
    if q[0] == q[1] == q[2] == 0.0 and q[3] == 1.0 and not (np.signbit(v) & (v == 0.0)).any():
        # The identity (most bodies): scipy's answer, each component v_k * 1 plus products
        # with zeros, is v itself unless v holds a -0.0; without importing scipy.spatial.
        return v.copy()
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quaternion).apply(v)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> quaternion [qx, qy, qz, qw]."""
    if np.array_equal(R, np.eye(3)):  # scipy's answer, without importing it (most bodies)
        return np.array([0.0, 0.0, 0.0, 1.0])
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat()
