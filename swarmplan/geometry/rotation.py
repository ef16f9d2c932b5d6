"""Rotations of the world format: roll, pitch, yaw in degrees, R = Rz(yaw) Ry(pitch) Rx(roll)
(intrinsic z-y'-x''), with quaternions as [qx, qy, qz, qw]."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation


def rotation_matrix(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles in degrees."""
    r, p, y = (math.radians(float(a)) for a in roll_pitch_yaw_deg)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def euler_to_quaternion(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """Roll, pitch, yaw in degrees -> quaternion [qx, qy, qz, qw]."""
    r, p, y = (float(a) for a in roll_pitch_yaw_deg)
    return Rotation.from_euler("ZYX", [y, p, r], degrees=True).as_quat()


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix -> quaternion [qx, qy, qz, qw]."""
    return Rotation.from_matrix(R).as_quat()
