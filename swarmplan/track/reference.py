"""Time-parameterized reference from a recorded trajectory, and an honest feasibility check.

The simulator records positions every ``dt`` (0.1 s typically) of a point mass whose velocity
changes by at most ``max_accel * dt`` per step. A C2 cubic spline through those samples, in
time, gives position, velocity and acceleration at any instant: the tracker's set-point and
its feed-forward. It passes exactly through every recorded position, so the error measured
against it is the error against the recording at every sample.

Nothing is smoothed away: where the recording is not flyable (a jump, a stop-and-reverse
sharper than the vehicle can pull), the spline's acceleration says so. ``feasibility``
compares the force that acceleration needs with what the vehicle has (thrust-to-weight and
the tilt limit) and the tracker reports every instant where the reference is out of reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from .config import G, TrackerConfig


@dataclass(frozen=True)
class Reference:
    """Reference of ``A`` agents on the integration grid ``times`` (K,): arrays (A, K, 3)."""

    times: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


def fill_gaps(times: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Positions (A, T, 3) with NaN gaps (agent absent from a step) filled by the nearest sample in time.

    An agent that leaves the log (or appears late) holds its last (first) recorded position:
    that is what a hovering vehicle would be asked to do. Rows with no sample stay NaN.
    """
    out = positions.copy()
    for a in range(out.shape[0]):
        ok = np.isfinite(out[a]).all(axis=1)
        if ok.all() or not ok.any():
            continue
        idx = np.flatnonzero(ok)
        nearest = idx[np.clip(np.searchsorted(idx, np.arange(len(times))), 0, len(idx) - 1)]
        prev = idx[np.clip(np.searchsorted(idx, np.arange(len(times))) - 1, 0, len(idx) - 1)]
        pick = np.where(np.abs(times[prev] - times) <= np.abs(times[nearest] - times), prev, nearest)
        out[a] = out[a][pick]
    return out


def build_reference(times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, dt: float) -> Reference:
    """Spline through recorded ``positions`` (A, T, 3) at ``times`` (T,), sampled every ``dt``.

    End conditions: the recorded velocity at the first and last sample (multirotors start at
    rest; the last one is the final step's displacement over dt), so the reference neither
    starts nor ends with an invented swing.
    """
    t = np.asarray(times, float)
    if len(t) < 2:
        raise ValueError("a reference needs at least two recorded steps")
    if np.any(np.diff(t) <= 0):
        raise ValueError("recorded times must increase")
    n_a = positions.shape[0]
    y = np.transpose(positions, (1, 0, 2)).reshape(len(t), n_a * 3)
    v0 = np.nan_to_num(velocities[:, 0]).reshape(-1)
    v1 = np.nan_to_num(velocities[:, -1]).reshape(-1)
    spline = CubicSpline(t, y, axis=0, bc_type=((1, v0), (1, v1)))
    k = int(np.floor((t[-1] - t[0]) / dt + 1e-9))
    grid = t[0] + dt * np.arange(k + 1)

    def ev(nu: int) -> np.ndarray:
        return np.transpose(spline(grid, nu).reshape(len(grid), n_a, 3), (1, 0, 2))

    return Reference(grid, ev(0), ev(1), ev(2))


def feasibility(ref: Reference, cfg: TrackerConfig) -> np.ndarray:
    """Boolean (A, K): where the reference needs more than the vehicle has.

    Following ``acc`` takes the specific force ``acc + g z + drag/m``; it is out of reach when
    its norm exceeds ``thrust_to_weight * g`` or its angle from vertical exceeds the tilt limit
    (a reference that asks for a free fall faster than g counts too: the vertical part < 0).
    """
    speed = np.linalg.norm(ref.vel, axis=2, keepdims=True)
    f = ref.acc + cfg.drag / cfg.mass * speed * ref.vel
    f[..., 2] += G
    norm = np.linalg.norm(f, axis=2)
    horiz = np.linalg.norm(f[..., :2], axis=2)
    tilt_ok = horiz <= f[..., 2] * np.tan(np.radians(cfg.max_tilt_deg)) + 1e-9
    return ~(tilt_ok & (norm <= cfg.thrust_to_weight * G + 1e-9))
