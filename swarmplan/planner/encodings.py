"""Path encodings for global planning: a decision vector ↔ a 3-D path, vectorized over a population.

Two encodings, both built on the frame of paper 000's eq (1): ``x'`` along start→goal
(S→E), ``y'`` horizontal and perpendicular to it, ``z'`` completing the right-handed frame
(tilted back by the climb angle θ of S→E, so it is vertical when S and E are level)::

    e_x = ( cosφ cosθ,  sinφ cosθ, sinθ)
    e_y = (-sinφ,       cosφ,      0   )
    e_z = (-cosφ sinθ, -sinφ sinθ, cosθ)

- :class:`PlaneEncoding` (papers 000 and 004): S→E is cut into ``D + 1`` equal parts and
  waypoint ``k`` lies on the plane through ``S + k/(D+1)·(E - S)`` perpendicular to S→E,
  at lateral offset ``y_k`` and vertical offset ``z_k`` (004's decision vector
  ``L = [y_2..y_{n-1}, z_2..z_{n-1}]``). Paper 004 uses planes perpendicular to the x axis;
  planes perpendicular to S→E are the same construction in the rotated frame of 000 and
  work for any start/goal (004's scenario runs diagonally), so both papers share it.
  The path is the broken line S → waypoints → E.
- :class:`SplineEncoding` (paper 002): the same plane offsets are *control points* of a
  cubic spline (scipy ``CubicSpline``, natural: 002 eq 15) through S, the control points and E, on
  the uniform parameter ``K = {0, k_1, .., k_M, 1}`` of 002's interpolation steps. Paper 002
  lets its fish move the control points freely in the box; keeping them on planes across
  S→E keeps the spline from folding back on itself, which free points make likely.

Decoded points are clipped into the flight volume shrunk by the agent's clearance, and
lifted above ``floor(x, y)`` (the terrain plus the altitude floor) when given, so every
decoded vertex at least stays inside the bounds and above the ground.
``decode(X)`` gives the *nodes* (n, K, 3) a cost model scores and the agent flies as its
route; ``dense(X)`` gives a finely resampled polyline (n, P, 3) for clearance checks.
The validity of the chosen path is then decided by FCL (``global_path.validate_path``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.geometry.polyline import resample_uniform


def se_frame(start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Rows e_x, e_y, e_z of paper 000's eq (1) rotation for the line start→goal."""
    d = np.asarray(goal, float) - np.asarray(start, float)
    horiz = float(np.hypot(d[0], d[1]))
    phi = float(np.arctan2(d[1], d[0])) if horiz > 1e-12 else 0.0
    theta = float(np.arctan2(d[2], horiz))
    cp, sp, ct, st = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    return np.array([[cp * ct, sp * ct, st], [-sp, cp, 0.0], [-cp * st, -sp * st, ct]])


class PlaneEncoding:
    """Waypoints on ``waypoints`` planes perpendicular to start→goal (papers 000 eq 1, 004 §2.1)."""

    name = "planes"

    def __init__(
        self,
        start: np.ndarray,
        goal: np.ndarray,
        waypoints: int,
        lateral: float,
        vertical: float,
        box_min: np.ndarray,
        box_max: np.ndarray,
        step: float = 1.0,
        floor: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        if waypoints < 1:
            raise ValueError("waypoints must be >= 1")
        self.start = np.asarray(start, float)
        self.goal = np.asarray(goal, float)
        self.D = int(waypoints)
        self.frame = se_frame(self.start, self.goal)
        self.box_min = np.asarray(box_min, float)
        self.box_max = np.asarray(box_max, float)
        self.step = float(step)
        self.floor = floor
        span = float(np.linalg.norm(self.goal - self.start))
        self.dense_count = int(np.clip(np.ceil(2.0 * span / max(self.step, 1e-9)), 2 * self.D + 4, 1000))
        self.dim = 2 * self.D
        self.lower = np.concatenate([np.full(self.D, -lateral), np.full(self.D, -vertical)])
        self.upper = -self.lower
        s = np.arange(1, self.D + 1) / (self.D + 1)
        self.base = self.start + s[:, None] * (self.goal - self.start)  # (D, 3) plane centres

    @property
    def straight(self) -> np.ndarray:
        """The decision vector of the straight line S→E (all offsets zero)."""
        return np.zeros(self.dim)

    def warm_start(self) -> np.ndarray:
        """Structured starting points (k, dim): the straight line, half-sine detours to each side
        at a quarter, half and all of the lateral range, and over the top at half and all of the
        vertical range. Half sines leave start and goal straight and turn gently (fixed wings)."""
        s = np.arange(1, self.D + 1) / (self.D + 1)
        bump = np.sin(np.pi * s)
        lateral, vertical = self.upper[0], self.upper[self.D]
        rows = [np.zeros(self.dim)]
        for side in (1.0, -1.0):
            for w in (0.25, 0.5, 1.0):
                rows.append(np.concatenate([side * w * lateral * bump, np.zeros(self.D)]))
        for w in (0.5, 1.0):
            rows.append(np.concatenate([np.zeros(self.D), w * vertical * bump]))
        return np.array(rows)

    def control_points(self, X: np.ndarray) -> np.ndarray:
        """(n, D, 3) waypoints in world coordinates, clipped into the box."""
        X = np.atleast_2d(np.asarray(X, float))
        y, z = X[:, : self.D], X[:, self.D :]
        pts = self.base[None] + y[..., None] * self.frame[1] + z[..., None] * self.frame[2]
        return self._clip(pts)

    def _clip(self, pts: np.ndarray) -> np.ndarray:
        """Into the box, and above ``floor(x, y)`` (e.g. the terrain plus the altitude floor)."""
        pts = np.clip(pts, self.box_min, self.box_max)
        if self.floor is not None:
            pts[..., 2] = np.clip(np.maximum(pts[..., 2], self.floor(pts[..., :2])), None, self.box_max[2])
        return pts

    def decode(self, X: np.ndarray) -> np.ndarray:
        """(n, D + 2, 3): S, the waypoints, E."""
        c = self.control_points(X)
        n = len(c)
        return np.concatenate(
            [np.broadcast_to(self.start, (n, 1, 3)), c, np.broadcast_to(self.goal, (n, 1, 3))], axis=1
        )

    def dense(self, X: np.ndarray, nodes: np.ndarray | None = None) -> np.ndarray:
        """(n, P, 3): each path resampled at ``P`` points evenly spaced along it; P puts them
        ``step`` apart on a path twice as long as start→goal (longer paths are sampled sparser)."""
        nodes = self.decode(X) if nodes is None else nodes
        return resample_uniform(nodes, self.dense_count)


class SplineEncoding(PlaneEncoding):
    """A cubic spline through S, ``waypoints`` control points on planes across S→E, and E (paper 002)."""

    name = "spline"

    def __init__(self, *args, samples: int = 40, **kwargs):
        super().__init__(*args, **kwargs)
        self.samples = max(int(samples), self.D + 2)
        self.knots = np.linspace(0.0, 1.0, self.D + 2)
        self.t = np.linspace(0.0, 1.0, self.samples)

    def decode(self, X: np.ndarray) -> np.ndarray:
        """(n, samples, 3): the spline sampled at ``samples`` uniform parameter values."""
        ctrl = super().decode(X)  # (n, D+2, 3)
        # 002 eq 15: natural end conditions, S''(x_0) = S''(x_n) = 0
        from scipy.interpolate import CubicSpline  # here: scipy.interpolate is slow to import

        pts = self._clip(CubicSpline(self.knots, ctrl, axis=1, bc_type="natural")(self.t))
        pts[:, 0], pts[:, -1] = self.start, self.goal
        return pts
