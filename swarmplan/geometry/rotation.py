"""Rotations of the world format: roll, pitch, yaw in degrees, R = Rz(yaw) Ry(pitch) Rx(roll)
(intrinsic z-y'-x''), with quaternions as [qx, qy, qz, qw]."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def rotation_matrix(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles in degrees."""
    return _from_rpy(roll_pitch_yaw_deg).as_matrix()


def euler_to_quaternion(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """Roll, pitch, yaw in degrees -> quaternion [qx, qy, qz, qw]."""
    return _from_rpy(roll_pitch_yaw_deg).as_quat()


def rotate(quaternion: np.ndarray | tuple[float, ...], v: np.ndarray) -> np.ndarray:
    """``v`` (..., 3) rotated by the quaternion [qx, qy, qz, qw]."""
    return Rotation.from_quat(quaternion).apply(np.asarray(v, dtype=float))


def _from_rpy(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> Rotation:
    # Intrinsic Z, then Y', then X'' is Rz(yaw) Ry(pitch) Rx(roll).
    r, p, y = (float(a) for a in roll_pitch_yaw_deg)
    return Rotation.from_euler("ZYX", [y, p, r], degrees=True)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> quaternion [qx, qy, qz, qw]."""
    return Rotation.from_matrix(R).as_quat()
