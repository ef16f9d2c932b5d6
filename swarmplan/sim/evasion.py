"""Arrived multirotors keep themselves safe: an agent hovering at its goal gets out of the way
of a moving obstacle (or of another agent) whose predicted path passes through it, and flies
back to its goal once the threat has passed.

The threat test, per watching agent ``i`` (a multirotor that has arrived) and per mover or
flying agent ``j``: ``j`` goes on at its current velocity, ``i`` is held where it is; the
closest approach of ``j`` within the horizon ``H_i``, to ``i`` or to ``i``'s goal, is closer than
``need = R_j + r_i + m`` (a mover: its bounding radius, and ``m`` the world's :func:`evade_margin`;
an agent: its radius, and ``m`` twice its safety margin, ``kinematics.safety_margin``). ``H_i`` is the
time ``i`` needs to move sideways by the largest such ``need`` from rest at ``max_accel`` and
``speed.max``, times ``HORIZON_FACTOR``, plus three steps of reaction. A mover that is not a
sphere is then measured by its surface (:func:`surface_approach`): it threatens only where its
nearest surface point comes within ``r_i + m`` of the agent or its goal, so a tall pole or a
long slab passing beside an arrived agent leaves it at its goal, while one aimed at it is
dodged as before.

The evasion command moves the agent across the threat's path, away from its point of closest
approach (head-on: to the threat's right, or to the side away from the nearest surface), until
the predicted miss is ``need`` plus its own radius, at a speed it can stop from before it gets there;
clear of every threat where it is, it hovers there until its goal is clear as well. The braking
margin and the safety filter check the evasion step as every other step (static obstacles,
bounds, other agents). While away the agent flies in mode ``apf`` (a log's audit covers it as
any flying agent) and cannot re-arrive; once every threat clears it and its goal by
``CLEAR_BY`` more of its radii (the hysteresis that keeps a wavering prediction from sending it
out and back step after step) it flies the potential field back to its goal and re-enters mode
``arrived`` with an ``evade_end`` event (its ``arrival_time`` stays its first arrival). An
arrival freezes the agent from a speed one step can stop: that stop takes the step after it, so
an agent that has just arrived (or come back) is tested for threats from the step after that,
and its evasion starts from rest (no velocity change beyond ``max_accel`` between two steps).

Fixed wings cannot hover: at their goal they loiter (``swarmplan.sim.loiter``), flown as every
flying aircraft (the field, the turn-ahead guard, the safety filter); a contact with one there
is a collision as for any agent.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from swarmplan.core import Event, Mode, SwarmState
from swarmplan.flight.kinematics import AgentParams, safety_margin
from swarmplan.geometry.vec3 import dot3, norm3
from swarmplan.runtime.compiled import kernel_module, use_compiled_checks
from swarmplan.sim.metrics import NOTHING, Tally
from swarmplan.sim.modes import mode_in, mode_table


def evade_margin(params: AgentParams) -> float:
    """The room an arrived agent keeps between its body and a mover's bounding sphere: the
    largest multirotor's radius, one body of air (the gap the default separation keeps between
    two agents). It scales with the agents: 0.5 m for 0.5 m multirotors, 5 cm for 5 cm lab
    drones, for which a margin in metres would send them off their goals whenever anything
    moved in a small room. One value per world (a mover's need does not depend on which
    agents watch it)."""
    stops = ~np.asarray(params.fixed_wing, dtype=bool)
    return float(np.max(params.radius[stops], initial=0.0))


CLEAR_BY = 1.0
"""Radii of its own body by which a threat must clear an agent away from its goal (evading, or
on its way back) before it comes back: the hysteresis between ``evade_start`` and ``evade_end``."""

HORIZON_FACTOR = 1.5
"""The threat horizon over the time a sideways move by the needed distance takes."""

_EPS = 1e-9
_WATCHED = mode_table(Mode.ARRIVED, Mode.APF)  # the watching agents: at their goals or in the field
_AWAY = mode_table(Mode.APF)  # watching agents away from their goals


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


Pairs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""Threat pairs: keys ``k * T + j`` (sorted), times (P, 2) and misses (P, 2) of the closest
approach to the agent and to its goal, the threat's offset then from the agent (P, 3)."""


def threat_pairs_dense(
    c: np.ndarray,
    u: np.ndarray,
    margin: np.ndarray,
    who: np.ndarray,
    rows: np.ndarray,
    radius: np.ndarray,
    position: np.ndarray,
    goal: np.ndarray,
    horizon: np.ndarray,
) -> Pairs:
    """Every threat ``j`` (centres ``c``, velocities ``u``, ``margin``, agent index ``who`` or -1)
    against every watching agent ``k`` (index ``rows``, ``radius``, ``position``, ``goal``,
    ``horizon``): the pairs whose closest approach to the agent or its goal is below
    ``margin[j] + radius[k]``, the agent itself left out."""
    t_star, closest, miss = _approach(c, u, position, horizon)
    t_goal, _, miss_goal = _approach(c, u, goal, horizon)
    need = margin[None, :] + radius[:, None]
    sel = ((miss < need) | (miss_goal < need)) & (who[None, :] != rows[:, None])
    kk, jj = np.nonzero(sel)
    times = np.stack([t_star[sel], t_goal[sel]], axis=1)
    misses = np.stack([miss[sel], miss_goal[sel]], axis=1)
    return kk.astype(np.int64) * len(c) + jj, times, misses, closest[sel]


def threat_pairs(
    c: np.ndarray,
    u: np.ndarray,
    margin: np.ndarray,
    who: np.ndarray,
    rows: np.ndarray,
    radius: np.ndarray,
    position: np.ndarray,
    goal: np.ndarray,
    horizon: np.ndarray,
    compiled: bool,
) -> Pairs:
    """:func:`threat_pairs_dense`'s pairs; ``compiled``: from a sweep along x that tests only the
    pairs within a threat's reach (its speed times the horizon plus its need), the same bits."""
    if not compiled:
        return threat_pairs_dense(c, u, margin, who, rows, radius, position, goal, horizon)
    f = np.ascontiguousarray
    return kernel_module("swarmplan.geometry._approach_kernel").threat_pairs(
        f(c, dtype=float),
        f(u, dtype=float),
        f(margin, dtype=float),
        f(who, dtype=np.int64),
        f(rows, dtype=np.int64),
        f(radius, dtype=float),
        f(position, dtype=float),
        f(goal, dtype=float),
        f(horizon, dtype=float),
        # numpy's clip keeps a -0.0 time when both its bounds broadcast as scalars (one agent).
        len(rows) == 1 and len(c) > 1,
    )


@dataclass(frozen=True)
class MoverSurfaces:
    """The moving obstacles' surfaces (``Obstacles.mover_surfaces``): ``distance(points,
    movers)`` the signed distance (K,) from ``points`` (K, 3) to mover ``movers[k]`` (its index
    among the movers) where it is, ``nearest`` the same with the distance's gradient (K, 3),
    and ``round`` (M,) the movers whose bounding sphere is their surface (spheres)."""

    distance: Callable[[np.ndarray, np.ndarray], np.ndarray]
    nearest: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    round: np.ndarray


SURFACE_SAMPLES = 9
"""Times over the horizon at which the surface approach is sampled before it is bracketed."""

SURFACE_STEPS = 30
"""Golden-section steps on the bracket of the surface's closest approach (0.618^30 of it, under
a millionth of the horizon)."""


def surface_approach(
    distance: Callable[[np.ndarray, np.ndarray], np.ndarray],
    points: np.ndarray,
    movers: np.ndarray,
    w: np.ndarray,
    horizon: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Closest approach within ``horizon`` (K,) of moving bodies ``movers`` (K,) going on at
    ``w`` (K, 3) to fixed ``points`` (K, 3): its time and the signed surface distance then.
    The body moved by ``t w`` is as far from the point as the body is from the point moved by
    ``-t w``: the distance along that line, convex for a convex body (every primitive), is
    sampled at ``SURFACE_SAMPLES`` times, then its least sample's bracket is narrowed by golden
    section (a body that is not convex, a mesh, may keep a nearer approach between samples)."""
    k = len(points)
    ts = np.linspace(0.0, 1.0, SURFACE_SAMPLES)[None, :] * horizon[:, None]  # (K, S)
    at = points[:, None, :] - ts[..., None] * w[:, None, :]
    d = distance(at.reshape(-1, 3), np.repeat(movers, SURFACE_SAMPLES)).reshape(k, SURFACE_SAMPLES)
    b = np.argmin(d, axis=1)
    rows = np.arange(k)
    lo = ts[rows, np.maximum(b - 1, 0)]
    hi = ts[rows, np.minimum(b + 1, SURFACE_SAMPLES - 1)]
    best_t, best_d = ts[rows, b], d[rows, b]

    def f(t: np.ndarray) -> np.ndarray:
        return distance(points - t[:, None] * w, movers)

    gold = 0.5 * (math.sqrt(5.0) - 1.0)
    for _ in range(SURFACE_STEPS):
        x1, x2 = hi - gold * (hi - lo), lo + gold * (hi - lo)
        left = f(x1) <= f(x2)  # a least distance lies in [lo, x2] (convex), else in [x1, hi]
        lo, hi = np.where(left, lo, x1), np.where(left, x2, hi)
    t = 0.5 * (lo + hi)
    ft = f(t)
    better = ft < best_d
    best_t, best_d = np.where(better, t, best_t), np.where(better, ft, best_d)
    return best_t, best_d


FAR_GOAL = np.array([1e9, 0.0, 0.0])
"""Offset of the goal row an evading agent's braking margin sees: its goal's cap never binds."""


class Evasion:
    """Which agents watch over their goal (arrived multirotors, for the rest of the run) and which of
    them are out of a threat's way this step (reset with :meth:`reset`)."""

    def __init__(self, params: AgentParams, dt: float, bounds: tuple[np.ndarray, np.ndarray]):
        self.params = params
        self.dt = dt
        self._bounds = bounds
        n = len(params.ids)
        self.watching = np.zeros(n, dtype=bool)
        self.evading = np.zeros(n, dtype=bool)
        # Agents that arrived (or came back) at the end of the last step: the arrival's stop takes
        # the step after it, so they are threats' targets only from the one after.
        self.settling = np.zeros(n, dtype=bool)
        self._command = np.zeros((n, 3))
        self._compiled = use_compiled_checks(n, bool(params.fixed_wing.any()))
        self._stop_speed = np.where(params.fixed_wing, np.inf, params.max_accel * dt)
        self._stop_speed.setflags(write=False)
        self._margin = evade_margin(params)

    def reset(self) -> None:
        self.watching[:] = False
        self.evading[:] = False
        self.settling[:] = False
        self._command[:] = 0.0

    def update(
        self,
        s: SwarmState,
        threats: tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]],
        surface: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
        shapes: MoverSurfaces | None = None,
    ) -> Tally:
        """Threat test for every watching agent at the step's start. ``threats`` are the movers'
        centres (M, 3), velocities (M, 3), bounding radii (M,) and ids; ``surface(rows)`` the
        clearance of agents ``rows`` to their nearest static surface and its outward normal. Arrived agents
        under threat take off (mode ``apf``, an ``evade_start`` event and an ``evasions`` count);
        agents already away stay evading while threatened; an agent that takes off flies straight
        back to its goal afterwards (the rest of its route is done). Returns the take-offs."""
        self.evading[:] = False
        rows = (self.watching & mode_in(s.mode, _WATCHED) & ~self.settling).nonzero()[0]
        self.settling[:] = False
        if not len(rows):
            return NOTHING
        p = self.params
        centres, velocities, radii, ids = threats
        # Flying agents are threats too (an agent on its way, or another one evading).
        flying = s.active.nonzero()[0]
        c = np.concatenate((centres, s.position[flying]))  # (np.vstack's rows, without its checks)
        u = np.concatenate((velocities, s.velocity[flying]))
        agent_margin = p.radius[flying] + 2.0 * safety_margin(p.radius[flying])
        margin = np.concatenate([radii + self._margin, agent_margin])
        who = np.concatenate([np.full(len(centres), -1), flying])
        if not len(c):
            return NOTHING
        radius = p.radius[rows]
        amax, vmax = p.max_accel[rows], p.speed_max[rows]
        # The largest need of each agent: max_j (margin_j + r) is max(margin) + r (rounding keeps order).
        if self._compiled:  # one compiled pass, the same bits
            horizon = kernel_module("swarmplan.geometry._approach_kernel").horizons(
                float(margin.max()), radius, amax, vmax, HORIZON_FACTOR, 3.0 * self.dt
            )
        else:
            horizon = HORIZON_FACTOR * sideways_time(margin.max() + radius, amax, vmax) + 3.0 * self.dt
        # Each threat's own motion against the agent held where it is (its evasion is what it
        # controls), and against its goal: it stays out until the goal is clear again, by one more
        # of its bodies (CLEAR_BY radii): an agent away comes back only once the threat clears its
        # goal by that much, so a prediction wavering about the need does not send it out and
        # back again step after step.
        away = mode_in(s.mode, _AWAY)[rows]
        reach = radius + CLEAR_BY * radius * away if away.any() else radius
        pairs = threat_pairs(
            c, u, margin, who, rows, reach, s.position[rows], s.goal[rows], horizon, self._compiled
        )
        if shapes is not None and len(pairs[0]):
            pairs = self._to_surfaces(pairs, shapes, (c, u, radii), rows, s, horizon, self._margin + reach)
        key, times, misses, offsets = pairs
        self._command[rows] = 0.0
        if not len(key):
            return NOTHING
        events, counts = [], []
        k_of, j_of = key // len(c), key % len(c)
        under, starts = np.unique(k_of, return_index=True)
        clearance, normal = surface(rows[under])
        bounds = np.append(starts, len(key))
        for n, k in enumerate(under.tolist()):
            i = int(rows[k])
            sl = slice(int(bounds[n]), int(bounds[n + 1]))
            js = j_of[sl]
            threat = misses[sl, 0] < margin[js] + reach[k]
            self.evading[i] = True
            side = (float(clearance[n]), normal[n])
            # Clear of every threat where it is: it hovers there until its goal is clear.
            self._command[i] = self._evasion(
                i, s.position[i], threat, offsets[sl], u[js], margin[js] + reach[k], side
            )
            if s.mode[i] == Mode.ARRIVED:
                m = sl.start + int(np.argmin(np.minimum(times[sl, 0], times[sl, 1])))
                s.mode[i] = Mode.APF
                if s.route[i] is not None:  # back to the goal straight: the route is done
                    s.route_index[i] = len(s.route[i])
                miss_j, in_j = round(float(min(misses[m, 0], misses[m, 1])), 6), round(float(times[m, 0]), 6)
                j = int(j_of[m])
                name = ids[j] if j < len(centres) else p.ids[int(who[j])]
                detail = {"threat": name, "miss": miss_j, "in": in_j}
                events.append(Event(s.t, p.ids[i], "evade_start", detail))
                counts.append(("evasions", i))
        return Tally(events=tuple(events), counts=tuple(counts)) if events else NOTHING

    def _to_surfaces(
        self,
        pairs: Pairs,
        shapes: MoverSurfaces,
        threats: tuple[np.ndarray, np.ndarray, np.ndarray],
        rows: np.ndarray,
        s: SwarmState,
        horizon: np.ndarray,
        room: np.ndarray,
    ) -> Pairs:
        """``pairs`` (found from the movers' bounding spheres) with each mover that is not a
        sphere measured by its surface instead: the closest approach of its nearest surface
        point to the agent and to its goal (a tall pole passing by has a bounding sphere as
        tall as itself, which chased arrived agents off their goals while its surface passed
        metres away). Such a pair stays a threat where the surface comes within ``room`` (per
        watching agent: the margin and its reach) of the agent or its goal; its misses are
        given as the surface's distance plus the bounding radius, and its offset as the way to
        the nearest surface point at that length, so the evasion's need (margin, bounding radius
        and reach) and sideways move keep the surface ``room`` away."""
        key, times, misses, offsets = pairs
        c, u, radii = threats
        m = len(radii)
        k_of, j_of = key // len(c), key % len(c)
        sel = np.flatnonzero(j_of < m)
        sel = sel[~shapes.round[j_of[sel]]]
        if not len(sel):
            return pairs
        k, j = k_of[sel], j_of[sel]
        n = len(sel)
        points = np.concatenate([s.position[rows[k]], s.goal[rows[k]]])
        movers, w, h = np.tile(j, 2), np.tile(u[j], (2, 1)), np.tile(horizon[k], 2)
        # Where each mover's centre is now, relative to the point: the surface's distances are
        # measured with the mover where it is and the point moved against its motion.
        t, d = surface_approach(shapes.distance, points, movers, w, h)
        at = points[:n] - t[:n, None] * w[:n]
        d_at, g_at = shapes.nearest(at, j)
        times, misses, offsets = times.copy(), misses.copy(), offsets.copy()
        times[sel] = np.stack([t[:n], t[n:]], axis=1)
        misses[sel] = np.stack([d[:n], d[n:]], axis=1) + radii[j][:, None]
        offsets[sel] = -g_at * (d_at + radii[j])[:, None]
        keep = np.ones(len(key), dtype=bool)
        keep[sel] = (d[:n] < room[k]) | (d[n:] < room[k])
        return key[keep], times[keep], misses[keep], offsets[keep]

    def _evasion(
        self,
        i: int,
        position: np.ndarray,
        threat: np.ndarray,
        closest: np.ndarray,
        w: np.ndarray,
        need: np.ndarray,
        surface: tuple[float, np.ndarray],
    ) -> np.ndarray:
        """Agent ``i``'s evasion velocity from its threats (rows of ``threat``): the sum of the
        sideways moves each needs, at a speed the agent can stop from within that move;
        ``surface`` is its clearance to the nearest static surface and that surface's normal. The
        move slides along that surface, and ends inside the flight volume: an agent at a face of
        the bounds moves along it (a mover pressing it against a face is dodged sideways, not
        into the face, where the safety filter would hold it until the mover came)."""
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
            move += self._along_faces(
                position, e, max(need[j] + p.radius[i] - gap, 0.0), wj, need[j] + p.radius[i]
            )
        if np.isfinite(clearance) and move @ normal < 0.0 and clearance < np.linalg.norm(move) + p.radius[i]:
            move -= (move @ normal) * normal  # slide along the nearest surface, never into it
        move = np.clip(move, self._bounds[0] - position, self._bounds[1] - position)
        length = float(np.linalg.norm(move))
        if length < _EPS:
            return np.zeros(3)
        speed = min(float(p.speed_max[i]), float(np.sqrt(2.0 * 0.8 * p.max_accel[i] * length)))
        return move / length * speed

    def _along_faces(
        self, position: np.ndarray, e: np.ndarray, length: float, w: np.ndarray, need: float
    ) -> np.ndarray:
        """The sideways move ``e * length`` kept inside the flight volume: its components towards
        a face of the bounds nearer than it would take them are left out (the agent slides along
        the face) and the rest is stretched to the same progress across the threat's path. Where
        less than half of ``e`` is left (the threat presses the agent straight into a face), the
        agent moves across the threat's path along that face instead, perpendicular to both the
        threat's motion ``w`` and the face, by the whole ``need``, to the side with more room."""
        lo, hi = self._bounds
        reach = e * length
        blocked = ((reach < 0.0) & (position + reach < lo)) | ((reach > 0.0) & (position + reach > hi))
        if not blocked.any():
            return reach
        slid = np.where(blocked, 0.0, e)
        kept = float(np.linalg.norm(slid))
        if kept >= 0.5:
            return slid / kept * (length / kept)
        face = np.zeros(3)
        face[int(np.argmax(np.where(blocked, np.abs(e), -1.0)))] = 1.0
        f = np.cross(w, face)
        if np.linalg.norm(f) < _EPS * max(float(np.linalg.norm(w)), 1.0):
            f = np.cross(e, face)
        if np.linalg.norm(f) < _EPS:
            f = np.cross(face, [1.0, 0.0, 0.0]) if face[0] == 0.0 else np.array([0.0, 1.0, 0.0])
        f = f / np.linalg.norm(f)
        ahead = np.where(f > 0.0, hi - position, position - lo) / np.maximum(np.abs(f), _EPS)
        behind = np.where(f < 0.0, hi - position, position - lo) / np.maximum(np.abs(f), _EPS)
        return (f if ahead.min() >= behind.min() else -f) * need

    def commands(self, idx: np.ndarray, v_cmd: np.ndarray) -> np.ndarray:
        """``v_cmd`` (rows of ``idx``) with the evading agents' rows replaced by their evasion."""
        rows = self.evading[idx]
        if not rows.any():
            return v_cmd
        out = v_cmd.copy()
        out[rows] = self._command[idx[rows]]
        return out

    def brake_goals(self, idx: np.ndarray, pos: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """The goals the braking margin of agents ``idx`` (at ``pos``) sees: an evading agent is not
        slowed by its goal, its row names a point so far off that the goal's cap never binds."""
        evading = self.evading[idx]
        return np.where(evading[:, None], pos + FAR_GOAL, goal) if evading.any() else goal

    def stop_speeds(self) -> np.ndarray:
        """The speeds an arrival (and its stop) needs at most: a one-step stop within max_accel
        (fixed wings: any); evading agents excluded (they cannot arrive while threatened)."""
        if not self.evading.any():
            return self._stop_speed
        return np.where(self.evading, -1.0, self._stop_speed)

    def arrived(self, tally: Tally, s: SwarmState) -> Tally:
        """The step's arrivals: first arrivals start watching (multirotors); a watching agent back
        at its goal gives an ``evade_end`` instead of a second ``arrived`` (and keeps its first
        arrival time)."""
        if not tally.arrivals:
            return tally
        back = {i for i, _t in tally.arrivals if self.watching[i]}
        for i, _t in tally.arrivals:
            if not self.params.fixed_wing[i]:
                self.watching[i] = True
                self.settling[i] = True
        if not back:
            return tally
        names = {self.params.ids[i] for i in back}
        events = tuple(
            Event(e.t, e.agent, "evade_end", e.detail) if e.kind == "arrived" and e.agent in names else e
            for e in tally.events
        )
        arrivals = tuple((i, t) for i, t in tally.arrivals if i not in back)
        return Tally(events, tally.counts, arrivals, tally.contacts)
