"""Arrived fixed wings keep flying: a fixed wing cannot hold still, so once at its goal it
loiters on a level circle about it, and stays an aircraft like any other (the turn-ahead guard,
the potential field's repulsion from moving obstacles and other agents, the safety filter and
the contact checks all go on for it).

The circle: centred on the goal, at the goal's altitude, of the smallest radius of
``LOITER_FACTORS`` x ``min_turn_radius`` (``swarmplan.planner.hold``) whose points (every
10 degrees) keep the aircraft's ``clearance`` from every static obstacle, the terrain and the
bounds; when none does, the one that keeps the most. It circles the way it was turning when it
arrived (left when flying straight). Its field pulls it at a point ``LEAD`` radians ahead of it
on the circle (which also stands for its goal in the field's goal-distance factor), so it flies
out onto the circle and round it.

Its mode stays ``arrived`` and its arrival time the first arrival; as every recorded step, its
loiter counts in its path length, clearances and curvature (``/summary`` and the replay alike);
a contact while it loiters is a collision, for the simulation as for the replay's audit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.core import Mode, SwarmState
from swarmplan.flight.kinematics import AgentParams
from swarmplan.planner.hold import LOITER_FACTORS

if TYPE_CHECKING:
    from swarmplan.sim.obstacles import Obstacles

LEAD = math.radians(30.0)
"""How far ahead on the circle (rad) a loitering fixed wing's field pulls it."""

_POINTS = 36  # points checked on a candidate circle (every 10 degrees)


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

    def reset(self) -> None:
        self.on[:] = False

    def rows(self, s: SwarmState) -> np.ndarray:
        """Which agents loiter (arrived fixed wings that have not collided since)."""
        if not self.fixed_wings or not self.on.any():  # (only fixed wings loiter)
            return self.on
        self.on &= s.mode == Mode.ARRIVED
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
        s: SwarmState,
        velocity: np.ndarray,
        flown: np.ndarray | None,
        turn: np.ndarray,
        obstacles: Obstacles,
    ) -> None:
        """The fixed wings among ``arrivals`` (agent, time) cannot stop: each flies on at its
        step's velocity (its row of ``flown`` back into ``velocity``, which the arrival zeroed)
        round its goal, from its turn state (a row of ``turn``). ``flown`` None: no fixed wings."""
        for i, _t in arrivals if flown is not None else ():
            if self.params.fixed_wing[i]:
                velocity[i] = flown[i]
                self.start(i, s.goal[i], turn[i], clear_of_statics(obstacles, i))

    def start(
        self, i: int, goal: np.ndarray, turn: np.ndarray, clearance: Callable[[np.ndarray], np.ndarray]
    ) -> None:
        """Agent ``i`` arrived at ``goal`` with turn state ``turn`` (2,): its circle, the first
        of the radii whose points keep ``clearance(points) >= 0`` (else the clearest one)."""
        r_min = float(self.params.min_turn_radius[i])
        ang = np.arange(_POINTS) * (2.0 * math.pi / _POINTS)
        best, best_clear = None, -np.inf
        for factor in LOITER_FACTORS:
            r = factor * r_min
            pts = goal + np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(_POINTS)])
            worst = float(clearance(pts).min())
            if worst >= 0.0:
                best = r
                break
            if worst > best_clear:
                best, best_clear = r, worst
        self.on[i] = True
        self.center[i] = goal
        self.radius[i] = best
        self.side[i] = 1.0 if turn[0] >= 0.0 else -1.0

    def targets(self, rows: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """The points (len(rows), 3) ``LEAD`` ahead on their circles of loitering agents ``rows``
        at ``pos``."""
        c = self.center[rows]
        theta = np.arctan2(pos[:, 1] - c[:, 1], pos[:, 0] - c[:, 0]) + self.side[rows] * LEAD
        r = self.radius[rows]
        return np.column_stack([c[:, 0] + r * np.cos(theta), c[:, 1] + r * np.sin(theta), c[:, 2]])


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
