"""Each agent's own deconfliction on what it believes of the others (worlds with ``comms``).

Without ``comms`` the safety filter deconflicts every pair on both agents' committed steps (a
perfect network lets them agree within the step), sliding, braking or stopping as below. With
it, two agents agree that way only when each heard the other's state of this very step (an
instantaneous network); every other pair is judged by the flyer alone: its own step against
the other's believed motion over the step (the last state heard, moved on by its velocity),
with a margin for what the other may have done since: ``max_accel (age + dt)^2 / 2`` with
``age`` the belief's age at the step's start.
A multirotor whose step closes in on another agent's believed motion to within both bodies,
each inflated by its safety margin (``kinematics.safety_margin``), and that margin slides (its
step without the part towards those agents, when that is within its acceleration limit), else
brakes (``max_accel``); it stops (an ``emergency_stop``) only at rest or where braking would
touch a body: the margins of the others hold only while every agent keeps to its acceleration
limit. A step that only widens the gap is no conflict. A belief whose
margin exceeds both agents' stopping reach (``apf.stopping_reach``) is too old to act on.
Before that, each multirotor's command keeps room to stop behind the agents it heard of
(:func:`braking_room`).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from swarmplan.core import Event
from swarmplan.flight.apf import stopping_reach
from swarmplan.flight.kinematics import AgentParams, checked_radius
from swarmplan.geometry.collision import segment_segment_min_distance
from swarmplan.geometry.neighbours import agent_contacts_indexed
from swarmplan.geometry.vec3 import dot3, norm3
from swarmplan.runtime.compiled import kernel_module, use_compiled, use_compiled_checks
from swarmplan.sim.braking import stoppable_speed
from swarmplan.sim.modes import ARRIVED, mode_in
from swarmplan.sim.network import Beliefs
from swarmplan.sim.network_passes import belief_doubt
from swarmplan.world.model import World


class Stopper(Protocol):
    """What deconfliction asks of the safety filter (``swarmplan.sim.safety.SafetyFilter``)."""

    params: AgentParams
    world: World
    checked_radius: np.ndarray  # every agent's radius with its safety margin

    def brake(self, i: int, v0: np.ndarray) -> np.ndarray: ...
    def stop_counts(self, i: int, v0: np.ndarray) -> list[tuple[str, int]]: ...
    def step_is_safe(
        self, i: int, p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray
    ) -> bool: ...


class Step(Protocol):
    """The step from ``t0`` to ``t1`` and the obstacles' poses at both ends (``safety.StepWindow``)."""

    t0: float
    t1: float
    q0: np.ndarray
    q1: np.ndarray


class Flyers(Protocol):
    """The flying agents ``idx``; with ``comms`` their beliefs and the pairs that can agree
    within the step (``safety.Commands``)."""

    idx: np.ndarray
    beliefs: Beliefs | None
    agreed: np.ndarray | None


def deconflict(
    filt: Stopper,
    commands: Flyers,
    start: tuple[np.ndarray, np.ndarray],
    end: tuple[np.ndarray, np.ndarray],
    mode: np.ndarray,
    window: Step,
) -> tuple[list[Event], list[tuple[str, int]], np.ndarray]:
    """The flying agents' (``commands.idx``) steps from ``start`` to ``end`` (positions,
    velocities; ``end`` changed in place) deconflicted: a pair whose bodies, each inflated by its
    safety margin, would touch during the step while closing in slides its multirotor(s) (the
    step without its part towards the other, within ``max_accel``, where that clears; once per
    agent and step), else stops them, braking (``max_accel``) where braking clears, until no
    conflict remains (a pair already that close
    that keeps its distance or opens it is let go: stopped, it could never part again, and a lab
    swarm froze for good); with ``comms`` only the pairs that can agree within the
    step, and then each agent alone on its beliefs (:func:`belief_conflicts`). Returns the
    events, the stop counters and which agents braked or stopped."""
    (pos0, vel0), (pos1, vel1) = start, end
    p, dt, ids = filt.params, filt.world.dt, filt.params.ids
    events: list[Event] = []
    counts: list[tuple[str, int]] = []
    n = len(ids)
    active = np.zeros(n, dtype=bool)
    active[commands.idx] = True
    stopped = np.zeros(n, dtype=bool)
    slid = np.zeros(n, dtype=bool)
    present = active | mode_in(mode, ARRIVED)  # no mode changes below
    checked = filt.checked_radius  # each body inflated by its safety margin
    compiled = use_compiled_checks(n, bool(p.fixed_wing.any()))
    for _ in range(n):
        pairs = agent_contacts_indexed(pos0, pos1, checked, present, compiled=compiled)
        if commands.beliefs is not None:  # together only the pairs that can agree within the step
            pairs = [(a, b) for a, b in pairs if commands.agreed is not None and commands.agreed[a, b]]
        changed = False
        for a, b in pairs:
            if _parting(pos0[a] - pos0[b], (pos1[a] - pos0[a]) - (pos1[b] - pos0[b])):
                continue
            for i in (a, b):
                if active[i] and not stopped[i] and not p.fixed_wing[i]:
                    other = b if i == a else a
                    w0 = pos0[i] - pos0[other]
                    if not slid[i]:
                        # Slide first (as on beliefs): the step without its part towards the
                        # other, within the acceleration limit of its last velocity, where it
                        # opens the gap or keeps clear and touches no body (a multirotor under
                        # another that only climbed into it stopped for good, the two held).
                        unit = -w0 / max(float(np.linalg.norm(w0)), 1e-9)
                        slide = vel1[i] - max(float(unit @ vel1[i]), 0.0) * unit
                        p_slide = pos0[i] + slide * dt
                        dw = (p_slide - pos0[i]) - (pos1[other] - pos0[other])
                        d = float(segment_segment_min_distance(pos0[i], p_slide, pos0[other], pos1[other]))
                        slid[i] = True
                        if (
                            np.linalg.norm(slide - vel0[i]) <= p.max_accel[i] * dt * (1.0 + 1e-9)
                            and (d >= checked[i] + checked[other] or _parting(w0, dw))
                            and filt.step_is_safe(i, pos0[i], p_slide, window.q0, window.q1)
                        ):
                            vel1[i] = slide
                            pos1[i] = p_slide
                            changed = True
                            continue
                    safe_brake = filt.brake(i, vel0[i])
                    p_brake = pos0[i] + safe_brake * dt
                    dw = (p_brake - pos0[i]) - (pos1[other] - pos0[other])
                    d = float(segment_segment_min_distance(pos0[i], p_brake, pos0[other], pos1[other]))
                    clear = d >= checked[i] + checked[other] or _parting(w0, dw)
                    if clear and filt.step_is_safe(i, pos0[i], p_brake, window.q0, window.q1):
                        vel1[i] = safe_brake
                    else:
                        vel1[i] = 0.0
                        counts += filt.stop_counts(i, vel0[i])
                        events.append(Event(window.t1, ids[i], "emergency_stop", {"other": ids[other]}))
                    pos1[i] = pos0[i] + vel1[i] * dt
                    stopped[i] = True
                    changed = True
        if not changed:
            break
    if commands.beliefs is not None:  # the rest: each agent alone, on what it believes
        deciding = active & ~stopped & ~p.fixed_wing
        more = belief_conflicts(filt, commands.beliefs, start, end, deciding, commands.agreed, window)
        events, counts, stopped = events + more[0], counts + more[1], stopped | more[2]
    return events, counts, stopped


def belief_margin(max_accel: np.ndarray, age: np.ndarray, dt: float) -> np.ndarray:
    """How far an agent may be from where it is believed at the end of a step: accelerating at
    ``max_accel`` since its state was true, ``age`` seconds before the step's start."""
    return belief_doubt(max_accel, np.where(np.isfinite(age), age, 0.0) + dt)


def belief_conflicts(
    filt: Stopper,
    beliefs: Beliefs,
    start: tuple[np.ndarray, np.ndarray],
    end: tuple[np.ndarray, np.ndarray],
    deciding: np.ndarray,
    agreed: np.ndarray | None,
    window: Step,
) -> tuple[list[Event], list[tuple[str, int]], np.ndarray]:
    """Stops and brakes of the multirotors ``deciding`` (bool, per agent) whose step from
    ``start`` to ``end`` (positions, velocities; ``end`` changed in place) would meet another
    agent's believed motion. ``agreed`` (N, N): the pairs already deconflicted together.
    Returns the events, the stop counters and which agents braked or stopped."""
    p, dt = filt.params, filt.world.dt
    (pos0, vel0), (pos1, vel1) = start, end
    events: list[Event] = []
    counts: list[tuple[str, int]] = []
    stopped = np.zeros(len(pos0), dtype=bool)
    if not deciding[beliefs.idx].any():
        return events, counts, stopped
    checked = checked_radius(p.radius)  # each body inflated by its safety margin
    # A belief whose margin exceeds both agents' stopping reach says nothing the pair can act on.
    cap = stopping_reach(p, dt)
    widest = min(2.0 * float(cap.max()), float(belief_margin(p.max_accel.max(), beliefs.age.max(), dt)))
    radius = float(
        norm3(pos1[beliefs.idx] - pos0[beliefs.idx]).max()
        + norm3(beliefs.vel).max() * dt
        + 2.0 * float(checked.max()) + widest
    )  # fmt: skip
    believed = (np.asarray(beliefs.idx, dtype=np.int64), beliefs.age, beliefs.pos, beliefs.vel)
    agents = (p.max_accel, cap, checked, deciding)
    agree = np.zeros((0, 0), dtype=bool) if agreed is None else agreed
    run = _kernel().meetings if use_compiled(len(p.radius)) else meetings_numpy
    k, j, need, closing, b0, b1, d, meet = run(
        beliefs.near_superset(radius), radius, believed, (pos0, pos1), agents, agree, dt
    )
    amax = p.max_accel
    for f in np.unique(k[meet]):
        mine = np.flatnonzero(k == f)
        i, n = int(beliefs.idx[f]), len(mine)
        at = np.repeat(pos0[i][None], n, 0)
        believed = (b0[mine], b1[mine], need[mine], closing[mine])

        def clears(v: np.ndarray, i: int = i, at: np.ndarray = at, believed: tuple = believed) -> bool:
            return _clears(filt, i, pos0[i], at, v * dt, believed, window)

        # Slide: the step without its part towards the others it would close in on (within the
        # acceleration limit of its last velocity), else brake, else stop.
        toward = b0[mine] - pos0[i]
        unit = toward / np.maximum(np.linalg.norm(toward, axis=1), 1e-9)[:, None]
        slide = vel1[i] - np.maximum(unit @ vel1[i], 0.0) @ unit
        brake = filt.brake(i, vel0[i])
        other = p.ids[j[mine][int(np.argmin(d[mine] - need[mine]))]]
        if np.linalg.norm(slide - vel0[i]) <= amax[i] * dt * (1.0 + 1e-9) and clears(slide):
            vel1[i] = slide
        elif clears(brake):
            vel1[i] = brake
        elif filt.step_is_safe(i, pos0[i], pos0[i] + brake * dt, window.q0, window.q1) and np.any(brake):
            # Braking within max_accel even where it does not clear: the others' margins hold
            # only while every agent keeps to its limit (a stop beyond it is what they cannot
            # foresee).
            vel1[i] = brake
        else:
            vel1[i] = 0.0
            counts += filt.stop_counts(i, vel0[i])
            events.append(Event(window.t1, p.ids[i], "emergency_stop", {"other": other}))
        pos1[i] = pos0[i] + vel1[i] * dt
        stopped[i] = True
    return events, counts, stopped


def meetings_numpy(
    pairs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    radius: float,
    believed: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    steps: tuple[np.ndarray, np.ndarray],
    agents: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    agreed: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, ...]:
    """Of the believed ``pairs`` (flyer row k, agent j, table row, distance now), those within
    ``radius`` whose flyer decides (``agents`` = (max_accel, stopping reach, checked radius,
    deciding) per agent) on a belief not too old to act on (its margin, :func:`belief_margin`,
    within both stopping reaches) and not agreed within the step (``agreed`` (N, N), or empty:
    none): their k, j, the distance needed (both checked bodies and the margin), the distance
    now less a rounding, the other's believed motion over the step (from, to: ``believed`` =
    (flyer agents, table ages, positions, velocities)), the closest approach of the flyer's step
    (``steps`` = (start, end) positions per agent) to it, and whether the step meets it: within
    the distance needed and closing in (a step away from an agent already within the margin
    only widens the gap)."""
    k, j, rows, now = pairs
    own, age, pos, vel = believed
    max_accel, cap, checked, deciding = agents
    pos0, pos1 = steps
    idx = own[k]
    margin = belief_margin(max_accel[j], age[rows], dt)
    keep = (now < radius) & deciding[idx] & (margin <= cap[idx] + cap[j])
    if agreed.shape[0]:
        keep &= ~agreed[idx, j]
    k, j, rows, now, idx, margin = k[keep], j[keep], rows[keep], now[keep], idx[keep], margin[keep]
    need = checked[idx] + checked[j] + margin
    b0 = pos[rows]
    b1 = b0 + vel[rows] * dt
    d = segment_segment_min_distance(pos0[idx], pos1[idx], b0, b1)
    closing = now * (1.0 - 1e-9)
    return k, j, need, closing, b0, b1, d, (d < need) & (d < closing)


def _parting(w0: np.ndarray, dw: np.ndarray) -> bool:
    """Whether two points ``w0`` apart (one minus the other) moving ``dw`` relative to each other
    in a step never come closer than they start (the closest approach of the step is its start)."""
    return float(w0 @ dw) >= 0.0


def _clears(
    filt: Stopper, i: int, p0: np.ndarray, at: np.ndarray, move: np.ndarray, believed: tuple, window: Step
) -> bool:
    """Whether agent ``i``'s step ``move`` from ``p0`` (``at``: ``p0`` once per pair) keeps out of
    the believed motions ``believed`` (from, to, the distance needed, the distance now; one
    row per other agent: far enough, or not closing in) and touches no body."""
    b0, b1, need, now = believed
    d = segment_segment_min_distance(at, at + move, b0, b1)
    return bool(((d >= need) | (d >= now)).all()) and filt.step_is_safe(
        i, p0, p0 + move, window.q0, window.q1
    )


def oldest_age(beliefs: Beliefs) -> float:
    """The age of the oldest state in ``beliefs`` (0 when none has an age; found once per beliefs)."""
    kept = beliefs.__dict__.get("_oldest")
    if kept is None:
        known = beliefs.age[np.isfinite(beliefs.age)]
        kept = beliefs.__dict__["_oldest"] = float(known.max(initial=0.0))
    return kept


class BrakingLook:
    """How far :func:`braking_room` looks (:meth:`radius`), its parts fixed by the agents and the
    step computed once: both agents' stopping reach and both bodies (``checked``: each inflated
    by its safety margin), and how far the other may be from where it is believed."""

    def __init__(self, params: AgentParams, dt: float):
        self.checked = checked_radius(params.radius)
        self._fixed = float(2.0 * (stopping_reach(params, dt).max() + self.checked.max()))
        self._max_accel = np.asarray(params.max_accel.max())

    def radius(self, age: float) -> float:
        """The radius with beliefs at most ``age`` old."""
        return self._fixed + float(belief_doubt(self._max_accel, np.asarray(age)))


def braking_room(
    params: AgentParams, beliefs: Beliefs, v_cmd: np.ndarray, dt: float, look: BrakingLook | None = None
) -> np.ndarray:
    """The commands ``v_cmd`` (one row per flyer of ``beliefs``) of multirotors cut along the
    line to each agent they believe ahead, to what still stops behind it: a step of reaction,
    then braking at 0.8 ``max_accel`` (the rest of the limit left to steer, as the surface and
    goal caps of ``apf.commanded_velocity`` brake), within the gap between both bodies (each
    inflated by its safety margin) less where the other may be beyond its belief
    (``belief_doubt``), plus the braking distance (at its full limit) of the speed at which the
    other moves away, less what it may have lost since (``max_accel age``): a leader that
    brakes unheard is not run into. Another that may be coming closer takes its own room out of
    the gap (its step of reaction and its braking at 0.8 of its limit from that speed): each
    of the two keeps its own share. A state of now (age 0: the pair agrees within the step,
    ``deconflict``) is left to the safety filter (``look``: :class:`BrakingLook` of ``params``
    and ``dt``, made here when None). A new array."""
    p = params
    out = np.array(v_cmd, dtype=float)
    look = BrakingLook(p, dt) if look is None else look
    checked = look.checked
    radius = look.radius(oldest_age(beliefs))
    compiled = use_compiled(len(p.radius))
    b = beliefs
    believed = (np.asarray(b.idx, dtype=np.int64), b.age, b.pos, b.vel, b.at)
    run = _kernel().closing_pairs if compiled else closing_pairs_numpy
    agents = (p.fixed_wing, p.max_accel, checked)
    k, n, room, brake = run(b.near_superset(radius), radius, believed, out, agents, dt)
    if len(k):
        (_kernel().cut if compiled else cut_numpy)(out, k, n, stoppable_speed(room, brake, dt))
    return out


def _kernel() -> Any:
    """The compiled passes of :func:`braking_room` and :func:`belief_conflicts`, run from swarm
    size on."""
    return kernel_module("swarmplan.sim._deconflict_kernel")


def closing_pairs_numpy(
    pairs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    radius: float,
    believed: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    v_cmd: np.ndarray,
    agents: tuple[np.ndarray, np.ndarray, np.ndarray],
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Of the believed ``pairs`` (flyer row k, agent j, table row, distance), those within
    ``radius`` that multirotor flyers' commands ``v_cmd`` close in on, with a state of some age
    (a state of now, age 0, the pair agrees within the step, :func:`deconflict`): their flyer
    rows, unit vectors towards the other, the room along them (:func:`braking_room`) and the
    flyer's braking, 0.8 of its limit (``believed`` = (flyer agents, table ages, positions,
    velocities, flyer positions); ``agents`` = (fixed wing, max_accel, checked radius))."""
    k, j, rows, dist = pairs
    own, age_row, pos, vel, at = believed
    fixed_wing, max_accel, checked = agents
    i, age = own[k], age_row[rows]
    keep = (dist < radius) & ~fixed_wing[i] & (dist > 0.0) & (age > 0.0) & np.isfinite(age)
    k, j, rows, dist, i, age = k[keep], j[keep], rows[keep], dist[keep], i[keep], age[keep]
    n = (pos[rows] - at[k]) / dist[:, None]
    # A command is cut only where it closes in faster than allowed (never below 0): the pairs
    # it does not close in on are left out before the rest is worked out.
    closing = dot3(v_cmd[k], n) > 0.0
    k, j, rows, dist, i, age, n = (a[closing] for a in (k, j, rows, dist, i, age, n))
    aj = max_accel[j]
    gap = dist - checked[i] - checked[j] - belief_doubt(aj, age)
    away = dot3(vel[rows], n) - aj * age
    towards = np.maximum(-away, 0.0)
    bj = 0.8 * aj
    coming = -(towards * dt + towards * towards / (2.0 * bj))
    own_room = np.where(away > 0.0, away * away / (2.0 * aj), coming)
    return k, n, np.maximum(gap + own_room, 0.0), 0.8 * max_accel[i]


def cut_numpy(out: np.ndarray, k: np.ndarray, n: np.ndarray, allowed: np.ndarray) -> None:
    """In place, each command ``out[k[r]]`` that closed in along ``n[r]`` faster than
    ``allowed[r]`` before any cut is cut to it, in (flyer, agent) order."""
    for r in np.flatnonzero(dot3(out[k], n) > allowed):
        excess = float(dot3(out[k[r]], n[r])) - allowed[r]
        if excess > 0.0:
            out[k[r]] -= excess * n[r]
