"""Crazyflie trajectories: the flown path as 7th-degree polynomial pieces in x, y, z and yaw.

The Crazyflie's high-level commander flies a trajectory of ``poly4d`` pieces from its
trajectory memory: per piece 8 coefficients for each of x, y, z and yaw (the polynomial in the
time since the piece began, lowest power first) and a duration, as 33 little-endian float32s
(cflib's ``Poly4D.pack``: 4 x 8 x 4 + 4 = 132 bytes). The memory holds
``TRAJECTORY_MEMORY_SIZE`` = 4096 bytes (crazyflie-firmware ``crtp_commander_high_level``),
so one trajectory has at most 4096 // 132 = 31 pieces.

Fit: a degree-7 B-spline in time whose interior knots have multiplicity 4, so position,
velocity, acceleration and jerk are continuous at every joint (C3); it is the least-squares
fit to every recorded position plus a small penalty on the snap (the minimum-snap
regulariser), starting and ending at the recorded positions with the recorded velocities and
zero acceleration. The number of pieces (equal durations) is the smallest that keeps the fit
within the accuracy bound of the flown path at every recorded step and between them; the snap
penalty is raised, on a fixed ladder, only while the fit breaks the agent's speed or
acceleration limit. Everything is checked on the coefficients as the Crazyflie holds them
(float32). A path that needs more than 31 pieces is refused with the accuracy 31 pieces reach
and the pieces the bound would need: never coarsened silently.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from .source import FlownPath, LimitError

DEGREE = 7
COEFFS = DEGREE + 1
PIECE_BYTES = 4 * (4 * COEFFS + 1)  # poly4d: x, y, z, yaw coefficients and the duration, float32
MEMORY_BYTES = 4096  # the Crazyflie's trajectory memory (TRAJECTORY_MEMORY_SIZE)
MAX_PIECES = MEMORY_BYTES // PIECE_BYTES  # 31
JOINT_MULTIPLICITY = 4  # interior knots: C(7 - 4) = C3 at every joint
DEFAULT_ACCURACY = 0.05  # m, at most; a tenth of the agent's smallest separation when smaller
SNAP_LADDER = (0.0, 1e-3, 1e-1, 10.0)  # snap penalty, relative to the fit's own scale
LIMIT_SEARCH = 6  # pieces beyond the fewest that reach the accuracy, tried for the limits
SEARCH_FACTOR = 4  # how far past the memory the refusal looks for the pieces the bound needs
DENSE = 16  # evaluation points per piece (and per recorded step) for deviations and limits
HEADER = ["Duration"] + [f"{axis}^{j}" for axis in ("x", "y", "z", "yaw") for j in range(COEFFS)]


@dataclass(frozen=True)
class Poly4D:
    """A Crazyflie trajectory: ``coeffs`` (n, 4, 8) for x, y, z, yaw (lowest power first, in the
    time since the piece began, float32 values) and ``durations`` (n,) s."""

    durations: np.ndarray
    coeffs: np.ndarray

    @property
    def n_pieces(self) -> int:
        return len(self.durations)

    @property
    def duration(self) -> float:
        return float(np.sum(self.durations, dtype=float))

    @property
    def nbytes(self) -> int:
        return self.n_pieces * PIECE_BYTES

    def breaks(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(self.durations.astype(float))])

    def evaluate(self, t: np.ndarray, derivative: int = 0) -> np.ndarray:
        """x, y, z, yaw (N, 4) or their ``derivative`` at times ``t`` from the trajectory's start
        (held at the ends), in float32 arithmetic as on the vehicle."""
        t = np.clip(np.asarray(t, float), 0.0, self.duration)
        b = self.breaks()
        k = np.clip(np.searchsorted(b, t, side="right") - 1, 0, self.n_pieces - 1)
        u = (t - b[k]).astype(np.float32)
        c = self.coeffs[k].astype(np.float32)  # (N, 4, 8)
        for _ in range(derivative):
            c = c[..., 1:] * np.arange(1, c.shape[-1], dtype=np.float32)
        out = np.zeros(c.shape[:2], np.float32)
        for j in range(c.shape[-1] - 1, -1, -1):  # Horner
            out = out * u[:, None] + c[..., j]
        return out.astype(float)

    def joint_jumps(self) -> np.ndarray:
        """Largest jump of position, velocity and acceleration (x, y, z) over the joints (3,)."""
        if self.n_pieces < 2:
            return np.zeros(3)
        jumps = np.zeros(3)
        for d in range(3):
            c = self.coeffs[:, :3, :].astype(float)
            for _ in range(d):
                c = c[..., 1:] * np.arange(1, c.shape[-1])
            h = self.durations[:-1].astype(float)
            powers = h[:, None] ** np.arange(c.shape[-1])
            end = np.einsum("nam,nm->na", c[:-1], powers)
            start = c[1:, :, 0]
            jumps[d] = float(np.abs(end - start).max())
        return jumps

    def rows(self) -> list[list[float]]:
        """The CSV rows: duration, then x^0..x^7, y^0..y^7, z^0..z^7, yaw^0..yaw^7."""
        return [
            [float(d)] + [float(v) for v in c.reshape(-1)]
            for d, c in zip(self.durations, self.coeffs, strict=True)
        ]


@dataclass(frozen=True)
class Fit:
    """A fitted trajectory and what it was checked against."""

    poly: Poly4D
    max_deviation: float  # m, from the flown path (time-synchronised, float32 coefficients)
    max_speed: float
    max_accel: float
    accuracy: float  # the bound it was fitted to
    snap_weight: float


def accuracy_for(path: FlownPath, override: float | None = None) -> float:
    """The accuracy bound: ``override`` (``--max-deviation``) when given, else 0.05 m or a tenth
    of the agent's smallest separation, whichever is smaller."""
    if override is not None:
        return float(override)
    sep = min(path.limits.separation) if path.limits.separation else math.inf
    return min(DEFAULT_ACCURACY, 0.1 * sep) if sep > 0 else DEFAULT_ACCURACY


def _knots(duration: float, n: int) -> np.ndarray:
    inner = np.repeat(np.linspace(0.0, duration, n + 1)[1:-1], JOINT_MULTIPLICITY)
    return np.concatenate([np.zeros(COEFFS), inner, np.full(COEFFS, duration)])


def _basis(knots: np.ndarray, x: np.ndarray, derivative: int = 0) -> np.ndarray:
    nc = len(knots) - COEFFS
    spline = BSpline(knots, np.eye(nc), DEGREE, extrapolate=False)
    if derivative:
        spline = spline.derivative(derivative)
    out = spline(np.clip(x, knots[0], knots[-1]))
    return np.nan_to_num(out)


def _snap_gram(knots: np.ndarray, n: int, duration: float) -> np.ndarray:
    """Gram matrix of the basis' 4th derivatives over [0, duration] (Gauss-Legendre: the products
    are of degree 6 on each piece, 4 nodes integrate them exactly)."""
    nodes, weights = np.polynomial.legendre.leggauss(4)
    b = np.linspace(0.0, duration, n + 1)
    a, h = b[:-1], np.diff(b)
    x = (a[:, None] + 0.5 * h[:, None] * (nodes[None] + 1.0)).reshape(-1)
    w = (0.5 * h[:, None] * weights[None]).reshape(-1)
    s = _basis(knots, x, 4)
    return s.T @ (w[:, None] * s)


def _kkt(h: np.ndarray, g: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """argmin c' h c / 2 - g' c subject to rows c = rhs."""
    nc, m = h.shape[0], len(rows)
    kkt = np.zeros((nc + m, nc + m))
    kkt[:nc, :nc] = h
    kkt[:nc, nc:] = rows.T
    kkt[nc:, :nc] = rows
    return np.linalg.lstsq(kkt, np.concatenate([g, rhs]), rcond=None)[0][:nc]


def _peaks(norm: np.ndarray, limit: float) -> np.ndarray:
    """Indices of the local maxima of ``norm`` above ``limit``."""
    over = norm > limit
    left = np.concatenate([[True], norm[1:] >= norm[:-1]])
    right = np.concatenate([norm[:-1] >= norm[1:], [True]])
    return np.flatnonzero(over & left & right)


def _to_poly(knots: np.ndarray, coef: np.ndarray, n: int, duration: float) -> Poly4D:
    """Local power-basis coefficients of each piece (float32): the piece is one polynomial of
    degree 7, so its values at 8 Chebyshev points inside it determine them exactly."""
    b = np.linspace(0.0, duration, n + 1)
    h = np.diff(b)
    spline = BSpline(knots, coef, DEGREE)
    nodes = 0.5 * (1.0 - np.cos((2 * np.arange(COEFFS) + 1) * np.pi / (2 * COEFFS)))  # in (0, 1)
    vander = np.vander(nodes, COEFFS, increasing=True)  # in the piece's unit time s = u / h
    out = np.zeros((n, 4, COEFFS))
    for j in range(n):
        values = spline(b[j] + h[j] * nodes)  # (8, 3)
        unit = np.linalg.solve(vander, values)  # coefficients of s^m
        out[j, :3] = (unit / h[j] ** np.arange(COEFFS)[:, None]).T
    return Poly4D(h.astype(np.float32), out.astype(np.float32))


def _end_velocity(times: np.ndarray, pos: np.ndarray, at_end: bool, arrived_still: bool) -> np.ndarray:
    if arrived_still:
        return np.zeros(3)
    if at_end:
        return (pos[-1] - pos[-2]) / (times[-1] - times[-2])
    return (pos[1] - pos[0]) / (times[1] - times[0])


def _dense(times: np.ndarray) -> np.ndarray:
    """Recorded times and DENSE - 1 points between each pair."""
    s = np.linspace(0.0, 1.0, DENSE, endpoint=False)
    inner = (times[:-1, None] + np.diff(times)[:, None] * s[None]).reshape(-1)
    return np.concatenate([inner, times[-1:]])


def _flown_at(times: np.ndarray, pos: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, times, pos[:, j]) for j in range(3)])


def evaluate_fit(poly: Poly4D, path: FlownPath) -> tuple[float, float, float]:
    """Largest deviation from the flown path (time-synchronised, between the recorded steps too,
    against the recorded polygon), speed and acceleration of the exported trajectory."""
    tau = path.times - path.times[0]
    t = _dense(tau)
    fitted = poly.evaluate(t)[:, :3]
    dev = float(np.linalg.norm(fitted - _flown_at(tau, path.positions, t), axis=1).max())
    tp = np.linspace(0.0, poly.duration, poly.n_pieces * DENSE * 4 + 1)
    speed = float(np.linalg.norm(poly.evaluate(tp, 1)[:, :3], axis=1).max())
    accel = float(np.linalg.norm(poly.evaluate(tp, 2)[:, :3], axis=1).max())
    return dev, speed, accel


LIMIT_TARGET = 0.99  # a peak over a limit is pinned this far below it (room for float32 and the grid)
MAX_PINS = 12  # rounds of pinning limit peaks before a fit is given up
PINS_PER_ROUND = 8  # the highest peaks over each limit pinned per round
PIN_RESIDUAL = 1e-6  # relative: a solve missing its equalities by more has contradictory pins


def _fit_pieces(
    path: FlownPath, n: int, ladder: tuple[float, ...] = SNAP_LADDER, pin: bool = True
) -> Iterator[tuple[Poly4D, float, float, float, float]]:
    """The fits with ``n`` pieces along the snap ``ladder``: (poly, deviation, speed, accel, weight).

    Each is the least-squares fit under the end conditions; where its speed or acceleration
    peaks over the agent's limit, the peak is held at the limit along its direction (an equality
    constraint, i.e. the inequality made active) and the fit is solved again, until no peak is
    over. Coefficients of x, y and z are solved together (the limits are on the norms)."""
    tau = path.times - path.times[0]
    duration = float(tau[-1])
    knots = _knots(duration, n)
    basis = _basis(knots, tau)
    nc = basis.shape[1]
    gram = _snap_gram(knots, n, duration)
    still = path.arrived or np.linalg.norm(path.positions[-1] - path.positions[-2]) < 1e-12
    v0 = _end_velocity(path.times, path.positions, False, False)
    # A multirotor starts from rest (the log's first step already holds its first command).
    if path.limits.model == "multirotor":
        v0 = np.zeros(3)
    v1 = _end_velocity(path.times, path.positions, True, bool(still))
    ends = np.array([0.0, duration])
    end_rows = np.vstack([_basis(knots, ends, 0), _basis(knots, ends, 1)])
    end_rhs = np.vstack([path.positions[0], path.positions[-1], v0, v1])
    eye3 = np.eye(3)
    rows0 = np.kron(eye3, end_rows)
    rhs0 = end_rhs.T.reshape(-1)
    grid = np.linspace(0.0, duration, max(n * DENSE * 4, len(tau) * 4) + 1)
    d1, d2 = _basis(knots, grid, 1), _basis(knots, grid, 2)
    a = basis.T @ basis
    g = np.concatenate([basis.T @ path.positions[:, j] for j in range(3)])
    scale = np.trace(a) / max(np.trace(gram), 1e-300)
    lim = path.limits
    for lam in ladder:
        h = np.kron(eye3, a + lam * scale * gram)
        rows, rhs = rows0, rhs0
        coef = None
        for _ in range(MAX_PINS if pin else 1):
            flat = _kkt(h, g, rows, rhs)
            if coef is not None and np.abs(rows @ flat - rhs).max() > PIN_RESIDUAL * max(
                1.0, np.abs(rhs).max()
            ):
                break  # the pins contradict each other: keep the last consistent fit (over a limit)
            coef = flat.reshape(3, nc).T  # (nc, 3)
            vel, acc = d1 @ coef, d2 @ coef
            new_rows, new_rhs = [], []
            for deriv, values, limit in ((d1, vel, lim.speed_max), (d2, acc, lim.max_accel)):
                norm = np.linalg.norm(values, axis=1)
                peaks = _peaks(norm, limit * (1 - 0.1 * (1 - LIMIT_TARGET)))
                for k in peaks[np.argsort(-norm[peaks], kind="stable")][:PINS_PER_ROUND]:
                    u = values[k] / norm[k]
                    new_rows.append(np.kron(u, deriv[k]))
                    new_rhs.append(limit * LIMIT_TARGET)
            if not new_rows:
                break
            rows = np.vstack([rows, *new_rows])
            rhs = np.concatenate([rhs, new_rhs])
        poly = _to_poly(knots, coef, n, duration)
        dev, speed, accel = evaluate_fit(poly, path)
        yield poly, dev, speed, accel, lam


def _within_limits(path: FlownPath, speed: float, accel: float) -> bool:
    lim = path.limits
    return speed <= lim.speed_max * (1 + 1e-6) and accel <= lim.max_accel * (1 + 1e-6)


def _pieces_needed(path: FlownPath, accuracy: float, start: int, cap: int) -> int | None:
    """The fewest pieces (from ``start``, at most ``cap``) whose plain least-squares fit reaches
    ``accuracy``, by doubling and bisection; None when even ``cap`` does not."""

    def reaches(n: int) -> bool:
        return next(_fit_pieces(path, n, (SNAP_LADDER[0],), pin=False))[1] <= accuracy

    hi = start
    while not reaches(hi):
        if hi >= cap:
            return None
        hi = min(cap, hi * 2)
    lo = max(start // 2, 1)
    while lo < hi:
        mid = (lo + hi) // 2
        if reaches(mid):
            hi = mid
        else:
            lo = mid + 1
    return hi


def fit(path: FlownPath, accuracy: float, max_pieces: int = MAX_PIECES) -> Fit:
    """The trajectory with the fewest pieces within ``accuracy`` of the flown path and within the
    agent's speed and acceleration limits. Raises :class:`LimitError` (with what would fit)
    when ``max_pieces`` do not reach it."""
    aid = path.limits.id
    lim = path.limits
    memory = f"{max_pieces} pieces ({max_pieces * PIECE_BYTES} of the {MEMORY_BYTES}-byte trajectory memory)"
    # A fit held to the limits is never closer than the plain least-squares fit with as many
    # pieces: the plain fits say where to start looking, and whether the memory can do at all.
    first = _pieces_needed(path, accuracy, 1, max_pieces * SEARCH_FACTOR)
    over: tuple[float, float] | None = None
    best_dev = math.inf
    last = min(max_pieces, (first or max_pieces) + LIMIT_SEARCH)
    for n in range((first or max_pieces + 1), last + 1):
        for poly, dev, speed, accel, lam in _fit_pieces(path, n):
            if not _within_limits(path, speed, accel):
                ratio = max(speed / lim.speed_max, accel / lim.max_accel)
                if over is None or ratio < max(over[0] / lim.speed_max, over[1] / lim.max_accel):
                    over = (speed, accel)  # the one closest to its limits
                continue
            best_dev = min(best_dev, dev)
            if dev <= accuracy:
                return Fit(poly, dev, speed, accel, accuracy, lam)
    if first is not None and first <= max_pieces:
        speed, accel = over if over is not None else (math.nan, math.nan)
        raise LimitError(
            f"agent {aid}: no trajectory of {first} to {last} pieces within {accuracy:g} m of the flown "
            "path keeps "
            f"its limits (best: speed {speed:.3f} of {lim.speed_max:g} m/s, acceleration {accel:.3f} of "
            f"{lim.max_accel:g} m/s^2)"
        )
    reach = min(dev for _, dev, *_ in _fit_pieces(path, max_pieces, (SNAP_LADDER[0],), pin=False))
    need = (
        f"{first} pieces ({first * PIECE_BYTES} bytes) would reach {accuracy:g} m"
        if first
        else f"not even {max_pieces * SEARCH_FACTOR} pieces reach {accuracy:g} m"
    )
    loose = math.ceil(reach * 1000) / 1000
    raise LimitError(
        f"agent {aid}: {memory} come within {reach:.3f} m of its {path.duration:.1f} s flown path at "
        f"best, not {accuracy:g} m; {need}: export it in parts or with --max-deviation {loose:g} or more"
    )


def csv_text(poly: Poly4D) -> str:
    """Bitcraze's trajectory CSV: a header line, then one line per piece."""
    lines = [",".join(HEADER)]
    for row in poly.rows():
        lines.append(",".join(repr(float(np.float32(v))) for v in row))
    return "\n".join(lines) + "\n"


def read_csv(text: str) -> Poly4D:
    """A trajectory CSV back (the header line is skipped)."""
    rows = [line.split(",") for line in text.strip().splitlines()[1:]]
    data = np.array([[float(v) for v in r] for r in rows], float).reshape(-1, 1 + 4 * COEFFS)
    return Poly4D(data[:, 0].astype(np.float32), data[:, 1:].reshape(-1, 4, COEFFS).astype(np.float32))
