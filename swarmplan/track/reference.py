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

from swarmplan.world.tracker_config import REFERENCE_METHODS, G, TrackerConfig


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


def build_reference(
    times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, dt: float, method: str = "velocity"
) -> Reference:
    """Reference through recorded ``positions`` (A, T, 3) at ``times`` (T,), sampled every ``dt``.

    ``method``:

    - ``"velocity"`` (default): the kinematics the simulator recorded. Each step's mean
      velocity ``(P[k] - P[k-1]) / h`` is placed at the step's mid-time and joined linearly;
      position is its exact integral, anchored at the first step's midpoint. The acceleration
      is each step's velocity change over h, i.e. exactly what the point mass did (at most its
      ``max_accel``, unless the log jumps), and the path passes every mid-step point of the
      recorded polygon exactly and every recorded position within ``|dv| h / 8`` (5 mm at
      4 m/s^2 and h = 0.1 s).
    - ``"cubic"``: the C2 cubic spline through every recorded position. Exact at the samples,
      but its acceleration amplifies step-to-step chatter of the APF (velocity changes that
      alternate sign every step) up to 3x, so it flags such chatter as infeasible although the
      point mass never exceeded its limit.

    End conditions: the recorded velocity at the first and the last sample (multirotors start at
    rest), so the reference neither starts nor ends with an invented swing.
    """
    t = np.asarray(times, float)
    if len(t) < 2:
        raise ValueError("a reference needs at least two recorded steps")
    if np.any(np.diff(t) <= 0):
        raise ValueError("recorded times must increase")
    if method not in REFERENCE_METHODS:
        raise ValueError(f"unknown reference method {method!r} (one of {', '.join(REFERENCE_METHODS)})")
    n_a = positions.shape[0]
    y = np.transpose(positions, (1, 0, 2)).reshape(len(t), n_a * 3)
    v0 = np.nan_to_num(velocities[:, 0]).reshape(-1)
    v1 = np.nan_to_num(velocities[:, -1]).reshape(-1)
    k = int(np.floor((t[-1] - t[0]) / dt + 1e-9))
    grid = t[0] + dt * np.arange(k + 1)
    if method == "cubic":
        spline = CubicSpline(t, y, axis=0, bc_type=((1, v0), (1, v1)))
        pos, vel, acc = spline(grid), spline(grid, 1), spline(grid, 2)
    else:
        h = np.diff(t)
        mid = 0.5 * (t[:-1] + t[1:])
        u = np.diff(y, axis=0) / h[:, None]
        knots = np.concatenate([[t[0]], mid, [t[-1]]])
        vk = np.vstack([v0, u, v1])
        # Piecewise-linear velocity: exact antiderivative per interval, no quadrature error.
        seg = np.clip(np.searchsorted(knots, grid, side="right") - 1, 0, len(knots) - 2)
        slope = np.diff(vk, axis=0) / np.diff(knots)[:, None]
        # position at every knot: integral of the linear pieces, anchored at the first midpoint
        piece = 0.5 * (vk[:-1] + vk[1:]) * np.diff(knots)[:, None]
        at_knot = np.vstack([np.zeros((1, y.shape[1])), np.cumsum(piece, axis=0)])
        at_knot += 0.5 * (y[0] + y[1]) - at_knot[1]
        tau = (grid - knots[seg])[:, None]
        vel = vk[seg] + slope[seg] * tau
        pos = at_knot[seg] + vk[seg] * tau + 0.5 * slope[seg] * tau**2
        acc = slope[seg]

    def shape(a: np.ndarray) -> np.ndarray:
        return np.transpose(a.reshape(len(grid), n_a, 3), (1, 0, 2))

    return Reference(grid, shape(pos), shape(vel), shape(acc))


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
