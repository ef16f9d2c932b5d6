"""Crazyflie trajectories: the flown path as 7th-degree polynomial pieces in x, y, z and yaw.

The Crazyflie's high-level commander flies a trajectory of ``poly4d`` pieces from its
trajectory memory: per piece 8 coefficients for each of x, y, z and yaw (the polynomial in the
time since the piece began, lowest power first) and a duration, as 33 little-endian float32s
(cflib's ``Poly4D.pack``: 4 x 8 x 4 + 4 = 132 bytes). The memory holds
``TRAJECTORY_MEMORY_SIZE`` = 4096 bytes (crazyflie-firmware ``crtp_commander_high_level``),
so one trajectory has at most 4096 // 132 = 31 pieces.

Fit: a degree-7 B-spline in time whose interior knots have multiplicity 4, so position,
velocity, acceleration and jerk are continuous at every joint (C3), on the flown timing (from
rest half a step before the first recorded step; :func:`ends_of`); an end at rest is a hover,
with no acceleration either. The agent's speed and
acceleration limits, the jerk a Crazyflie can produce within them
(:meth:`~swarmplan.track.crazyflie.Crazyflie.max_jerk`: the body rates a trajectory asks for are
its jerk over the thrust acceleration, and the gyro measures at most 2000 deg/s) and the
accuracy bound are constraints on dense grids: of the splines that
keep them, the fit is the one closest to the least-squares fit to every recorded position plus
a small penalty on the snap, found by cutting planes (:func:`_solve`) and solved exactly as a
least distance programme (:func:`_ldp`). The number of pieces (equal durations) is the
smallest that fits. Everything is checked again on the coefficients as the Crazyflie holds them
(float32). A path that 31 pieces cannot fit is refused, never coarsened, with what would fit:
the smallest bound within which 31 pieces keep the limits, or the limits its timing needs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.optimize import nnls

from swarmplan.track.crazyflie import Crazyflie

from .source import FlownPath, LimitError

DEGREE = 7
COEFFS = DEGREE + 1
PIECE_BYTES = 4 * (4 * COEFFS + 1)  # poly4d: x, y, z, yaw coefficients and the duration, float32
MEMORY_BYTES = 4096  # the Crazyflie's trajectory memory (TRAJECTORY_MEMORY_SIZE)
MAX_PIECES = MEMORY_BYTES // PIECE_BYTES  # 31
JOINT_MULTIPLICITY = 4  # interior knots: C(7 - 4) = C3 at every joint
DEFAULT_ACCURACY = 0.05  # m, at most; a tenth of the agent's smallest separation when smaller
SNAP_WEIGHT = 1e-3  # snap penalty beside the least squares, relative to the fit's own scale
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
    max_jerk: float
    accuracy: float  # the bound it was fitted to
    lead: float  # s: the trajectory starts this long before the flown path's first step


def accuracy_for(path: FlownPath, override: float | None = None) -> float:
    """The accuracy bound: ``override`` (``--max-deviation``) when given, else 0.05 m or a tenth
    of the agent's smallest separation, whichever is smaller."""
    if override is not None:
        return float(override)
    sep = min(path.limits.separation) if path.limits.separation else math.inf
    return min(DEFAULT_ACCURACY, 0.1 * sep) if sep > 0 else DEFAULT_ACCURACY


def _knots(breaks: np.ndarray) -> np.ndarray:
    inner = np.repeat(breaks[1:-1], JOINT_MULTIPLICITY)
    return np.concatenate([np.full(COEFFS, breaks[0]), inner, np.full(COEFFS, breaks[-1])])


def _basis(knots: np.ndarray, x: np.ndarray, derivative: int = 0) -> np.ndarray:
    nc = len(knots) - COEFFS
    spline = BSpline(knots, np.eye(nc), DEGREE, extrapolate=False)
    if derivative:
        spline = spline.derivative(derivative)
    out = spline(np.clip(x, knots[0], knots[-1]))
    return np.nan_to_num(out)


def _snap_gram(knots: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    """Gram matrix of the basis' 4th derivatives over the trajectory (Gauss-Legendre: the products
    are of degree 6 on each piece, 4 nodes integrate them exactly)."""
    nodes, weights = np.polynomial.legendre.leggauss(4)
    a, h = breaks[:-1], np.diff(breaks)
    x = (a[:, None] + 0.5 * h[:, None] * (nodes[None] + 1.0)).reshape(-1)
    w = (0.5 * h[:, None] * weights[None]).reshape(-1)
    s = _basis(knots, x, 4)
    return s.T @ (w[:, None] * s)


def _peaks(norm: np.ndarray, limit: float) -> np.ndarray:
    """Indices of the local maxima of ``norm`` above ``limit``."""
    over = norm > limit
    left = np.concatenate([[True], norm[1:] >= norm[:-1]])
    right = np.concatenate([norm[:-1] >= norm[1:], [True]])
    return np.flatnonzero(over & left & right)


def _to_poly(knots: np.ndarray, coef: np.ndarray, breaks: np.ndarray) -> Poly4D:
    """Local power-basis coefficients of each piece (float32): the piece is one polynomial of
    degree 7, so its values at 8 Chebyshev points inside it determine them exactly."""
    b = breaks
    n = len(b) - 1
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


def ramp_time(path: FlownPath, accuracy: float) -> float:
    """s: half the longest ramp of the acceleration, centred on a step of it, that keeps within
    ``accuracy`` of the step. Against a path that steps from rest to the acceleration ``a`` at an
    instant, a trajectory whose acceleration rises linearly over T centred on that instant has
    the same velocity from the ramp's end on and is ahead by ``a T^2 / 48`` at the instant and
    by ``a T^2 / 24`` from the ramp's end on (which it gives back by flying a little slower
    after; a trajectory behind a path flown on at the speed limit could not win it back), so T
    may be ``sqrt(24 accuracy / a)``: the trajectory may begin to leave (or end to reach) a
    hover up to ``sqrt(6 accuracy / a)`` before (after) the flown path's step, with ``a`` the
    agent's acceleration limit."""
    return math.sqrt(6.0 * accuracy / path.limits.max_accel)


def ends_of(path: FlownPath, accuracy: float) -> tuple[float, float]:
    """How long (s) the trajectory starts before the flown path's first step and ends after its
    last, at a rest: half a step and the :func:`ramp_time`. The simulator's step (v += a dt,
    then x += v dt) moves as a body whose acceleration is held over each step centred on the
    recorded instant: from rest half a step before the first recorded position (a multirotor
    starts hovering; its first step already holds its first command), and to rest half a step
    after the last one when it arrived (its last move stops within the acceleration limit).
    Those are steps of the acceleration, which a vehicle takes up over a time (it has to tilt):
    the trajectory's rise of the acceleration is centred on the step, so it begins before it.
    A trajectory that began its rise at the step would lag the path by the rise for good where
    the path flies on at the speed limit."""
    tau = path.times - path.times[0]
    ramp = ramp_time(path, accuracy)
    lead = 0.5 * float(tau[1]) + ramp if path.limits.model == "multirotor" else 0.0
    trail = 0.5 * float(tau[-1] - tau[-2]) + ramp if _still(path) else 0.0
    return lead, trail


def _still(path: FlownPath) -> bool:
    return bool(path.arrived or np.linalg.norm(path.positions[-1] - path.positions[-2]) < 1e-12)


def _dense_ends(path: FlownPath, ends: tuple[float, float]) -> np.ndarray:
    """The dense deviation times on the trajectory's clock: the recorded steps' (:func:`_dense`)
    and as dense over the lead and the trail (``ends``) before and after them."""
    tau = path.times - path.times[0]
    lead, trail = ends
    spacing = float(tau[1]) / DENSE
    before = np.linspace(-lead, 0.0, int(np.ceil(lead / spacing)) + 1)[:-1]
    after = np.linspace(tau[-1], tau[-1] + trail, int(np.ceil(trail / spacing)) + 1)[1:]
    return np.concatenate([before, _dense(tau), after]) + lead


def jerk_limit(path: FlownPath) -> float:
    """m/s^3: the jerk a Crazyflie can produce within the agent's acceleration limit
    (:meth:`~swarmplan.track.crazyflie.Crazyflie.max_jerk`: the gyro's range times the least
    thrust acceleration, g - max_accel)."""
    return Crazyflie().max_jerk(path.limits.max_accel)


def evaluate_fit(
    poly: Poly4D, path: FlownPath, ends: tuple[float, float]
) -> tuple[float, float, float, float]:
    """Largest deviation from the flown path (time-synchronised, between the recorded steps too,
    against the recorded polygon, held at its ends before and after it: ``ends`` = lead and
    trail), speed, acceleration and jerk of the exported trajectory."""
    tau = path.times - path.times[0]
    lead = ends[0]
    t = _dense_ends(path, ends)
    fitted = poly.evaluate(t)[:, :3]
    dev = float(np.linalg.norm(fitted - _flown_at(tau, path.positions, t - lead), axis=1).max())
    tp = np.linspace(0.0, poly.duration, poly.n_pieces * DENSE * 4 + 1)
    speed = float(np.linalg.norm(poly.evaluate(tp, 1)[:, :3], axis=1).max())
    accel = float(np.linalg.norm(poly.evaluate(tp, 2)[:, :3], axis=1).max())
    jerk = float(np.linalg.norm(poly.evaluate(tp, 3)[:, :3], axis=1).max())
    return dev, speed, accel, jerk


LIMIT_TARGET = 0.99  # a bound is held this far inside (room for float32 and between the grid points)
ACCEPT = 0.995  # a fit whose norms keep within this fraction of each bound on the grids is taken
CUTS_PER_ROUND = 32  # the highest peaks over each bound held per round
MAX_ROUNDS = 60  # rounds of cutting planes before a fit is given up
LDP_INFEASIBLE = 1e-10  # a dual residual this small: the constraints contradict each other
REFUSAL_PRECISION = 0.02  # relative: how finely a refusal brackets what would fit


def _ldp(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """argmin |y| subject to a y >= b, or None when no y meets it: Lawson and Hanson's least
    distance programme, solved as the non-negative least squares problem of its dual."""
    n = a.shape[1]
    if len(b) == 0:
        return np.zeros(n)
    scale = np.linalg.norm(a, axis=1)
    scale[scale == 0] = 1.0
    e = np.vstack([(a / scale[:, None]).T, (b / scale)[None]])
    f = np.zeros(n + 1)
    f[n] = 1.0
    u, _ = nnls(e, f, maxiter=50 * e.shape[1])
    r = e @ u - f
    if np.linalg.norm(r) < LDP_INFEASIBLE or r[n] > -LDP_INFEASIBLE:
        return None  # the constraints contradict each other
    return -r[:n] / r[n]


@dataclass
class _Problem:
    """The fit of one path with ``n`` pieces: the least-squares objective (with a snap penalty)
    under the end conditions, reduced to the free coefficients, and the matrices its limits and
    its deviation are measured with."""

    n: int
    breaks: np.ndarray  # (n + 1,) s: the joints, from 0 to the duration
    knots: np.ndarray
    nc: int
    duration: float  # s, the trajectory's (the flown path's, with its lead and trail)
    ends: tuple[float, float]  # s: the lead and the trail
    c_free: np.ndarray  # (3 nc,) the fit without limits
    reduce: np.ndarray  # (3 nc, m): coefficients = c_free + reduce @ y, |y|^2 / 2 the objective's rise
    d1: np.ndarray  # basis velocity on the limit grid
    d2: np.ndarray  # basis acceleration on the limit grid
    d3: np.ndarray  # basis jerk on the limit grid
    dev_basis: np.ndarray  # basis at the dense deviation times
    dev_target: np.ndarray  # the flown polygon there (N, 3)


def _problem(path: FlownPath, n: int, ends: tuple[float, float], snap: float = SNAP_WEIGHT) -> _Problem:
    """The fit with ``n`` pieces of equal durations, with the lead and the trail ``ends``: the
    least squares are to the recorded positions and, one a step, to the held ends over the lead
    and the trail."""
    tau = path.times - path.times[0]
    lead, trail = ends
    duration = float(tau[-1]) + lead + trail
    breaks = np.linspace(0.0, duration, n + 1)
    knots = _knots(breaks)
    step = float(tau[1])
    held_before = -step * np.arange(int(np.floor(lead / step)), 0, -1)
    held_after = tau[-1] + step * np.arange(1, int(np.floor(trail / step)) + 1)
    ls_t = np.concatenate([held_before, tau, held_after])
    ls_pos = _flown_at(tau, path.positions, ls_t)
    basis = _basis(knots, ls_t + lead)
    nc = basis.shape[1]
    gram = _snap_gram(knots, breaks)
    v0 = np.zeros(3) if lead else _end_velocity(path.times, path.positions, False, False)
    v1 = _end_velocity(path.times, path.positions, True, bool(trail))
    ends = np.array([0.0, duration])
    rows = [_basis(knots, ends, 0), _basis(knots, ends, 1)]
    rhs = [np.vstack([path.positions[0], path.positions[-1]]), np.vstack([v0, v1])]
    # An end at rest is a hover: no acceleration there either (a hovering vehicle cannot take up
    # an acceleration at once; it has to tilt first).
    rest = [t for t, at_rest in ((0.0, lead > 0), (duration, trail > 0)) if at_rest]
    if rest:
        rows.append(_basis(knots, np.array(rest), 2))
        rhs.append(np.zeros((len(rest), 3)))
    eq = np.kron(np.eye(3), np.vstack(rows))
    eq_rhs = np.vstack(rhs).T.reshape(-1)
    a = basis.T @ basis
    scale = np.trace(a) / max(np.trace(gram), 1e-300)
    h = np.kron(np.eye(3), a + snap * scale * gram)
    h += np.eye(len(h)) * 1e-12 * np.trace(h) / len(h)
    g = np.concatenate([basis.T @ ls_pos[:, j] for j in range(3)])
    # Null space of the end conditions: coefficients = x0 + null @ z.
    x0 = np.linalg.lstsq(eq, eq_rhs, rcond=None)[0]
    _, s, vt = np.linalg.svd(eq)
    null = vt[int(np.sum(s > 1e-10 * s[0])) :].T
    hz = null.T @ h @ null
    gz = null.T @ (g - h @ x0)
    chol = np.linalg.cholesky(hz)  # hz = L L'
    z_free = np.linalg.solve(hz, gz)
    reduce = null @ np.linalg.inv(chol).T
    grid = np.linspace(0.0, duration, max(n * DENSE * 4, len(tau) * 4) + 1)
    t = _dense_ends(path, ends)
    return _Problem(
        n, breaks, knots, nc, duration, (lead, trail), x0 + null @ z_free, reduce,
        _basis(knots, grid, 1), _basis(knots, grid, 2), _basis(knots, grid, 3),
        _basis(knots, t), _flown_at(tau, path.positions, t - lead),
    )  # fmt: skip


def _cuts(
    basis: np.ndarray, values: np.ndarray, bound: float, target: float, offset: np.ndarray | None = None
) -> tuple[list[np.ndarray], list[float]]:
    """Half-spaces that keep the norms of ``values`` (rows of ``basis`` applied to the
    coefficients, less ``offset``) at most ``target`` where their peaks are over ``bound``: at a
    peak, the component along its own direction is held (a tangent plane of the ball)."""
    norm = np.linalg.norm(values, axis=1)
    if norm.max(initial=0.0) <= bound:
        return [], []
    peaks = _peaks(norm, target)
    rows, rhs = [], []
    for k in peaks[np.argsort(-norm[peaks], kind="stable")][:CUTS_PER_ROUND]:
        u = values[k] / norm[k]
        rows.append(-np.kron(u, basis[k]))
        rhs.append(-target - (0.0 if offset is None else float(u @ offset[k])))
    return rows, rhs


def _solve(
    prob: _Problem, speed: float, accel: float, jerk: float, accuracy: float | None
) -> np.ndarray | None:
    """Coefficients (nc, 3) closest to the least-squares fit with the speed at most ``speed``, the
    acceleration at most ``accel``, the jerk at most ``jerk`` and (unless None) every dense
    point within ``accuracy`` of the flown path, all on the dense grids; None when no such
    coefficients exist (or the cutting planes do not settle). Each norm bound is met by tangent
    planes at the peaks that break it, added round by round (each plane is implied by the
    bound, so an empty set proves that none exists)."""
    g_rows: list[np.ndarray] = []
    g_rhs: list[float] = []
    for _ in range(MAX_ROUNDS):
        if g_rows:
            gm = np.array(g_rows)
            y = _ldp(gm @ prob.reduce, np.array(g_rhs) - gm @ prob.c_free)
            if y is None:
                return None
            flat = prob.c_free + prob.reduce @ y
        else:
            flat = prob.c_free
        coef = flat.reshape(3, prob.nc).T
        new_rows: list[np.ndarray] = []
        new_rhs: list[float] = []
        checks = [
            (prob.d1, prob.d1 @ coef, speed, None),
            (prob.d2, prob.d2 @ coef, accel, None),
            (prob.d3, prob.d3 @ coef, jerk, None),
        ]
        if accuracy is not None:
            checks.append(
                (prob.dev_basis, prob.dev_basis @ coef - prob.dev_target, accuracy, prob.dev_target)
            )
        for basis, values, limit, offset in checks:
            r, h = _cuts(basis, values, limit * ACCEPT, limit * LIMIT_TARGET, offset)
            new_rows += r
            new_rhs += h
        if not new_rows:
            return coef
        g_rows += new_rows
        g_rhs += new_rhs
    return None


_Found = tuple[Poly4D, float, float, float, float]  # poly, deviation, speed, accel, jerk


def _fit_n(path: FlownPath, prob: _Problem, accuracy: float | None, scale: float = 1.0) -> _Found | None:
    """The trajectory of ``prob`` within ``accuracy`` (None: any) and ``scale`` times the agent's
    speed and acceleration limits (and the jerk a Crazyflie can produce at that acceleration),
    checked on its float32 coefficients: (poly, deviation, speed, accel, jerk), or None."""
    lim = path.limits
    jerk_max = Crazyflie().max_jerk(lim.max_accel * scale)
    coef = _solve(prob, lim.speed_max * scale, lim.max_accel * scale, jerk_max, accuracy)
    if coef is None:
        return None
    poly = _to_poly(prob.knots, coef, prob.breaks)
    dev, speed, accel, jerk = evaluate_fit(poly, path, prob.ends)
    ok = speed <= lim.speed_max * scale and accel <= lim.max_accel * scale and jerk <= jerk_max
    if not ok or (accuracy is not None and dev > accuracy):
        return None
    return poly, dev, speed, accel, jerk


def _plain(prob: _Problem) -> Poly4D:
    """The least-squares fit of ``prob``, limits aside."""
    return _to_poly(prob.knots, prob.c_free.reshape(3, prob.nc).T, prob.breaks)


def _plain_deviation(path: FlownPath, n: int, ends: tuple[float, float]) -> float:
    """Deviation of the least-squares fit with ``n`` pieces, limits aside."""
    return evaluate_fit(_plain(_problem(path, n, ends)), path, ends)[0]


def _pieces_needed(path: FlownPath, accuracy: float, cap: int, ends: tuple[float, float]) -> int | None:
    """The fewest pieces (at most ``cap``) whose least-squares fit reaches ``accuracy``, by
    doubling and bisection; None when even ``cap`` does not."""

    def reaches(n: int) -> bool:
        return _plain_deviation(path, n, ends) <= accuracy

    hi = 1
    while not reaches(hi):
        if hi >= cap:
            return None
        hi = min(cap, hi * 2)
    lo = max(hi // 2, 1)
    while lo < hi:
        mid = (lo + hi) // 2
        if reaches(mid):
            hi = mid
        else:
            lo = mid + 1
    return hi


def _smallest(feasible: Callable[[float], bool], lo: float, hi: float) -> float:
    """The smallest value in [lo, hi] for which ``feasible`` holds (``hi`` does), to a relative
    REFUSAL_PRECISION, by bisection."""
    while hi - lo > REFUSAL_PRECISION * hi:
        mid = 0.5 * (lo + hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return hi


def fit(path: FlownPath, accuracy: float, max_pieces: int = MAX_PIECES, lead: float | None = None) -> Fit:
    """The trajectory with the fewest pieces within ``accuracy`` of the flown path and within the
    agent's speed, acceleration and jerk limits, on the flown timing, starting ``lead`` before
    the flown path's first step (at least its own, :func:`ends_of`; the swarm's trajectories
    start together). Raises :class:`LimitError` (saying what would fit) when ``max_pieces`` do
    not reach it."""
    own_lead, trail = ends_of(path, accuracy)
    ends = (max(own_lead, lead or 0.0), trail)
    # The least-squares fit says where to start: one held to the limits and the bound seldom
    # needs fewer pieces.
    first = _pieces_needed(path, accuracy, max_pieces, ends) or max_pieces
    tried: dict[int, _Found | None] = {}

    def attempt(n: int) -> _Found | None:
        if n not in tried:
            tried[n] = _fit_n(path, _problem(path, n, ends), accuracy)
        return tried[n]

    n, failed = first, first - 1
    while attempt(n) is None and n < max_pieces:
        failed, n = n, min(max_pieces, n + max(1, n // 4))
    found = attempt(n)
    if found is None:
        raise LimitError(_refusal(path, accuracy, max_pieces, ends))
    while n - failed > 1:  # the fewest pieces between the last that failed and n
        mid = (n + failed) // 2
        n, failed = (mid, failed) if attempt(mid) is not None else (n, mid)
    poly, dev, speed, accel, jerk = attempt(n)  # type: ignore[misc]
    return Fit(poly, dev, speed, accel, jerk, accuracy, ends[0])


def _refusal(path: FlownPath, accuracy: float, max_pieces: int, ends: tuple[float, float]) -> str:
    """Why ``max_pieces`` cannot fit the path at ``accuracy``, and what would: the smallest
    deviation bound within which they keep the limits, or (when they cannot keep the limits on
    the flown timing at all) how far the limits would have to rise."""
    lim = path.limits
    prob = _problem(path, max_pieces, ends)
    head = (
        f"agent {lim.id}: no trajectory of at most {max_pieces} equal pieces "
        f"({max_pieces * PIECE_BYTES} of the {MEMORY_BYTES}-byte trajectory memory) keeps within "
        f"{accuracy:g} m of its {path.duration:.1f} s "
        f"flown path with speed <= {lim.speed_max:g} m/s, acceleration <= {lim.max_accel:g} m/s^2 "
        f"and jerk <= {jerk_limit(path):.0f} m/s^3"
    )
    loose = _fit_n(path, prob, None)
    if loose is not None:
        need = _smallest(lambda e: _fit_n(path, prob, e) is not None, accuracy, loose[1])
        bound = math.ceil(need * 1e4) / 1e4
        return (
            f"{head}; {max_pieces} pieces keep them within {need:.4f} m: export it with "
            f"--max-deviation {bound:g} or more"
        )
    # Not even the limits alone: the flown timing asks more of the agent than it has.
    plain = _plain(prob)
    dev, speed, accel, jerk = evaluate_fit(plain, path, ends)
    hi = max(speed / lim.speed_max, accel / lim.max_accel, 1.0) * 1.01
    probe = max(accuracy, dev * 1.01)
    if _fit_n(path, prob, probe, hi) is None:
        return f"{head}; its flown timing needs {speed:.3f} m/s, {accel:.3f} m/s^2 and {jerk:.0f} m/s^3"
    s = _smallest(lambda k: _fit_n(path, prob, probe, k) is not None, 1.0, hi)
    return (
        f"{head}; on its flown timing it needs limits {s:.3f} times as high "
        f"({lim.speed_max * s:.3f} m/s, {lim.max_accel * s:.3f} m/s^2)"
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
