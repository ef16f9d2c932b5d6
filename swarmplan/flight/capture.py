"""A fixed wing's capture of its goal: the final approach of an aircraft that cannot stop.

A fixed wing turns on circles of its minimum radius ``R`` at best, one either side of its
heading. The shortest way to a goal point (a Dubins path with a free final heading) is a turn
towards it on the circle of its side, then the straight line along the tangent through it: the
field's pull at the goal, the turn limited by the model, flies exactly that, as long as the goal
lies outside that circle. A goal inside it cannot be turned onto: pulled at it the aircraft
circles it, or passes it and circles again. So a fixed wing whose goal lies inside its turn
circle on the goal's side extends: it flies on straight ahead (its point of attraction a turn
radius ahead of it, at the goal's altitude) until the goal lies outside the circle it will
actually fly, a final straight off it (``FINAL``), then turns in and flies the straight into
the goal's tolerance.

The circle it will actually fly starts after it has rolled into the turn: the roll-in (from
wings level to the bank of a minimum-radius turn, ``atan(V^2 / (g R))``, at its roll rate)
takes ``V t_roll`` of flight, and moves the circle's centre about half of that forward. The
extension ends once the goal is outside that circle (so it starts the turn in time to come
round onto the goal) and starts again only when the goal falls inside the circle of its
heading now (a goal on the circle it already turns on is being captured).

Only the fixed wings flying at their goal itself are concerned (a segment's or route's
waypoint, a loiter point, a guide's point keep their own way); multirotors stop at their goals.

Flying away from its goal to come round onto it is no local minimum: within ``CAPTURE_RANGE``
turn radii of its goal (horizontally) a fixed wing flying at it is not held stuck for as long as
a capture takes (``capture_time``: out of that range and back, and a full circle, at its
minimum speed), after which its progress is watched again.
"""

from __future__ import annotations

import numpy as np

from swarmplan.flight.kinematics import AgentParams
from swarmplan.world.airframe import GRAVITY

_EPS = 1e-9

INSIDE = 0.98
"""A goal within this fraction of the turn radius from the centre of the circle of the current
heading lies inside it (the goal exactly on a circle flown at the limit is being captured)."""


CAPTURE_RANGE = 3.0
"""Turn radii (horizontally) from its goal within which a fixed wing is capturing it: beyond two,
the goal cannot lie inside either turn circle; the third is the room of the final straight."""


def capture_time(params: AgentParams) -> np.ndarray:
    """Per agent, s: the longest a capture takes, out of ``CAPTURE_RANGE`` and back and a full
    circle at the minimum turn radius, flown at the minimum speed."""
    r = params.min_turn_radius
    return (2.0 * CAPTURE_RANGE + 2.0 * np.pi) * r / np.maximum(params.speed_min, _EPS)


def roll_in_distance(params: AgentParams, k: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The flight (m) of fixed wings ``k`` at ``speed`` rolling from wings level into the bank of
    a minimum-radius turn, ``atan(V^2 / (g R))``, at their roll rate (0 at an unlimited one)."""
    bank = np.arctan(speed * speed / (GRAVITY * params.min_turn_radius[k]))
    return speed * bank / params.roll_rate[k]


FINAL = float(np.sqrt(2.0))
"""An extending fixed wing turns in once its goal is this many turn radii from the centre of the
circle it will fly: the tangent from the circle to the goal, its final straight, is then a turn
radius long (room to roll out and to take up what pushed it off its line), and the goal stays
well outside the circle of its heading while it comes round (no return to extending)."""


class GoalCapture:
    """Per fixed wing, whether it extends to capture its goal (reset with :meth:`reset`)."""

    def __init__(self, params: AgentParams):
        self.params = params
        n = len(params.ids)
        self.extending = np.zeros(n, dtype=bool)
        self.since = np.full(n, np.nan)  # when each one came within capture range of its goal
        self.hold = np.zeros(n, dtype=bool)  # capturing now: its progress window starts again
        self.time = capture_time(params)
        self.any = bool(params.fixed_wing.any())

    def reset(self) -> None:
        self.extending[:] = False
        self.since[:] = np.nan
        self.hold[:] = False

    def targets(
        self,
        t: float,
        idx: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        goal: np.ndarray,
        target: np.ndarray,
    ) -> np.ndarray:
        """``target`` (rows of ``idx``, at time ``t``) with the point ahead of each fixed wing
        flying at its goal that must extend before it can turn onto it (module docstring); the
        others' unchanged. Sets ``hold``: the agents capturing their goals now."""
        fw = self.params.fixed_wing[idx]
        same = target == goal
        rows = np.flatnonzero(fw & same[:, 0] & same[:, 1] & same[:, 2])
        extending = self.extending
        self.hold[:] = False
        if not len(rows):
            self.since[:] = np.nan
            return target
        k = idx[rows]
        p, g = pos[rows], goal[rows]
        h = vel[rows, :2]
        speed = np.sqrt(h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1])
        h = h / np.maximum(speed, _EPS)[:, None]
        e = g[:, :2] - p[:, :2]
        near = np.sqrt(e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1]) < CAPTURE_RANGE * self.params.min_turn_radius[k]
        since = np.full(len(self.since), np.nan)
        since[k[near]] = np.where(np.isnan(self.since[k[near]]), t, self.since[k[near]])
        self.since = since
        self.hold[k[near]] = t - since[k[near]] < self.time[k[near]]
        cross = h[:, 0] * e[:, 1] - h[:, 1] * e[:, 0]
        side = np.where(cross < 0.0, -1.0, 1.0)
        r = self.params.min_turn_radius[k]
        normal = np.column_stack([-h[:, 1], h[:, 0]]) * side[:, None]
        center = p[:, :2] + r[:, None] * normal
        now = np.hypot(*(g[:, :2] - center).T)
        # The circle after the roll-in: its centre half the roll-in's flight ahead.
        roll_in = roll_in_distance(self.params, k, speed)
        later = np.hypot(*(g[:, :2] - center - 0.5 * roll_in[:, None] * h).T)
        level = speed > _EPS  # a (near) vertical velocity has no heading to extend
        # Extending until the goal is a final straight of a turn radius off the circle's tangent.
        ext = level & np.where(extending[k], later < FINAL * r, now < INSIDE * r)
        extending[k] = ext
        if not ext.any():
            return target
        out = np.array(target, dtype=float)
        j = rows[ext]
        ahead = p[ext, :2] + r[ext, None] * h[ext]
        out[j, :2] = ahead
        out[j, 2] = g[ext, 2]
        return out


def height_first(
    params: AgentParams,
    idx: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    at_goal: np.ndarray,
    target: np.ndarray,
) -> np.ndarray:
    """``target`` (rows of flying agents ``idx`` at ``pos``) with the height of each fixed wing
    flying at its ``goal`` (``at_goal``, rows: the goal itself, the point its capture extends to or
    the point of its approach circle) within ``CAPTURE_RANGE`` turn radii ``R`` of it
    (horizontally) set so the pull wins the goal's height before its last turn radius: its
    flight-path angle towards the target is the slope that wins the height ``dz`` still to win or
    lose over the way in less that turn radius, or the level-off profile ``sqrt(dz / R)`` when
    that is less (within the last turn radius, the profile), at most its climb limit. The profile
    levels off at half the turn's curvature (the other half, and more, stays for the heading:
    the model shares one budget between them), so an aircraft does not turn onto its goal still
    climbing or diving at its limit: it takes its last turn radius level and passes the goal at
    its height. A target so set is not the goal itself: the pull is the field's conic one all the
    way in (a fixed wing cannot stop; the goal's quadratic well, weaker the nearer it flies,
    would leave its last turn to whatever else pushes it). The others' targets unchanged."""
    fw = params.fixed_wing[idx] & at_goal
    if not fw.any():
        return target
    rows = np.flatnonzero(fw)
    k = idx[rows]
    r = params.min_turn_radius[k]
    e = goal[rows] - pos[rows]
    away = np.hypot(e[:, 0], e[:, 1])
    near = away < CAPTURE_RANGE * r
    if not near.any():
        return target
    rows, k, r, e, away = rows[near], k[near], r[near], e[near], away[near]
    dz = np.abs(e[:, 2])
    slope = np.arctan2(dz, np.maximum(away - r, 0.0))  # won over the way in before its last turn radius
    gamma = np.minimum(np.minimum(slope, np.sqrt(dz / r)), params.max_climb[k]) * np.sign(e[:, 2])
    t = target[rows] - pos[rows]
    run = np.maximum(np.hypot(t[:, 0], t[:, 1]), _EPS)
    out = np.array(target, dtype=float)
    out[rows, 2] = pos[rows, 2] + run * np.tan(gamma)
    return out
