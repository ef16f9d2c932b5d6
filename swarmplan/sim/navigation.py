"""Plan following: which point each agent flies at (segment waypoint, route waypoint or
goal), starting and ending segments, the segment watchdog, and stuck detection."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from itertools import repeat
from operator import is_not

import numpy as np

from swarmplan.core import (
    DONE_MODES,
    FAILED,
    REACH_STEPS,
    SEGMENT_MODES,
    SEGMENT_REPULSION_SCALE,
    Event,
    Mode,
    PlannedSegment,
    StuckOutcome,
    SwarmState,
    mode_codes,
)
from swarmplan.flight.guide import StaticGuide
from swarmplan.flight.kinematics import AgentParams, initial_velocity
from swarmplan.sim.metrics import NOTHING, Tally
from swarmplan.world.model import World


class Navigator:
    """Per-agent progress bookkeeping over a run (reset with :meth:`reset`)."""

    def __init__(self, world: World, params: AgentParams, guide: StaticGuide | None = None):
        self.world = world
        self.params = params
        self.guide = guide
        n = len(params.ids)
        self.progress_ref = np.zeros(n)
        self.progress_t = np.zeros(n)
        # At each window's start: the straight (or route) distance and whether the guide's way
        # measured the agent (its progress is measured the same way at both ends of a window).
        self.progress_straight = np.zeros(n)
        self.progress_led = np.zeros(n, dtype=bool)
        self.segment_ref: dict[int, tuple] = {}  # agent -> (waypoint index, distance, t, segment)
        self.window = stuck_windows(world.planner_config.stuck.window, params)
        self._due_at = self.window - 1e-9  # a window has run out from this long on

    def reset(self, s: SwarmState) -> None:
        """Progress is measured from here on (call again once global routes are known)."""
        rows = np.arange(len(self.params.ids))
        self.progress_ref, self.progress_straight, self.progress_led = self.to_go(s, rows)
        self.progress_t = np.zeros(len(self.params.ids))
        self.segment_ref = {}

    def to_go(self, s: SwarmState, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance still to fly of agents ``rows``: :func:`distance_to_go`, or along the guide's
        way round static obstacles for the agents it guides (flying along a wall to its gap is
        progress, though the goal gets no nearer); straight within the field's influence of the
        goal (where the goal factor, not the guide's grid, governs the approach) and where the
        guide finds no way (a goal closer to a surface than its grid's clearance). Returns that
        distance, :func:`distance_to_go` and whether the way measured it, per row."""
        rows = np.asarray(rows)
        straight = distance_to_go(s, rows)
        dg = straight.copy()
        led = np.zeros(len(rows), dtype=bool)
        if self.guide is not None:
            near = float(self.world.planner_config.apf.influence)
            on_way = [
                k
                for k, i in enumerate(rows.tolist())
                if self.guide.guided[i] and s.active[i] and s.route[i] is None and dg[k] > near
            ]
            if on_way:
                i = rows[on_way]
                way = self.guide.way_length(s.position[i], s.goal[i])
                dg[on_way] = np.where(np.isfinite(way), way, dg[on_way])
                led[on_way] = np.isfinite(way)
        return dg, straight, led

    def _restart_windows(
        self, rows: np.ndarray | int, dg: np.ndarray, straight: np.ndarray, led: np.ndarray, t: float
    ) -> None:
        """Progress of agents ``rows`` is measured from here (``dg``, ``straight``, ``led``: of
        :meth:`to_go`) at ``t``."""
        self.progress_ref[rows], self.progress_straight[rows] = dg, straight
        self.progress_led[rows], self.progress_t[rows] = led, t

    def attraction_targets(self, s: SwarmState, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, Tally]:
        """Point each agent is attracted to (segment waypoint, route waypoint or goal), the scale
        of its static repulsion (reduced along a segment that FCL already validated), and the
        segments that ended."""
        events = []
        target = s.goal.take(idx, axis=0)  # (a new array: rows gathered as [idx] does, faster)
        scale = np.ones(len(idx))
        # Agents with neither a segment nor a route fly at their goal: nothing to do for them.
        seg, route = s.segment, s.route
        if not any(map(is_not, seg, repeat(None))) and not any(map(is_not, route, repeat(None))):
            planned = []  # no agent has either (one pass over the lists, no per-agent test)
        else:
            planned = [k for k, i in enumerate(idx.tolist()) if seg[i] is not None or route[i] is not None]
        for k in planned:
            i = idx[k]
            if s.mode[i] in SEGMENT_MODES and s.segment[i] is not None:
                wp = self.advance(s, s.segment[i], i, "segment")
                if wp is None:
                    kind = "escape_end" if s.mode[i] == Mode.ESCAPE else "smoothing_end"
                    events.append(Event(s.t, self.params.ids[i], kind, {}))
                    s.mode[i] = Mode.APF
                    s.segment[i] = None
                    rejoin_route(s, i)
                else:
                    target[k] = wp
                    scale[k] = SEGMENT_REPULSION_SCALE
                    continue
            if s.route[i] is not None:
                wp = self.advance(s, s.route[i], i, "route")
                target[k] = s.goal[i] if wp is None else wp
        return target, scale, Tally(events=tuple(events)) if events else NOTHING

    def advance(self, s: SwarmState, pts: np.ndarray, i: int, which: str) -> np.ndarray | None:
        """Next waypoint of ``pts`` not yet reached by agent ``i`` (None once all are): one within
        ``REACH_STEPS`` steps of flight (at least the goal tolerance), or within the agent's turn
        radius at its speed (``v^2 / max_accel``) and no longer closing in on it (abeam or
        behind): the nearest it can come at that speed. An agent slow to turn circled such a
        waypoint for good, commanded at it at cruise speed."""
        index = s.segment_index if which == "segment" else s.route_index
        p, v = s.position[i], s.velocity[i]
        speed = float(np.linalg.norm(v))
        reach = max(self.world.goal_tolerance, speed * self.world.dt * REACH_STEPS)
        turn = speed * speed / max(float(self.params.max_accel[i]), 1e-9)
        k = index[i]
        while k < len(pts):
            d = pts[k] - p
            gap = float(np.linalg.norm(d))
            if gap > reach and (gap > turn or float(np.dot(d, v)) > 0.0):
                break
            k += 1
        index[i] = k
        return None if k >= len(pts) else pts[k]

    def start_segment(self, s: SwarmState, i: int, seg: PlannedSegment) -> Tally:
        """Agent ``i`` follows ``seg`` from now on; returns its start (and an escape's count)."""
        s.segment[i] = np.asarray(seg.waypoints, dtype=float)
        s.segment_index[i] = 0
        if seg.route_index is not None:
            s.route_index[i] = seg.route_index
        s.mode[i] = seg.mode
        if seg.mode == Mode.ESCAPE:
            return Tally(
                events=(
                    Event(
                        s.t,
                        self.params.ids[i],
                        "escape_start",
                        {"waypoints": np.round(s.segment[i], 6).tolist()},
                    ),
                ),
                counts=(("escapes", i),),
            )
        return Tally(
            events=(
                Event(
                    s.t,
                    self.params.ids[i],
                    "smoothing_start",
                    {"waypoints": np.round(s.segment[i], 6).tolist()},
                ),
            )
        )

    def detect_stuck(
        self,
        s: SwarmState,
        on_stuck: Callable[[int], tuple[StuckOutcome, Sequence[Event]]] | None,
        exempt: np.ndarray | None = None,
        restart: np.ndarray | None = None,
    ) -> Tally:
        """No progress towards the goal for an agent's stuck window (``planner.stuck.window``
        seconds, a fixed wing's at least a full circle: :func:`stuck_windows`) is a local minimum.

        Progress is measured as the distance still to fly: straight to the goal, or along the
        rest of the global route when the agent has one (a route may detour away from the goal).
        ``on_stuck(i)`` answers for a stuck agent: a segment to follow, ``FAILED`` or None (keep
        flying under APF; a fixed wing answered ``FAILED`` flies on too: it cannot stop), with
        the events reported while planning it (logged after the ``stuck`` event). Agents of
        ``exempt`` are not checked; those of ``restart`` start their progress window again
        (fixed wings coming round onto their goals, ``swarmplan.flight.capture``). Returns what
        was detected and started.
        """
        out = NOTHING
        window = self.window
        min_progress = self.world.planner_config.stuck.min_progress
        # Only agents following a segment or whose window has run out need work this step.
        # One pass over the modes: 0 done (arrived, collided, failed), 1 apf, 2 on a segment.
        kind = mode_codes(s.mode, _STUCK_KIND, np.int8)
        if restart is not None and restart.any():  # their progress is watched from now
            again = np.flatnonzero(restart & (kind == 1))
            self._restart_windows(again, *self.to_go(s, again), s.t)
        due = np.where(kind == 1, s.t - self.progress_t >= self._due_at, kind == 2)
        if exempt is not None:
            due &= ~exempt
        rows = due.nonzero()[0]
        if not len(rows):
            return out
        dg, straight, led = (np.empty(len(s.mode)), np.empty(len(s.mode)), np.zeros(len(s.mode), dtype=bool))
        dg[rows], straight[rows], led[rows] = self.to_go(s, rows)
        for i in rows.tolist():
            if s.mode[i] != Mode.APF:
                self._restart_windows(i, dg[i], straight[i], led[i], s.t)
                out += self.segment_watchdog(s, i, float(window[i]), min_progress)
                continue
            if s.t - self.progress_t[i] < window[i] - 1e-9:
                continue
            # The same measure at both ends: along the way if it measured both, else straight
            # (the way's length jumps by the detour where the guide starts leading the agent).
            if led[i] == self.progress_led[i]:
                progress = self.progress_ref[i] - dg[i]
            else:
                progress = self.progress_straight[i] - straight[i]
            self._restart_windows(i, dg[i], straight[i], led[i], s.t)
            if progress >= min_progress:
                continue
            detail = {
                "progress": round(float(progress), 6),
                "window": float(window[i]),
                "distance_to_goal": round(float(np.linalg.norm(s.goal[i] - s.position[i])), 6),
                "distance_to_go": round(float(dg[i]), 6),
            }
            out += Tally(
                events=(Event(s.t, self.params.ids[i], "stuck", detail),), counts=(("stuck_events", i),)
            )
            if on_stuck is None:
                continue
            outcome, reported = on_stuck(i)
            out += Tally(events=tuple(reported))
            if outcome == FAILED and self.params.fixed_wing[i]:
                continue  # a fixed wing cannot stop in the air: it flies on and is asked again
            if outcome == FAILED:
                s.mode[i] = Mode.FAILED
                failed = Event(s.t, self.params.ids[i], "failed", {"reason": failure_reason(reported)})
                out += Tally(events=(failed,))
            elif outcome is not None:
                out += self.start_segment(s, i, outcome)
        return out

    def segment_watchdog(self, s: SwarmState, i: int, window: float, min_progress: float) -> Tally:
        """A segment whose next waypoint gets no closer for ``window`` s is abandoned (back to APF,
        whose stuck detection then asks the planner again). Returns the abandonment, if any."""
        seg = s.segment[i]
        if seg is None or s.segment_index[i] >= len(seg):
            return NOTHING
        k = int(s.segment_index[i])
        d = float(np.linalg.norm(seg[k] - s.position[i]))
        ref = self.segment_ref.get(i)
        if ref is None or ref[0] != k or ref[3] is not seg:
            self.segment_ref[i] = (k, d, s.t, seg)
            return NOTHING
        # A sharp corner at a waypoint costs a turnaround (brake, turn, speed up again) before
        # the distance to the next one falls: half a minimum-radius circle at cruise speed.
        p = self.params
        turn_radius = p.min_turn_radius[i] if p.fixed_wing[i] else p.speed_cruise[i] ** 2 / p.max_accel[i]
        grace = math.pi * turn_radius / max(p.speed_cruise[i], 1e-6)
        if s.t - ref[2] < window + grace - 1e-9:
            return NOTHING
        if ref[1] - d >= min_progress:
            self.segment_ref[i] = (k, d, s.t, seg)
            return NOTHING
        kind = "escape_end" if s.mode[i] == Mode.ESCAPE else "smoothing_end"
        s.mode[i] = Mode.APF
        s.segment[i] = None
        self.segment_ref.pop(i, None)
        rejoin_route(s, i)
        return Tally(events=(Event(s.t, self.params.ids[i], kind, {"abandoned": True, "waypoint": k}),))


_STUCK_KIND = {m: 0 if m in DONE_MODES else (1 if m == Mode.APF else 2) for m in Mode}
"""Per mode, what :meth:`Navigator.detect_stuck` does with an agent: 0 nothing (it no longer
flies), 1 its progress window (APF), 2 its segment's watchdog."""


def failure_reason(reported: tuple[Event, ...]) -> str:
    """Why the planner gave an agent up, from the events it reported with that answer: a
    ``hold`` that was not possible says why no escape was found and that no holding pattern
    was free."""
    for e in reversed(reported):
        if e.kind == "hold" and not e.detail.get("possible", True):
            return f"{e.detail.get('reason', 'no way out')}; no free holding pattern"
    return "no valid escape segment"


def timeouts(s: SwarmState, ids: tuple[str, ...]) -> Tally:
    """A ``timeout`` event for every agent still flying at ``s.t`` (the run's time is up)."""
    events = []
    for i in np.flatnonzero(s.active):
        distance = round(float(np.linalg.norm(s.goal[i] - s.position[i])), 6)
        events.append(Event(s.t, ids[i], "timeout", {"distance_to_goal": distance}))
    return Tally(events=tuple(events))


def initial_state(world: World, params: AgentParams) -> SwarmState:
    """Every agent at its start at t = 0, flying the field (mode ``apf``) toward its goal."""
    n = len(world.agents)
    start = np.array([a.start for a in world.agents], dtype=float)
    goal = np.array([a.goal for a in world.agents], dtype=float)
    return SwarmState(
        t=0.0,
        step=0,
        position=start,
        velocity=initial_velocity(params, start, goal),
        goal=goal,
        mode=np.array([Mode.APF] * n, dtype=object),
        segment=[None] * n,
        segment_index=np.zeros(n, dtype=int),
        route=[None] * n,
        route_index=np.zeros(n, dtype=int),
    )


def distance_to_go(s: SwarmState, rows: np.ndarray | None = None) -> np.ndarray:
    """Per agent (of ``rows``, default all): straight to the goal, or along the rest of its
    global route when it has one."""
    if rows is None:
        rows = np.arange(len(s.route))
    dg = np.linalg.norm(s.goal[rows] - s.position[rows], axis=1)
    route_of = s.route
    for r, i in enumerate(rows.tolist()):
        route = route_of[i]
        if route is None:
            continue
        k = int(s.route_index[i])
        if k < len(route):
            rest = np.vstack([route[k:], s.goal[i]])
            legs = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
            dg[r] = np.linalg.norm(route[k] - s.position[i]) + legs
    return dg


def rejoin_route(s: SwarmState, i: int) -> None:
    """After a segment, go on along the global route from its nearest point ahead of where the
    agent left it (the route is what avoids the obstacles: never straight to the goal, and
    not back to the point where the segment began)."""
    route, k0 = s.route[i], int(s.route_index[i])
    if route is None or k0 >= len(route):
        return
    d = np.linalg.norm(route[k0:] - s.position[i], axis=1)
    s.route_index[i] = k0 + int(np.argmin(d))


def stuck_windows(window: float, params: AgentParams) -> np.ndarray:
    """Per agent, the seconds without progress that make it stuck: ``planner.stuck.window``, for a
    fixed wing at least the time of a full circle at its minimum turn radius and cruise speed (a
    fixed wing turned away, by the guard or to come round onto its goal, loses ground for a turn
    and wins it back on the next: no local minimum)."""
    circle = 2.0 * np.pi * params.min_turn_radius / np.maximum(params.speed_cruise, 1e-9)
    return np.where(params.fixed_wing, np.maximum(window, circle), window)
