"""Arrived multirotors keep themselves safe: an agent hovering at its goal gets out of the way
of a moving obstacle (or of another agent) whose predicted path passes through it, and flies
back to its goal once the threat has passed.

The threat test, per guarding agent ``i`` (a multirotor that has arrived) and per mover or
flying agent ``j``: ``j`` goes on at its current velocity, ``i`` is held where it is; the
closest approach of ``j`` within the horizon ``H_i``, to ``i`` or to ``i``'s goal, is closer than
``need = R_j + r_i + GUARD_MARGIN`` (a mover: its bounding radius; an agent: its radius, and
``AGENT_MARGIN`` instead of ``GUARD_MARGIN``). ``H_i`` is the time ``i`` needs to move sideways
by the largest such ``need`` from rest at ``max_accel`` and ``speed.max``, times
``HORIZON_FACTOR``, plus three steps of reaction.

The evasion command moves the agent across the threat's path, away from its point of closest
approach (head-on: to the threat's right, or to the side away from the nearest surface), until
the predicted miss is ``need + GUARD_MARGIN``, at a speed it can stop from before it gets there;
clear of every threat where it is, it hovers there until its goal is clear as well. The braking
margin and the safety filter check the evasion step as every other step (static obstacles,
bounds, other agents). While away the agent flies in mode ``apf`` (a log's audit covers it as
any flying agent) and cannot re-arrive; once no threat is left it flies the potential field
back to its goal and re-enters mode ``arrived`` with an ``evade_end`` event (its
``arrival_time`` stays its first arrival).

Fixed wings cannot hover: at their goal their flight ends (they are recorded at rest there, the
model's convention for a fixed wing that reached its goal) and they do not evade; a contact
with one there is a collision as for any agent.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.core import Event, Mode, SwarmState
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.vec3 import dot3, norm3
from swarmplan.sim.metrics import NOTHING, Tally
from swarmplan.sim.safety import AGENT_MARGIN

GUARD_MARGIN = 0.5
"""Metres an arrived agent keeps between its body and a mover's bounding sphere."""

HORIZON_FACTOR = 1.5
"""The threat horizon over the time a sideways move by the needed distance takes."""

_EPS = 1e-9


def _approach(
    c: np.ndarray, u: np.ndarray, points: np.ndarray, horizon: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest approach of threats at ``c`` (T, 3) moving at ``u`` (T, 3) to fixed ``points``
    (R, 3) within ``horizon`` (R,): its time (R, T), the threat's offset from the point then
    (R, T, 3) and that offset's length (R, T)."""
    d = c[None, :, :] - points[:, None, :]
    w = np.broadcast_to(u[None, :, :], d.shape)
    t_star = np.clip(-dot3(d, w) / np.maximum(dot3(w, w), _EPS), 0.0, horizon[:, None])
    closest = d + t_star[..., None] * w
    return t_star, closest, norm3(closest)


def sideways_time(distance: np.ndarray, amax: np.ndarray, vmax: np.ndarray) -> np.ndarray:
    """Seconds to move ``distance`` from rest to rest at ``amax`` with top speed ``vmax``."""
    d = np.maximum(distance, 0.0)
    a = np.maximum(amax, _EPS)
    v = np.maximum(vmax, _EPS)
    return np.where(d <= v * v / a, 2.0 * np.sqrt(d / a), d / v + v / a)


class GoalGuard:
    """Which agents guard their goal (arrived multirotors, for the rest of the run) and which of
    them are out of a threat's way this step (reset with :meth:`reset`)."""

    def __init__(self, params: AgentParams, dt: float):
        self.params = params
        self.dt = dt
        n = len(params.ids)
        self.guarding = np.zeros(n, dtype=bool)
        self.evading = np.zeros(n, dtype=bool)
        self._command = np.zeros((n, 3))

    def reset(self) -> None:
        self.guarding[:] = False
        self.evading[:] = False
        self._command[:] = 0.0

    def update(
        self,
        s: SwarmState,
        threats: tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]],
        surface: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    ) -> Tally:
        """Threat test for every guarding agent at the step's start. ``threats`` are the movers'
        centres (M, 3), velocities (M, 3), bounding radii (M,) and ids; ``surface(rows)`` the
        clearance of agents ``rows`` to their nearest static surface and its outward normal. Arrived agents
        under threat take off (mode ``apf``, an ``evade_start`` event and an ``evasions`` count);
        agents already away stay evading while threatened. Returns the take-offs."""
        self.evading[:] = False
        rows = np.flatnonzero(self.guarding & ((s.mode == Mode.ARRIVED) | (s.mode == Mode.APF)))
        if not len(rows):
            return NOTHING
        p = self.params
        centres, velocities, radii, ids = threats
        # Flying agents are threats too (an agent on its way, or another one evading).
        flying = np.flatnonzero(s.active)
        c = np.vstack([centres, s.position[flying]])
        u = np.vstack([velocities, s.velocity[flying]])
        margin = np.concatenate([radii + GUARD_MARGIN, p.radius[flying] + AGENT_MARGIN])
        who = np.concatenate([np.full(len(centres), -1), flying])
        names = tuple(ids) + tuple(p.ids[k] for k in flying.tolist())
        if not len(c):
            return NOTHING
        need = margin[None, :] + p.radius[rows, None]  # (R, T)
        amax, vmax = p.max_accel[rows], p.speed_max[rows]
        horizon = HORIZON_FACTOR * sideways_time(need.max(axis=1), amax, vmax) + 3.0 * self.dt
        others = who[None, :] != rows[:, None]
        # Each threat's own motion against the agent held where it is (its evasion is what it
        # controls), and against its goal: it stays out until the goal is clear again.
        t_star, closest, miss = _approach(c, u, s.position[rows], horizon)
        t_goal, _, miss_goal = _approach(c, u, s.goal[rows], horizon)
        threat = (miss < need) & others
        at_goal = (miss_goal < need) & others
        self._command[rows] = 0.0
        events, counts = [], []
        under = np.flatnonzero((threat | at_goal).any(axis=1))
        if not len(under):
            return NOTHING
        clearance, normal = surface(rows[under])
        for n, k in enumerate(under.tolist()):
            i = int(rows[k])
            self.evading[i] = True
            side = (float(clearance[n]), normal[n])
            # Clear of every threat where it is: it hovers there until its goal is clear.
            self._command[i] = self._evasion(i, threat[k], closest[k], u, need[k], side)
            if s.mode[i] == Mode.ARRIVED:
                j = int(np.argmin(np.where(threat[k] | at_goal[k], np.minimum(t_star[k], t_goal[k]), np.inf)))
                s.mode[i] = Mode.APF
                miss_j, in_j = (
                    round(float(min(miss[k, j], miss_goal[k, j])), 6),
                    round(float(t_star[k, j]), 6),
                )
                detail = {"threat": names[j], "miss": miss_j, "in": in_j}
                events.append(Event(s.t, p.ids[i], "evade_start", detail))
                counts.append(("evasions", i))
        return Tally(events=tuple(events), counts=tuple(counts)) if events else NOTHING

    def _evasion(
        self,
        i: int,
        threat: np.ndarray,
        closest: np.ndarray,
        w: np.ndarray,
        need: np.ndarray,
        surface: tuple[float, np.ndarray],
    ) -> np.ndarray:
        """Agent ``i``'s evasion velocity from its threats (rows of ``threat``): the sum of the
        sideways moves each needs, at a speed the agent can stop from within that move;
        ``surface`` is its clearance to the nearest static surface and that surface's normal."""
        p = self.params
        clearance, normal = surface
        move = np.zeros(3)
        for j in np.flatnonzero(threat).tolist():
            wj = w[j]
            wn = float(np.linalg.norm(wj))
            away = -closest[j]  # from the threat's closest approach to the agent
            if wn > _EPS:
                away = away - (away @ wj) / (wn * wn) * wj
            gap = float(np.linalg.norm(away))
            if gap > 1e-3:
                e = away / gap
            else:  # head-on: to the threat's right, or away from the nearest surface
                e = np.cross(wj, [0.0, 0.0, 1.0]) if wn > _EPS else np.array([1.0, 0.0, 0.0])
                if np.linalg.norm(e) < _EPS:
                    e = np.array([1.0, 0.0, 0.0])
                e = e / np.linalg.norm(e)
                if np.isfinite(clearance) and e @ normal < 0.0:
                    e = -e
            move += e * max(need[j] + GUARD_MARGIN - gap, 0.0)
        if np.isfinite(clearance) and move @ normal < 0.0 and clearance < np.linalg.norm(move) + p.radius[i]:
            move -= (move @ normal) * normal  # slide along the nearest surface, never into it
        length = float(np.linalg.norm(move))
        if length < _EPS:
            return np.zeros(3)
        speed = min(float(p.speed_max[i]), float(np.sqrt(2.0 * 0.8 * p.max_accel[i] * length)))
        return move / length * speed

    def commands(self, idx: np.ndarray, v_cmd: np.ndarray) -> np.ndarray:
        """``v_cmd`` (rows of ``idx``) with the evading agents' rows replaced by their evasion."""
        rows = self.evading[idx]
        if not rows.any():
            return v_cmd
        out = v_cmd.copy()
        out[rows] = self._command[idx[rows]]
        return out

    def stop_speeds(self, stop_speed: np.ndarray) -> np.ndarray:
        """The arrival speeds with evading agents excluded (they cannot arrive while threatened)."""
        if not self.evading.any():
            return stop_speed
        return np.where(self.evading, -1.0, stop_speed)

    def arrived(self, tally: Tally, s: SwarmState) -> Tally:
        """The step's arrivals: first arrivals start guarding (multirotors); a guarding agent back
        at its goal gives an ``evade_end`` instead of a second ``arrived`` (and keeps its first
        arrival time)."""
        if not tally.arrivals:
            return tally
        back = {i for i, _t in tally.arrivals if self.guarding[i]}
        for i, _t in tally.arrivals:
            if not self.params.fixed_wing[i]:
                self.guarding[i] = True
        if not back:
            return tally
        names = {self.params.ids[i] for i in back}
        events = tuple(
            Event(e.t, e.agent, "evade_end", e.detail) if e.kind == "arrived" and e.agent in names else e
            for e in tally.events
        )
        arrivals = tuple((i, t) for i, t in tally.arrivals if i not in back)
        return Tally(events, tally.counts, arrivals, tally.contacts)
