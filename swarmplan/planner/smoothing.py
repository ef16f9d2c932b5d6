"""Curvature smoothing: arc fillets (paper 004 §6) and optimized smoothing segments.

``fillet_path`` (in :mod:`swarmplan.geometry.polyline`, re-exported here) replaces each
corner of a polyline by a circular arc of radius ρ = v²/a (paper 004 eq 34: a = v²/ρ with
the rated speed v and acceleration a), tangent to both legs; a corner whose arc would not
fit in half of each adjacent leg, or whose arc collides (``collision_check``), keeps its
sharp corner (the paper's "special broken points", where the UAV stops instead). Global
routes, escapes and smoothing segments are all filleted before they are flown.

:class:`CurvatureSmoother` watches agents flying APF: when the point they are attracted to
(the next route waypoint, or the goal) lies inside one of their minimum turning circles,
or the route turns at the next waypoint more tightly than the model's radius allows, it
plans a ``smoothing`` segment with the optimizer (same cost as escapes, purpose
"smoothing"), validated with FCL. Checks are rate-limited per agent, and skipped while other
agents are within the reach of the field's agent term (their passing shapes the way, and a
segment planned through them would be out of date within a second).
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.core import Mode, PlannedSegment, PlanningContext
from swarmplan.flight.apf import current_reach, stopping_reach
from swarmplan.geometry.polyline import fillet_corner, fillet_path
from swarmplan.planner.escape import model_turn_radius, static_clearance

__all__ = ["CurvatureSmoother", "fillet_corner", "fillet_path"]


def _norm(x: np.ndarray) -> float:
    """``float(np.linalg.norm(x))`` of a float vector, the same bits (numpy's own path for a
    vector: the square root of ``x.dot(x)``) without its dispatch."""
    x = x.ravel(order="K")
    return math.sqrt(x.dot(x))


class CurvatureSmoother:
    """Plans smoothing segments in ``on_step`` (see the module docstring)."""

    def __init__(self, escape_planner, check_interval: float = 1.0, cooldown: float = 6.0):
        self.ep = escape_planner
        self.check_interval = check_interval
        self.cooldown = cooldown
        self.next_check = np.zeros(0)  # per agent: the time of its next check
        self._reach: float | None = None  # the field's agent term's reach (``agents_near``)

    def reset(self) -> None:
        """Every agent is checked at its first step."""
        self.next_check = np.zeros(0)

    def _target(self, sim: PlanningContext, i: int) -> tuple[np.ndarray, np.ndarray | None, int]:
        """Next attraction point, the point after it (route corner) and its route index (-1: goal)."""
        s = sim.state
        route = s.route[i]
        if route is not None and s.route_index[i] < len(route):
            k = int(s.route_index[i])
            after = route[k + 1] if k + 1 < len(route) else s.goal[i]
            return route[k], after, k
        return s.goal[i], None, -1

    def check(self, sim: PlanningContext, i: int) -> tuple[np.ndarray, int] | None:
        """(end point of a smoothing segment, route index it passes) when agent ``i`` must turn
        more tightly than its model allows, else None."""
        s = sim.state
        p, v = s.position[i], s.velocity[i]
        speed = _norm(v)
        if speed < 0.5 * float(sim.params.speed_cruise[i]):
            return None
        R = model_turn_radius(sim, i)
        if not sim.params.fixed_wing[i]:
            # A multirotor turns at speed v on a radius of v^2/a, and slows down near its
            # target (``commanded_velocity``): its turning circles are those of its speed now.
            R = min(R, speed * speed / max(float(sim.params.max_accel[i]), 1e-9))
        target, after, k = self._target(sim, i)
        to_t = target - p
        dist = _norm(to_t)
        if dist <= sim.world.goal_tolerance:
            return None
        h = v / speed
        # Target inside a minimum turning circle (in the plane of heading and target): unreachable
        # by turning at the limit, the APF would circle or overshoot.
        lateral = to_t - np.dot(to_t, h) * h
        nl = _norm(lateral)
        # A fixed wing's own goal is captured by its final approach (``swarmplan.flight.capture``),
        # the way onto it from the route's last waypoint too.
        goal = s.goal[i]
        captured = bool(sim.params.fixed_wing[i]) and (
            bool((target == goal).all()) or (after is not None and bool((after == goal).all()))
        )
        if captured:
            return None
        if nl > 1e-6:
            center = p + R * lateral / nl
            if _norm(target - center) < R * 0.98:
                return (target.copy(), -1) if k < 0 else (target.copy(), k)
        # Route corner at the next waypoint tighter than the turn radius allows.
        if after is not None and dist < 2.0 * R:
            d1 = to_t / dist
            d2 = after - target
            l2 = _norm(d2)
            if l2 > 1e-6:
                theta = math.acos(float(np.clip(np.dot(d1, d2 / l2), -1, 1)))
                tangent = R * math.tan(min(theta, 3.0) / 2)
                if theta > math.radians(30) and tangent > min(dist, l2) / 2:
                    end = target + d2 / l2 * min(l2, max(tangent, R))
                    return end, k
        return None

    @staticmethod
    def _fast(sim: PlanningContext, rows: np.ndarray) -> list[int]:
        """The agents of ``rows`` flying at least half their cruise speed, by ``check``'s own
        test (``np.linalg.norm`` of each velocity). The speeds of all rows at once decide every
        row but those within rounding of the threshold, which are measured again one by one."""
        s = sim.state
        v = s.velocity[rows]
        half = 0.5 * sim.params.speed_cruise[rows]
        speed = np.sqrt((v * v).sum(axis=1))
        unsure = np.abs(speed - half) <= 1e-9 * (np.abs(half) + 1.0)
        keep = ~(speed < half)
        for j in np.flatnonzero(unsure).tolist():
            i = int(rows[j])
            keep[j] = not np.linalg.norm(s.velocity[i]) < 0.5 * float(sim.params.speed_cruise[i])
        return rows[keep].tolist()

    def _crowded(self, sim: PlanningContext, rows: np.ndarray) -> list[bool]:
        """Per agent of ``rows``: ``EscapePlanner.agents_near(sim, i).any()`` (the same
        distances, all rows at once)."""
        s = sim.state
        if self._reach is None:
            rho0 = float(sim.world.planner_config.apf.influence)
            self._reach = current_reach(sim.params, stopping_reach(sim.params, sim.world.dt), rho0)
        # np.linalg.norm(diff, axis=2) is sqrt((x² + y²) + z²) summed in this order: the same
        # bits per coordinate plane, without the (rows, n, 3) array and its reduction over 3.
        p, q = s.position.T, s.position[rows].T
        x, y, z = (p[c][None, :] - q[c][:, None] for c in range(3))
        near = (np.sqrt(x * x + y * y + z * z) < self._reach) & s.active
        near[np.arange(len(rows)), rows] = False
        return near.any(axis=1).tolist()

    def on_step(self, sim: PlanningContext) -> dict[int, PlannedSegment]:

        s = sim.state
        out = {}
        n = len(s.mode)
        if len(self.next_check) != n:
            self.next_check = np.zeros(n)
        ready = ~(s.t < self.next_check)
        if not ready.any():  # most steps: no agent's check is due
            return out
        apf = np.fromiter(map(Mode.APF.__eq__, s.mode.tolist()), dtype=bool, count=n)
        due = np.flatnonzero(s.active & apf & ready)
        if not len(due):
            return out
        self.next_check[due] = s.t + self.check_interval
        # Too slow to need a turn wider than it can fly (``check``'s first test).
        fast = self._fast(sim, due)
        if not fast:
            return out
        # Among other agents the way is theirs to shape: no segment to smooth.
        crowded = self._crowded(sim, np.array(fast))
        for i, busy in zip(fast, crowded, strict=True):
            if busy:
                continue
            found = self.check(sim, i)
            if found is None:
                continue
            end, k = found
            self.next_check[i] = s.t + self.cooldown
            L = float(np.linalg.norm(end - s.position[i]))
            poly, _, _ = self.ep.optimize_segment(sim, i, end, "smoothing", width=max(L, 5.0), n_free=3)
            r = float(sim.params.radius[i])
            c0 = float(static_clearance(sim, s.position[i], r)[0])
            if self.ep.segment_hit(sim, i, poly, c0) is not None:
                continue
            poly = self.ep.fillet(sim, i, poly)
            route_index = None
            if k >= 0 and s.route[i] is not None and not np.allclose(end, s.route[i][k]):
                route_index = k + 1  # the segment rounds this corner: the route goes on after it
            out[i] = PlannedSegment(poly[1:], mode=Mode.SMOOTHING, route_index=route_index)
        return out
