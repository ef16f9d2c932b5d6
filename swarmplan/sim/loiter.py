"""Arrived fixed wings keep flying: a fixed wing cannot hold still, so once at its goal it
loiters on a level circle through where it arrived, and stays an aircraft like any other (the
turn-ahead guard, the potential field's repulsion from moving obstacles and other agents, the
safety filter and the contact checks all go on for it).

The circle: through the point where the aircraft arrived (within the goal tolerance of its
goal, which every lap passes again), tangent to its heading there, at that altitude, so it
flies straight on into its loiter with no entry to fly (a circle centred on the goal could not
be entered from its centre without flying out past it: a turn at R_min from the centre reaches
2 R_min from it); of the smallest radius of ``LOITER_FACTORS`` x ``min_turn_radius``
(``swarmplan.planner.hold``) whose points (every 10 degrees) keep the aircraft's ``clearance``
from every static obstacle, the terrain and the bounds, on the side it was turning to when it
arrived first (left when flying straight), else on the other; when none does, the one that keeps
the most. Its field pulls it at a point ``LEAD`` radians ahead of it on the circle (which also
stands for its goal in the field's goal-distance factor), so it flies round it.

A goal the aircraft cannot fly through and loiter after (a goal in a corner, or near a wall it
would pass heading into) is approached on its loiter circle: between one and ``CAPTURE_RANGE``
turn radii of its goal (horizontally), a fixed wing flying at it checks the circles through the
goal tangent to its bearing to it (the heading it would arrive with), with the room its roll-in
takes (half of its flight) as a margin, and the height it has to win or lose. When none of them
is clear, or the height is more than its climb limit allows over the way in less a turn radius
(it spirals on the circle instead), it takes, of the circles
through the goal (every 10 degrees of heading there, either side, the radii of
``LOITER_FACTORS``), the clear one of the smallest radius that is the shortest to fly to (a
Dubins way: the turn at its minimum radius onto a tangent of the circle in the circle's
direction of flight, the tangent, the arc to the goal; from inside it, the turn onto its
course and the arc when shorter), or
the clearest when none is clear; it flies onto it along the tangent (its field pulls at the
tangent point), then onto and round it along a vector field (``_on_circle``) and through its
goal, and loiters on that same circle once it arrives. It turns into its goal only with no more
height left to win or lose than its climb limit wins over the arc to it: else it goes round
once more, spiralling to the goal's height (a goal passed above or below is not reached).
Within a turn radius of its goal its bearing no longer tells the heading it will arrive with:
it keeps what it decided before.

Its mode stays ``arrived`` and its arrival time the first arrival; as every recorded step, its
loiter counts in its path length, clearances and curvature (``/summary`` and the replay alike);
a contact while it loiters is a collision, for the simulation as for the replay's audit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.core import SwarmState
from swarmplan.flight.capture import CAPTURE_RANGE, roll_in_distance
from swarmplan.flight.kinematics import AgentParams
from swarmplan.planner.hold import LOITER_FACTORS, loiter_circle
from swarmplan.sim.modes import ARRIVED, mode_in

if TYPE_CHECKING:
    from swarmplan.sim.obstacles import Obstacles

LEAD = math.radians(30.0)
"""How far ahead on the circle (rad) a loitering fixed wing's field pulls it."""

CONVERGE = 2.0
"""The gain of the course onto an approach circle: off it by a fraction x of its radius, the
course turns atan(2 x) from the circle's tangent towards it (45 degrees at a quarter radius)."""


class Loiter:
    """The circles of the arrived fixed wings (reset with :meth:`reset`)."""

    def __init__(self, params: AgentParams):
        self.params = params
        n = len(params.ids)
        self.on = np.zeros(n, dtype=bool)  # loitering now
        self.center = np.zeros((n, 3))
        self.radius = np.zeros(n)
        self.side = np.ones(n)
        self.fixed_wings = bool(params.fixed_wing.any())  # whether any agent can loiter
        self.approaching = np.zeros(n, dtype=bool)  # on its way round its circle to its goal

    def reset(self) -> None:
        self.on[:] = False
        self.approaching[:] = False

    def rows(self, s: SwarmState) -> np.ndarray:
        """Which agents loiter (arrived fixed wings that have not collided since)."""
        if not self.fixed_wings or not self.on.any():  # (only fixed wings loiter)
            return self.on
        self.on &= mode_in(s.mode, ARRIVED)
        return self.on

    def flying(self, s: SwarmState, active: np.ndarray) -> np.ndarray:
        """The agents flown this step: the ``active`` ones and those that loiter (flown as the rest)."""
        if not self.fixed_wings:
            return active
        loiter = self.rows(s)
        return active | loiter if loiter.any() else active

    def fly_on(
        self,
        arrivals: tuple[tuple[int, float], ...],
        position: np.ndarray,
        velocity: np.ndarray,
        flown: np.ndarray | None,
        turn: np.ndarray,
        obstacles: Obstacles,
    ) -> None:
        """The fixed wings among ``arrivals`` (agent, time) cannot stop: each flies on at its
        step's velocity (its row of ``flown`` back into ``velocity``, which the arrival zeroed)
        round a circle through where it arrived (its row of ``position``), from its turn state
        (a row of ``turn``; the circle it approached its goal on, when it did). ``flown`` None:
        no fixed wings."""
        for i, _t in arrivals if flown is not None else ():
            if self.params.fixed_wing[i]:
                velocity[i] = flown[i]
                if self.approaching[i]:
                    self.approaching[i], self.on[i] = False, True
                else:
                    self.start(i, position[i], flown[i], turn[i], clear_of_statics(obstacles, i))

    def start(
        self,
        i: int,
        position: np.ndarray,
        velocity: np.ndarray,
        turn: np.ndarray,
        clearance: Callable[[np.ndarray], np.ndarray],
    ) -> None:
        """Agent ``i`` arrived at ``position`` flying ``velocity`` with turn state ``turn`` (2,):
        its circle through ``position``, tangent to ``velocity``, the first of the radii and
        sides whose points keep ``clearance(points) >= 0`` (else the clearest one)."""
        r_min = float(self.params.min_turn_radius[i])
        first = 1.0 if turn[0] >= 0.0 else -1.0
        best, best_clear = None, -np.inf
        for factor in LOITER_FACTORS:
            for side in (first, -first):
                r = factor * r_min
                worst = float(clearance(loiter_circle(position, velocity, r, side)).min())
                if worst > best_clear:
                    best, best_clear = (r, side), worst
                if worst >= 0.0:
                    break
            if best_clear >= 0.0:
                break
        r, side = best
        h = np.array([velocity[0], velocity[1]], float)
        n = float(np.hypot(*h))
        h = h / n if n > 1e-9 else np.array([1.0, 0.0])
        self.on[i] = True
        self.center[i] = (position[0] - side * r * h[1], position[1] + side * r * h[0], position[2])
        self.radius[i] = r
        self.side[i] = side

    def approach(
        self,
        idx: np.ndarray,
        pos: np.ndarray,
        vel: np.ndarray,
        goal: np.ndarray,
        at_goal: np.ndarray,
        target: np.ndarray,
        obstacles: Obstacles,
    ) -> np.ndarray:
        """``target`` (rows of flying agents ``idx`` at ``pos`` moving at ``vel``) with, for the
        fixed wings flying at their ``goal`` (``at_goal``, rows) within ``CAPTURE_RANGE`` turn
        radii of it that must approach it on a circle (module docstring), the point on its
        circle their field pulls at; the others' unchanged."""
        k_all = idx
        r_min = self.params.min_turn_radius[k_all]
        e = goal[:, :2] - pos[:, :2]
        away = np.hypot(e[:, 0], e[:, 1])
        near = away < CAPTURE_RANGE * r_min
        fly = self.params.fixed_wing[k_all] & at_goal & near & ~self.on[k_all]
        self.approaching[k_all[~fly]] = False
        if not fly.any():
            return target
        out = target
        for row in np.flatnonzero(fly):
            i = int(k_all[row])
            # Within a turn radius its bearing is no longer the heading it arrives with: it flies
            # on as it decided before.
            if not self.approaching[i] and (
                away[row] < r_min[row] or not self._choose(i, pos[row], vel[row], goal[row], obstacles)
            ):
                continue
            if out is target:
                out = np.array(target, dtype=float)
            out[row] = self._on_circle(i, pos[row], vel[row], goal[row])
        return out

    def _choose(self, i: int, p: np.ndarray, v: np.ndarray, g: np.ndarray, obstacles: Obstacles) -> bool:
        """Whether agent ``i`` at ``p`` flying ``v`` must approach its goal ``g`` on a circle (no
        clear loiter circle through ``g`` tangent to its bearing to it, or more height to win or
        lose than its climb limit allows on the way in after a turn); if so, its circle."""
        r_min = float(self.params.min_turn_radius[i])
        speed = np.array([max(float(np.hypot(v[0], v[1])), 1e-9)])
        margin = 0.5 * float(roll_in_distance(self.params, np.array([i]), speed)[0])
        clearance = clear_of_statics(obstacles, i)
        bearing = np.array([g[0] - p[0], g[1] - p[1], 0.0])
        run = float(np.hypot(bearing[0], bearing[1])) - r_min
        steep = abs(g[2] - p[2]) > max(run, 0.0) * math.tan(float(self.params.max_climb[i]))
        direct = [loiter_circle(g, bearing, f * r_min, side) for f in LOITER_FACTORS for side in (1.0, -1.0)]
        worst = clearance(np.concatenate(direct)).reshape(len(direct), -1).min(axis=1)
        if not steep and (worst >= margin).any():
            return False
        angles = np.radians(np.arange(0.0, 360.0, 10.0))
        best, best_clear = None, -np.inf
        for f in LOITER_FACTORS:
            r = f * r_min
            cands = [(a, side) for a in angles for side in (1.0, -1.0)]
            pts = [loiter_circle(g, np.array([math.cos(a), math.sin(a), 0.0]), r, side) for a, side in cands]
            worst = clearance(np.concatenate(pts)).reshape(len(cands), -1).min(axis=1)
            clear = np.flatnonzero(worst >= margin)
            if len(clear):
                ways = [_way_length(p, v, g, cands[j][0], r, cands[j][1], r_min) for j in clear]
                a, side = cands[int(clear[int(np.argmin(ways))])]
                best = (a, side, r)
                break
            j = int(np.argmax(worst))
            if worst[j] > best_clear:
                best, best_clear = (cands[j][0], cands[j][1], r), float(worst[j])
        a, side, r = best
        self.approaching[i] = True
        self.center[i] = (g[0] - side * r * math.sin(a), g[1] + side * r * math.cos(a), g[2])
        self.radius[i], self.side[i] = r, side
        return True

    def _on_circle(self, i: int, p: np.ndarray, v: np.ndarray, g: np.ndarray) -> np.ndarray:
        """The point agent ``i`` at ``p`` flying ``v`` towards its goal ``g`` round its circle is
        pulled at: far out (over sqrt(2) radii from the centre), the tangent point of its way onto
        the circle; nearer, a point ``LEAD`` of arc away along the course of a vector field that
        turns onto the circle in its direction (the circle's tangent, turned towards the circle by
        atan(``CONVERGE`` x the distance off it over its radius)); the goal itself once it lies
        less than ``LEAD`` ahead, the aircraft near its circle and flying its way, with no more
        height to win or lose than its climb limit wins over the arc to it (else it goes round
        once more, spiralling to the goal's height)."""
        c, r, side = self.center[i], float(self.radius[i]), float(self.side[i])
        dx, dy = p[0] - c[0], p[1] - c[1]
        d = math.hypot(dx, dy)
        theta = math.atan2(dy, dx)
        if d > math.sqrt(2.0) * r:
            theta += side * math.acos(r / d)
            return np.array([c[0] + r * math.cos(theta), c[1] + r * math.sin(theta), g[2]])
        course = theta + side * 0.5 * math.pi
        to_goal = (side * (math.atan2(g[1] - c[1], g[0] - c[0]) - theta)) % (2.0 * math.pi)
        along = v[0] * math.cos(course) + v[1] * math.sin(course)
        # The height still to win or lose over the arc to the goal at the climb limit: else
        # round once more (the spiral), never into a goal it would pass above or below.
        level = abs(g[2] - p[2]) <= r * to_goal * math.tan(float(self.params.max_climb[i]))
        near = abs(d - r) < 0.25 * r and along > math.sqrt(0.5) * math.hypot(v[0], v[1])
        if to_goal <= LEAD and near and level:
            return np.array(g, dtype=float)
        course += side * math.atan(CONVERGE * (d - r) / r)
        ahead = r * LEAD
        return np.array([p[0] + ahead * math.cos(course), p[1] + ahead * math.sin(course), g[2]])

    def targets(self, rows: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """The points (len(rows), 3) ``LEAD`` ahead on their circles of loitering agents ``rows``
        at ``pos``."""
        c = self.center[rows]
        theta = np.arctan2(pos[:, 1] - c[:, 1], pos[:, 0] - c[:, 0]) + self.side[rows] * LEAD
        r = self.radius[rows]
        return np.column_stack([c[:, 0] + r * np.cos(theta), c[:, 1] + r * np.sin(theta), c[:, 2]])


def _way_length(
    p: np.ndarray, v: np.ndarray, g: np.ndarray, heading: float, r: float, side: float, r_min: float
) -> float:
    """The length of a fixed wing's way from ``p`` flying ``v`` to ``g`` on the circle of radius
    ``r`` through ``g`` with heading ``heading`` there, turning to ``side``: the shortest Dubins
    way onto the circle (a turn at ``r_min`` to either side, the straight tangent from that turn
    onto the circle in its own direction of flight) and the arc to ``g``. From inside the circle
    it may also ease out onto it along its field, in a turn wider than its tightest (no Dubins
    way: its tangents may need a full turn, or none exists): the turn onto the circle's course
    abreast of it and the arc from there, when that is shorter."""
    cx, cy = g[0] - side * r * math.sin(heading), g[1] + side * r * math.cos(heading)
    psi = math.atan2(v[1], v[0])
    best = math.inf
    for turn in (1.0, -1.0):
        ax, ay = p[0] - turn * r_min * math.sin(psi), p[1] + turn * r_min * math.cos(psi)
        dx, dy = cx - ax, cy - ay
        k = side * r - turn * r_min  # the tangent's offset between the two circles
        dd = dx * dx + dy * dy
        if dd < k * k:
            continue
        straight = math.sqrt(dd - k * k)
        u = math.atan2(dy, dx) - math.atan2(k, straight)  # the tangent's heading
        leave = _swept(psi, u, turn)  # the turn from the heading now onto the tangent
        # Where the tangent meets the circle (its radius at angle u - side 90 degrees), on to g.
        meet = u - side * 0.5 * math.pi
        arc = _swept(meet, math.atan2(g[1] - cy, g[0] - cx), side)
        best = min(best, r_min * leave + straight + r * arc)
    if math.hypot(p[0] - cx, p[1] - cy) < r:  # inside: easing out onto it along its field
        theta = math.atan2(p[1] - cy, p[0] - cx)
        course = theta + side * 0.5 * math.pi  # the circle's own course abreast of the aircraft
        onto = abs(math.remainder(course - psi, 2.0 * math.pi))
        best = min(best, r_min * onto + r * _swept(theta, math.atan2(g[1] - cy, g[0] - cx), side))
    return best


def _swept(a: float, b: float, side: float) -> float:
    """The angle (rad, in [0, 2 pi)) swept from angle ``a`` to angle ``b`` turning to ``side``
    (1: anticlockwise, -1: clockwise)."""
    return (side * (b - a)) % (2.0 * math.pi)


def clear_of_statics(obstacles: Obstacles, i: int) -> Callable[[np.ndarray], np.ndarray]:
    """``clearance(points) -> (P,)`` of agent ``i``'s body at ``points``: from the terrain and the
    bounds beyond its radius, from the static obstacles beyond its ``clearance``."""
    w, p, distances = obstacles.world, obstacles.params, obstacles.distances
    static = np.flatnonzero(~obstacles.moving_mask)

    def clearance(points: np.ndarray) -> np.ndarray:
        r = p.radius[i]
        c = points[:, 2] - w.terrain_height(points[:, :2]) - r
        c = np.minimum(c, np.minimum(points - w.bounds_min, w.bounds_max - points).min(axis=1) - r)
        if len(static):
            c = np.minimum(c, distances.distance(points, None, static).min(axis=1) - p.clearance[i])
        return c

    return clearance
