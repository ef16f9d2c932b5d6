"""Cost of short candidate segments (escape and smoothing), vectorized over a whole population.

A candidate is a polyline ``start → K free waypoints → end``. :class:`SegmentEncoding` maps
a decision vector (offsets of the K waypoints in a box around the line ``start → end``)
to the polyline; :class:`SegmentCost` scores ``(n, K+2, 3)`` polylines in one call:

- length (a straight, free segment costs exactly its length);
- turning: a vertex whose fillet of the model's turn radius R (``min_turn_radius`` for
  fixed wings, ``v²/a`` at cruise speed for multirotors, paper 004 eq 34) does not fit
  in half of each adjacent leg, including the turn from the current heading; climb
  angles above ``max_climb_angle``;
- clearance to static obstacles on points sampled densely along each polyline
  (``geometry.batch.ShapeBatch``), below the ground/terrain floor and outside ``bounds``;
- threats (soft, inside ``r_max``);
- moving obstacles at their *predicted* positions (``motion.poses_at``) at the time the
  agent would reach each sample at cruise speed;
- other agents at their intended positions at that time (their segment or route, else
  their velocity extrapolated for a few seconds).

Every penalty is zero for a path with the required clearance everywhere, so such a path
costs its length plus its turning term (zero for a straight segment).

A call is one compiled kernel (``_segment_kernel``: samples computed on the fly, bodies and
intents culled per leg, samples skipped only where a distance proves they add zero); the
numpy methods below (``sample``, ``static_penalty``, ...) are its reference
(``terms_reference``) and its fallback for meshes, terrain peaks and threats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.geometry.batch import ShapeBatch
from swarmplan.planner._segment_pack import analytic, pack_bodies, pack_intents
from swarmplan.runtime.compiled import kernel_module
from swarmplan.world.motion import poses_at

_EPS = 1e-9
_ZERO3 = np.zeros(3)
# Names of the terms, in the order of the kernel's columns (swarmplan.planner._segment_kernel).
TERMS = ("length", "turning", "static", "vertices", "floor_bounds", "threats", "moving", "agents")
_STATIC, _VERTICES, _FLOOR, _THREATS, _MOVING = 2, 3, 4, 5, 6


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors (exactly 0 for parallel ones, unlike arccos of a rounded dot)."""
    # The cross product written out: np.cross costs ~20 µs of axis juggling on these small arrays.
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), np.sum(a * b, axis=-1))


@dataclass(frozen=True)
class Weights:
    """Penalty weights (per metre of path unless noted)."""

    clearance: float = 200.0  # per metre of path per metre of missing clearance
    collision: float = 2000.0  # per metre of path inside an obstacle (clearance < 0)
    floor: float = 200.0  # below ground/terrain clearance
    bounds: float = 200.0
    turn: float = 1.0  # m per radian of heading change (mild smoothness term)
    turn_radius: float = 20.0  # per metre of fillet tangent that does not fit
    climb: float = 50.0  # per metre of path per radian above the climb limit
    threat: float = 20.0  # per metre of path, scaled by the threat's weight and depth
    moving: float = 200.0
    agents: float = 100.0
    vertex: float = 20.0  # per metre a free waypoint lacks of ``vertex_clearance``


def _points_box(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    flat = pts.reshape(-1, 3)
    return flat.min(axis=0), flat.max(axis=0)


@dataclass
class Intent:
    """Where another agent means to be: a polyline with times (piecewise linear, then it stays)."""

    times: np.ndarray  # (m,), increasing, absolute sim time
    points: np.ndarray  # (m, 3)
    radius: float
    separation: np.ndarray  # (3,)

    def at(self, t: np.ndarray) -> np.ndarray:
        """Positions at times ``t`` (any shape) → (..., 3)."""
        if len(self.times) == 1:
            return np.broadcast_to(self.points[0], t.shape + (3,)).copy()
        return np.stack([np.interp(t, self.times, self.points[:, k]) for k in range(3)], axis=-1)


class SegmentEncoding:
    """Decision vector ↔ polyline: K waypoints offset in a box around the line start → end.

    Waypoint k sits at fraction k/(K+1) of the line plus an offset (along, lateral, vertical)
    in the line's frame; along ∈ ±``along`` (default ``width``), lateral ∈ ±``width``,
    vertical ∈ ±``height``; backing out of a pocket needs negative along-offsets.
    Waypoints are clipped into ``lo``..``hi`` (the flight volume shrunk by the radius).
    """

    def __init__(
        self,
        start: np.ndarray,
        end: np.ndarray,
        n_free: int,
        width: float,
        height: float,
        along: float | None = None,
        lo: np.ndarray | None = None,
        hi: np.ndarray | None = None,
    ):
        self.start = np.asarray(start, dtype=float)
        self.end = np.asarray(end, dtype=float)
        self.k = int(n_free)
        d = self.end - self.start
        self.length = float(np.linalg.norm(d))
        e1 = d / self.length if self.length > _EPS else np.array([1.0, 0.0, 0.0])
        e2 = np.cross([0.0, 0.0, 1.0], e1)
        if np.linalg.norm(e2) < 1e-6:
            e2 = np.array([0.0, 1.0, 0.0])
        e2 = e2 / np.linalg.norm(e2)
        e3 = np.cross(e1, e2)
        self.frame = np.stack([e1, e2, e3])  # rows
        a = width if along is None else along
        half = np.array([a, width, height])
        self.upper = np.tile(half, self.k)
        self.lower = -self.upper
        self.lo = lo
        self.hi = hi
        s = np.arange(1, self.k + 1) / (self.k + 1)
        self.base = self.start + s[:, None] * d  # (K, 3)

    @property
    def dim(self) -> int:
        return 3 * self.k

    def decode(self, X: np.ndarray) -> np.ndarray:
        """(n, 3K) → polylines (n, K+2, 3) (compiled: numpy's dozen small operations cost as
        much as scoring the population)."""
        X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
        clip = self.lo is not None
        lo = np.asarray(self.lo, dtype=float) if clip else _ZERO3
        hi = np.asarray(self.hi, dtype=float) if clip else _ZERO3
        decode_segments = kernel_module("swarmplan.planner._decode_kernel").decode_segments
        return decode_segments(X, self.frame, self.base, self.start, self.end, lo, hi, clip)

    def encode(self, waypoints: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`decode` for K free waypoints (no clipping) → (3K,)."""
        off = (np.asarray(waypoints, dtype=float) - self.base) @ self.frame.T
        return np.clip(off.reshape(-1), self.lower, self.upper)


@dataclass(frozen=True)
class Flyer:
    """The agent whose segments are scored: its radius and its flight limits."""

    radius: float  # m
    speed: float  # m/s, the cruise speed the segment is flown at
    turn_radius: float  # m
    max_climb: float  # rad, the steepest flight-path angle
    min_altitude: float  # m above the ground
    fixed_wing: bool = False


class SegmentCost:
    """Scores candidate polylines of one agent (a simulation's: ``EscapePlanner.make_cost``)."""

    def __init__(
        self,
        world,  # noqa: ANN001 - swarmplan.world.World
        flyer: Flyer,
        *,
        t0: float = 0.0,
        margin: float = 1.0,
        heading: np.ndarray | None = None,
        start_clearance: float | None = None,
        intents: list[Intent] | None = None,
        weights: Weights | None = None,
        spacing: float | None = None,
        vertex_clearance: float = 0.0,
    ):
        self.world = world
        self.r = float(flyer.radius)
        self.speed = max(float(flyer.speed), 0.1)
        self.turn_radius = float(flyer.turn_radius)
        self.max_climb = float(flyer.max_climb)
        self.min_alt = float(flyer.min_altitude)
        self.t0 = float(t0)
        self.margin = float(margin)
        self.heading = None if heading is None else _unit(np.asarray(heading, dtype=float))
        self.intents = intents or []
        self.w = weights or Weights()
        self.spacing = spacing if spacing is not None else max(0.5 * self.r, 0.25)
        self.fixed_wing = bool(flyer.fixed_wing)
        self.vertex_clearance = float(vertex_clearance)
        self.static = [o for o in world.obstacles if not o.moving]
        self.moving = [o for o in world.obstacles if o.moving]
        self.batch = ShapeBatch(self.static)
        self._moving_batch = ShapeBatch(self.moving)
        # Predicted centres of the moving obstacles on a 0.2 s grid, extended as candidates
        # need (a per-escape constant: the same for every call).
        self._pose_step = 0.2
        self._pose_grid = np.zeros((0, len(self.moving), 3))
        # Culling data: a body can only add to the cost where it comes within reach of the
        # sampled points, so the terms skip those that cannot (the values are unchanged).
        self._static_center = np.array([o.position for o in self.static]).reshape(-1, 3)
        self._static_bound = np.array([o.bounding_radius for o in self.static])
        self._moving_bound = np.array([o.bounding_radius for o in self.moving])
        # The compiled kernel's constants; meshes leave their terms to numpy (see terms()).
        self._kernel_static = analytic(self.static)
        self._kernel_moving = analytic(self.moving)
        self._static_pack = pack_bodies(self.static if self._kernel_static else [])
        self._moving_pack = pack_bodies(self.moving if self._kernel_moving else [])
        self._vstep = np.zeros(len(self.moving))
        self._intents = pack_intents(self.intents, self.r)
        self._args_key: tuple | None = None
        self._args: tuple = ()
        self.required = self.r + self.margin
        # Near the start the agent may already be closer than required: ask only for what
        # it has plus the distance travelled (the path must not get worse, then must clear).
        self.start_clearance = np.inf if start_clearance is None else float(start_clearance)
        # Samples per polyline. The cost only steers the search (FCL validates the result), so
        # on kilometre-long segments a few metres' spacing is enough; 4000 samples made one
        # fixed-wing escape in the 2 km world of paper 001 cost over a minute.
        self.max_samples = 800

    def _kernel_args(self) -> tuple:
        """The kernel's per-escape arguments (rebuilt if a setting was changed since)."""
        key = (self.spacing, self.vertex_clearance, self.max_samples, self.w, self.start_clearance, self.t0)
        key += (self.r, self.required, self.speed, self.turn_radius, self.max_climb, self.min_alt)
        key += (self.fixed_wing, None if self.heading is None else tuple(self.heading))
        if self._args_key == key:
            return self._args
        w, world = self.w, self.world
        floor = max(self.min_alt, world.terrain_clearance if world.peaks else 0.0)
        f = [self.r, self.required, self.start_clearance, self.speed, self.t0, self.spacing, self.turn_radius]
        f += [self.max_climb, self.heading is not None, self.fixed_wing, self.vertex_clearance, floor]
        f += [self.max_samples, self._pose_step]
        wv = [w.clearance, w.collision, w.floor, w.bounds, w.turn, w.turn_radius, w.climb, w.moving, w.agents]
        static_k = bool(self.static) and self._kernel_static
        flags = [static_k, static_k and self.vertex_clearance > 0, not world.peaks]
        sp, mp, ip = self._static_pack, self._moving_pack, self._intents
        self._args = (
            np.array(f, dtype=float),
            np.array(wv + [w.vertex], dtype=float),
            _ZERO3 if self.heading is None else np.ascontiguousarray(self.heading, dtype=float),
            (np.asarray(world.bounds_min, dtype=float), np.asarray(world.bounds_max, dtype=float)),
            np.array(flags, dtype=np.int64),
            tuple(sp[k] for k in ("code", "pos", "rot", "ident", "prm", "bound")),
            tuple(mp[k] for k in ("code", "rot", "ident", "prm", "bound")),
            tuple(ip[k] for k in ("times", "points", "nk", "scale", "contact", "reach", "vmax")),
        )
        self._args_key = key
        return self._args

    # ------------------------------------------------------------------ sampling

    def sample(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (n, S, 3) sampled along each polyline, their path-length weights ds (n, S) and
        arc length s (n, S) from the start. Same sample count per leg for every candidate."""
        n, m, _ = P.shape
        legs = np.diff(P, axis=1)  # (n, m-1, 3)
        lens = np.linalg.norm(legs, axis=-1)
        per_leg = int(np.clip(np.ceil(lens.max() / self.spacing), 4, max(4, self.max_samples // (m - 1))))
        u = (np.arange(per_leg) + 0.5) / per_leg  # midpoints: weights sum to each leg's length
        pts = P[:, :-1, None, :] + u[None, None, :, None] * legs[:, :, None, :]
        ds = np.broadcast_to(lens[:, :, None] / per_leg, (n, m - 1, per_leg))
        cum = np.concatenate([np.zeros((n, 1)), np.cumsum(lens, axis=1)[:, :-1]], axis=1)
        s = cum[:, :, None] + u[None, None, :] * lens[:, :, None]
        return pts.reshape(n, -1, 3), ds.reshape(n, -1), s.reshape(n, -1)

    # ------------------------------------------------------------------ terms

    def length(self, P: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.diff(P, axis=1), axis=-1).sum(axis=1)

    def turning(self, P: np.ndarray) -> np.ndarray:
        """Mild heading-change term plus the turn-radius and climb-angle violations."""
        legs = np.diff(P, axis=1)
        lens = np.linalg.norm(legs, axis=-1)
        dirs = legs / np.maximum(lens, _EPS)[..., None]
        valid = lens > 1e-6
        theta = np.where(valid[:, 1:] & valid[:, :-1], _angle(dirs[:, :-1], dirs[:, 1:]), 0.0)
        avail = np.minimum(lens[:, 1:], lens[:, :-1]) / 2
        need = self.turn_radius * np.tan(np.minimum(theta, 3.0) / 2)
        cost = self.w.turn * theta.sum(axis=1) + self.w.turn_radius * np.maximum(need - avail, 0).sum(axis=1)
        if self.heading is not None:
            th0 = np.where(valid[:, 0], _angle(dirs[:, 0], self.heading[None]), 0.0)
            need0 = self.turn_radius * np.tan(np.minimum(th0, 3.0) / 2)
            k = self.w.turn_radius if self.fixed_wing else 0.1 * self.w.turn_radius
            cost = cost + self.w.turn * th0 + k * np.maximum(need0 - lens[:, 0], 0)
        horiz = np.linalg.norm(legs[..., :2], axis=-1)
        climb = np.arctan2(np.abs(legs[..., 2]), np.maximum(horiz, _EPS))
        cost = cost + self.w.climb * (np.maximum(climb - self.max_climb, 0) * lens).sum(axis=1)
        return cost

    def _required(self, s: np.ndarray) -> np.ndarray:
        return np.minimum(self.required, self.start_clearance + self.r + s)

    def _blocks(self, pts: np.ndarray, legs: tuple | None) -> tuple[np.ndarray, np.ndarray, int]:
        """Boxes (n, B, 3) of blocks of consecutive samples: each leg's (``legs``, from the
        polylines' vertices) or each candidate's; and the samples per block."""
        if legs is None:
            lo, hi = pts.min(axis=1)[:, None], pts.max(axis=1)[:, None]
        else:
            lo, hi = legs
        return lo, hi, pts.shape[1] // lo.shape[1]

    @staticmethod
    def _block_gap(lo: np.ndarray, hi: np.ndarray, blo: np.ndarray, bhi: np.ndarray) -> np.ndarray:
        """Distance (n, B, M) from each block box to each body box ``blo``..``bhi`` (M, 3)."""
        g = np.maximum(np.maximum(blo - hi[:, :, None, :], lo[:, :, None, :] - bhi), 0.0)
        return np.sqrt(np.einsum("nbmk,nbmk->nbm", g, g))

    def static_penalty(
        self, pts: np.ndarray, ds: np.ndarray, s: np.ndarray, legs: tuple | None = None
    ) -> np.ndarray:
        """Clearance and collision along the samples. Only blocks of samples (legs) that come
        within ``required`` of a body's bounding sphere are measured, against those bodies:
        every other sample has a distance >= required, where both terms are exactly zero."""
        n, S, _ = pts.shape
        if not self.static:
            return np.zeros(n)
        lo, hi, per = self._blocks(pts, legs)
        B = lo.shape[1]
        gap = self._block_gap(lo, hi, self._static_center, self._static_center) - self._static_bound
        near = (gap < self.required).reshape(n * B, -1)
        blocks = np.flatnonzero(near.any(axis=1))
        if not len(blocks):
            return np.zeros(n)
        bodies = np.flatnonzero(near[blocks].any(axis=0))
        q = pts.reshape(n * B, per, 3)[blocks].reshape(-1, 3)
        # Then per point: only the bodies whose bounding sphere it comes within ``required`` of
        # (the others are farther than that), as (point, body) pairs.
        rel = q[:, None, :] - self._static_center[bodies][None]
        reach = self.required + self._static_bound[bodies]
        inside = np.einsum("ijk,ijk->ij", rel, rel) < reach * reach
        rows = np.flatnonzero(inside.any(axis=1))
        d = np.full(len(q), np.inf)
        n_pairs = int(np.count_nonzero(inside))
        if n_pairs and 3 * n_pairs < len(rows) * len(bodies):
            # Sparse: each point near few of many bodies (long legs among scattered bodies).
            pi, bj = np.nonzero(inside)
            dp = self.batch.pair_distance(q[pi], bodies[bj])
            starts = np.flatnonzero(np.r_[True, pi[1:] != pi[:-1]])  # pi is sorted (row-major)
            d[pi[starts]] = np.minimum.reduceat(dp, starts)
        elif n_pairs:
            # Dense (e.g. one hub near everything): the matrix of the near rows is cheaper.
            dm = self.batch.distance(q[rows], subset=bodies)
            d[rows] = np.where(inside[rows], dm, np.inf).min(axis=1)
        d = d.reshape(len(blocks), per)
        req = self._required(s.reshape(n * B, per)[blocks])
        dsb = ds.reshape(n * B, per)[blocks]
        f = self.w.clearance * (np.maximum(req - d, 0) * dsb).sum(axis=1) + self.w.collision * (
            (d < self.r) * dsb
        ).sum(axis=1)
        return np.bincount(blocks // B, weights=f, minlength=n)

    def vertex_penalty(self, P: np.ndarray) -> np.ndarray:
        """Free waypoints closer to a static surface than ``vertex_clearance`` (hard to reach)."""
        n, m, _ = P.shape
        if not self.static or self.vertex_clearance <= 0 or m <= 2:
            return np.zeros(n)
        d = self.batch.distance(P[:, 1:-1].reshape(-1, 3))
        c = d.min(axis=1).reshape(n, m - 2) - self.r
        return self.w.vertex * np.maximum(self.vertex_clearance - c, 0).sum(axis=1)

    def floor_bounds_penalty(self, pts: np.ndarray, ds: np.ndarray, box: tuple | None = None) -> np.ndarray:
        w = self.world
        floor = max(self.min_alt, w.terrain_clearance if w.peaks else 0.0)
        lo, hi = _points_box(pts) if box is None else box
        if (
            not w.peaks
            and lo[2] >= floor
            and np.all(lo >= w.bounds_min + self.r)
            and np.all(hi <= w.bounds_max - self.r)
        ):
            return np.zeros(len(pts))  # every point above the floor and inside: both terms are 0
        h = w.terrain_height(pts[..., :2])
        below = np.maximum(h + floor - pts[..., 2], 0)
        out = np.maximum(w.bounds_min + self.r - pts, 0).sum(-1) + np.maximum(
            pts - w.bounds_max + self.r, 0
        ).sum(-1)
        return self.w.floor * (below * ds).sum(1) + self.w.bounds * (out * ds).sum(1)

    def threat_penalty(self, pts: np.ndarray, ds: np.ndarray) -> np.ndarray:
        cost = np.zeros(len(pts))
        for th in self.world.threats:
            d = np.linalg.norm(pts - th.position, axis=-1)
            depth = np.clip((th.r_max - d) / max(th.r_max - th.r_min, _EPS), 0.0, 1.0)
            cost = cost + self.w.threat * th.weight * (depth * ds).sum(1)
            if th.avoid:  # a core the world keeps flight out of costs like an obstacle's inside
                inside = np.maximum(th.r_min + self.r - d, 0.0)
                cost = cost + self.w.collision * (inside * ds).sum(1)
        return cost

    def _centers(self, kmax: int) -> np.ndarray:
        """Predicted centres (kmax + 1, Mm, 3) of the moving obstacles at t0 + k * 0.2 s."""
        have = len(self._pose_grid)
        if have <= kmax:
            grid = np.arange(have, kmax + 1) * self._pose_step + self.t0
            more = np.empty((len(grid), len(self.moving), 3))
            for j, o in enumerate(self.moving):
                if o.motion.type == "linear":
                    # motion.pose_at's formula for all the times at once (the same values).
                    more[:, j] = o.position + o.motion.velocity * grid[:, None]
                else:
                    more[:, j] = [poses_at([o], tt)[0][0] for tt in grid]
            self._pose_grid = np.concatenate([self._pose_grid, more])
            # Largest move of each centre between grid times (the kernel's tracing bound).
            if len(self._pose_grid) > 1:
                steps = np.linalg.norm(np.diff(self._pose_grid, axis=0), axis=-1).max(axis=0)
                self._vstep = steps * (1 + 1e-9)
        return self._pose_grid[: kmax + 1]

    def moving_penalty(
        self, pts: np.ndarray, ds: np.ndarray, s: np.ndarray, legs: tuple | None = None
    ) -> np.ndarray:
        n, S, _ = pts.shape
        if not self.moving:
            return np.zeros(n)
        t = self.t0 + s / self.speed
        # Predicted poses on a 0.2 s grid (translations only, so shifting the points is exact).
        k = np.round((t - self.t0) / self._pose_step).astype(int)
        centers = self._centers(int(k.max()))  # (T, Mm, 3)
        cost = np.zeros(n)
        # A body whose centre track stays farther than its bounding radius + ``required`` from
        # a block of samples adds nothing there.
        lo, hi, per = self._blocks(pts, legs)
        B = lo.shape[1]
        gap = self._block_gap(lo, hi, centers.min(axis=0), centers.max(axis=0)) - self._moving_bound
        near = (gap < self.required).reshape(n * B, -1)
        for j in np.flatnonzero(near.any(axis=0)):
            blocks = np.flatnonzero(near[:, j])
            q = pts.reshape(n * B, per, 3)[blocks].reshape(-1, 3)
            kb = k.reshape(n * B, per)[blocks].reshape(-1)
            rel = q - centers[kb, j]
            d = self._moving_batch.distance(rel + self.moving[j].position, subset=np.array([j]))[:, 0]
            d = d.reshape(len(blocks), per)
            dsb = ds.reshape(n * B, per)[blocks]
            f = self.w.moving * (np.maximum(self.required - d, 0) * dsb).sum(1) + self.w.collision * (
                (d < self.r) * dsb
            ).sum(1)
            cost = cost + np.bincount(blocks // B, weights=f, minlength=n)
        return cost

    def agent_penalty_reference(self, pts: np.ndarray, ds: np.ndarray, s: np.ndarray) -> np.ndarray:
        """The agents' term by brute force: every intent interpolated at every sample (tests)."""
        cost = np.zeros(len(pts))
        t = self.t0 + s / self.speed
        for it in self.intents:
            scale = it.separation + self.r + it.radius
            q = it.at(t)
            e = np.linalg.norm((pts - q) / scale, axis=-1)
            cost = cost + self.w.agents * (np.maximum(1.2 - e, 0) * ds).sum(1)
            d = np.linalg.norm(pts - q, axis=-1)
            cost = cost + self.w.collision * ((d < self.r + it.radius) * ds).sum(1)
        return cost

    # ------------------------------------------------------------------ total

    def terms(self, P: np.ndarray) -> dict[str, np.ndarray]:
        """Every term of polylines ``P`` (n, m, 3) → {name: (n,)} (the compiled kernel, with
        numpy for meshes, terrain peaks and threats)."""
        out = self._kernel(P)
        return {name: out[:, k] for k, name in enumerate(TERMS)}

    def terms_reference(self, P: np.ndarray) -> dict[str, np.ndarray]:
        """The terms in numpy on materialised samples (the culled numpy terms and the
        brute-force agents' term): what the kernel must equal (tests)."""
        P = np.asarray(P, dtype=float)
        pts, ds, s = self.sample(P)
        a, b = P[:, :-1], P[:, 1:]
        legs = (np.minimum(a, b), np.maximum(a, b))
        return {
            "length": self.length(P),
            "turning": self.turning(P),
            "static": self.static_penalty(pts, ds, s, legs),
            "vertices": self.vertex_penalty(P),
            "floor_bounds": self.floor_bounds_penalty(pts, ds),
            "threats": self.threat_penalty(pts, ds),
            "moving": self.moving_penalty(pts, ds, s, legs),
            "agents": self.agent_penalty_reference(pts, ds, s),
        }

    def __call__(self, P: np.ndarray) -> np.ndarray:
        """Total cost of polylines ``P`` (n, m, 3) → (n,)."""
        return self._kernel(P)[:, len(TERMS)]

    def _kernel(self, P: np.ndarray) -> np.ndarray:
        """(n, 9): the terms in ``TERMS`` order and their total (summed in that order)."""
        segment_terms = kernel_module("swarmplan.planner._segment_kernel").segment_terms
        P = np.ascontiguousarray(P, dtype=float)
        n = len(P)
        world = self.world
        args = self._kernel_args()
        out, need = segment_terms(P, *args, self._pose_grid, self._vstep)
        if need > len(self._pose_grid):
            # Movers' centres up to the longest candidate's end, then the same call again.
            self._centers(need - 1)
            out, need = segment_terms(P, *args, self._pose_grid, self._vstep)
        numpy_static = bool(self.static) and not self._kernel_static
        numpy_moving = bool(self.moving) and not self._kernel_moving
        if numpy_static or numpy_moving or world.peaks or world.threats:
            # Meshes (distance grids), terrain and threats: numpy on materialised samples.
            pts, ds, s = self.sample(P)
            a, b = P[:, :-1], P[:, 1:]
            legs = (np.minimum(a, b), np.maximum(a, b))
            if numpy_static:
                out[:, _STATIC] = self.static_penalty(pts, ds, s, legs)
                out[:, _VERTICES] = self.vertex_penalty(P)
            if numpy_moving:
                out[:, _MOVING] = self.moving_penalty(pts, ds, s, legs)
            if world.peaks:
                out[:, _FLOOR] = self.floor_bounds_penalty(pts, ds, _points_box(P))
            out[:, _THREATS] = self.threat_penalty(pts, ds)
            total = np.zeros(n)
            for k in range(len(TERMS)):
                total = total + out[:, k]
            out[:, len(TERMS)] = total
        return out


def agent_intents(
    sim, agent: int, horizon: float = 4.0, extra: dict[int, Intent] | None = None
) -> list[Intent]:  # noqa: ANN001
    """Intended positions of every other agent: its segment (or route) at cruise speed, else
    its current velocity extrapolated for ``horizon`` s; arrived agents stand still."""
    s = sim.state
    p = sim.params
    out = []
    for j in range(sim.n):
        if j == agent or s.mode[j] in ("collided", "failed"):
            continue
        if extra and j in extra:
            out.append(extra[j])
            continue
        pos = s.position[j].copy()
        sep, rad = p.separation[j], float(p.radius[j])
        if s.mode[j] == "arrived":
            out.append(Intent(np.array([s.t]), pos[None], rad, sep))
            continue
        path = None
        if s.mode[j] in ("escape", "smoothing") and s.segment[j] is not None:
            path = s.segment[j][s.segment_index[j] :]
        elif s.route[j] is not None:
            path = s.route[j][s.route_index[j] :]
        if path is not None and len(path):
            pts = np.vstack([pos, path])
            seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            times = s.t + np.concatenate([[0.0], np.cumsum(seg)]) / max(float(p.speed_cruise[j]), 0.1)
            keep = np.concatenate([[True], seg > 1e-9])
            out.append(Intent(times[keep], pts[keep], rad, sep))
            continue
        v = s.velocity[j]
        out.append(Intent(np.array([s.t, s.t + horizon]), np.stack([pos, pos + v * horizon]), rad, sep))
    return out
