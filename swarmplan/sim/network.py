"""What each agent knows of the others when the world has ``comms``: the last state it heard
from each, extrapolated by its age, and what it senses itself.

Every agent broadcasts its state (position, velocity, acceleration over its last step within
its limit, whether it still flies, its distance to its goal, its mode and its plan: the route
or escape segment it follows) ``comms.rate`` times
a second, at the end of a step (agent k's broadcasts are spread over the period by k/N of it,
so the swarm does not all speak at once). Each receiver gets a
copy after ``delay`` (+- a uniform ``jitter``), unless it is lost (probability ``loss``) or the
two are farther apart than ``range`` when it is sent. A receiver keeps the newest state it has
received from each sender and acts on it, moved on for the state's age: its field by the
velocity and acceleration sent, its deconfliction by the velocity sent (with a margin for any
acceleration within the sender's limit since). A state so old that its agent may be farther
from it (``network_passes.belief_doubt``) than both agents' stopping reach is too old to act on: the
receiver knows nothing of that agent until it hears from it again.
With ``sensing``, an agent sees the true, current state of every agent within ``sensing.range``
(onboard sensing: no age).

Each copy's loss and delay are its own draws (``network_passes.draws``: a counter-based stream keyed once
per run from the run's seeded ``comms`` stream, the copy's table row and receiver picking its
draws), whenever and however often they are asked: the same seed gives the same messages.
Before flight every agent has heard every other agent within range (their starts, at t = 0).

Each agent's field, deconfliction (``swarmplan.sim.deconflict``) and the planner deciding its
escapes (through :class:`AgentView`) read these beliefs. Static bodies are the known map, and
moving obstacles are known as the world describes them. The simulator keeps the truth and alone
judges contacts and arrivals; :class:`Network` only answers what each agent believes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import chain
from operator import is_not
from typing import Any

import numpy as np

from swarmplan.core import AgentAges, Mode, SwarmState
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module, use_compiled
from swarmplan.sim.network_book import Book
from swarmplan.sim.network_passes import (
    belief_table_numpy,
    compact_near_numpy,
    deliver_numpy,
    fates_numpy,
    held_pairs,
    oldest_ages,
)
from swarmplan.world.comms import Comms, Sensing

_EPS = 1e-9

Plan = tuple[Mode, "np.ndarray | None", int, "np.ndarray | None", int]
"""An agent's mode, segment and index on it, route and index on it (as :class:`SwarmState` has them)."""


@dataclass(frozen=True)
class Beliefs:
    """What flyers ``idx`` (at ``at``, (n, 3)) believe of every agent at one time, as a table of
    believed states, one row each: ``pos``/``vel`` (M, 3) moved on to now at the velocity sent
    (the reference the deconfliction's margin bounds: an agent within its acceleration limit
    is at most ``max_accel age^2 / 2`` from it), ``expected_pos``/``expected_vel`` moved on with
    the acceleration sent too (the field's best guess), ``parked``, ``goal_distance``, ``age``
    (s since the state was true; 0 for a flyer's own and sensed rows), ``yields`` (a fixed wing
    loitering about its goal when it sent the state: it gives way, ``apf.Swarm.yields``) and
    ``agent`` (M,);
    ``view`` (n, N) the row flyer k holds of agent b (-1: it knows nothing of b). A flyer's own
    row is its true state."""

    idx: np.ndarray
    at: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    parked: np.ndarray
    goal_distance: np.ndarray
    age: np.ndarray
    agent: np.ndarray
    view: np.ndarray
    expected_pos: np.ndarray
    expected_vel: np.ndarray
    yields: np.ndarray

    def near_superset(self, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every (flyer row k, agent j, table row, distance) with agent j believed by flyer k
        closer than ``radius`` to it (itself left out), in (k, j) order, and maybe farther ones:
        the widest answer found is kept and returned whole for a narrower question (its caller
        tests each pair's distance)."""
        kept = self.__dict__.get("_near")
        if kept is not None and radius <= kept[0]:
            return kept[1]
        out = self._pairs(radius)
        self.__dict__["_near"] = (radius, out)
        return out

    def _pairs(self, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        held = _kernel().held_pairs if use_compiled(self.view.shape[1]) else held_pairs
        return held(self.view, self.pos, self.at, np.asarray(self.idx, dtype=np.int64), float(radius))


def _kernel() -> Any:
    """The compiled passes over every (receiver, sender) pair, run from swarm size on."""
    return kernel_module("swarmplan.sim._network_kernel")


class _Table:
    """Every state sent, one row each (row 0: nothing heard), grown by doubling."""

    def __init__(self, n: int):
        self.size = 1
        self.t = np.full(4 * n + 1, -np.inf)
        self.pos = np.zeros((4 * n + 1, 3))
        self.vel = np.zeros((4 * n + 1, 3))
        self.acc = np.zeros((4 * n + 1, 3))
        self.parked = np.zeros(4 * n + 1, dtype=bool)
        self.yields = np.zeros(4 * n + 1, dtype=bool)
        self.goal_distance = np.zeros(4 * n + 1)
        self.plan = np.zeros(4 * n + 1, dtype=np.int64)
        self.agent = np.full(4 * n + 1, -1, dtype=np.int64)
        self.mark = np.full(4 * n + 1, -1, dtype=np.int64)  # scratch of the compiled compaction

    def add(self, t: float, agent: np.ndarray, pos: np.ndarray, vel: np.ndarray, parked: np.ndarray,
            to_go: np.ndarray, plan: np.ndarray, yields: np.ndarray) -> np.ndarray:  # fmt: skip
        """Rows for the states of agents ``agent`` true at ``t``; returns their row numbers."""
        k, first = len(pos), self.size
        if first + k > len(self.t):
            grow = max(len(self.t), k)
            for name, fill in (("t", -np.inf), ("pos", 0.0), ("vel", 0.0), ("acc", 0.0), ("parked", False),
                               ("yields", False), ("goal_distance", 0.0), ("plan", 0), ("agent", -1),
                               ("mark", -1)):  # fmt: skip
                old = getattr(self, name)
                setattr(
                    self, name, np.concatenate([old, np.full((grow, *old.shape[1:]), fill, dtype=old.dtype)])
                )
        at = slice(first, first + k)  # (a slice writes faster than the rows' numbers)
        self.t[at], self.pos[at], self.vel[at] = t, pos, vel
        self.parked[at], self.goal_distance[at], self.plan[at] = parked, to_go, plan
        self.agent[at], self.yields[at] = agent, yields
        self.size += k
        return np.arange(first, first + k)


@dataclass
class _Sent:
    """One step's broadcasts: ``senders`` (k,), the table ``rows`` of their states, the time
    ``due`` their copies arrive (give or take the jitter)."""

    senders: np.ndarray
    rows: np.ndarray
    due: float
    heard_by: np.ndarray | None
    """(N, k): whether each copy will be heard (not its sender's own, in range, not lost)."""
    misses: tuple[np.ndarray, np.ndarray] | None = None
    """Swarm worlds in place of ``heard_by``: the receivers that will not hear each copy
    (``_network_kernel.misses``)."""


class Network:
    """The messages of one run and every agent's beliefs (reset with :meth:`reset`)."""

    def __init__(
        self, comms: Comms, sensing: Sensing | None, max_accel: np.ndarray, reach: np.ndarray, dt: float
    ):
        """``max_accel`` and ``reach`` (each agent's stopping reach, ``apf.stopping_reach``): a
        belief whose agent may be farther from it than both agents' reach is too old to act on."""
        self.comms, self.n, self.dt = comms, len(max_accel), dt
        self._stale = (np.asarray(max_accel, dtype=float), np.asarray(reach, dtype=float))
        self.max_accel = np.maximum(np.asarray(max_accel, dtype=float), 1e-9)
        self.sensing_range = math.inf if sensing is None else sensing.range
        self.period = comms.period(dt)
        # Agent k speaks at (m + k / N) periods: spread over the period.
        self._phase = np.arange(self.n) / max(self.n, 1)
        self.instant = comms.delay == 0.0 and comms.jitter == 0.0
        # Swarm worlds keep what each receiver holds sparse (``network_book.Book``): each
        # sender's base row, and the receivers holding another row (a copy missed or not yet
        # due); smaller worlds the (receiver, sender) matrix itself.
        self._sparse = use_compiled(self.n)
        n, none = self.n, np.empty(0, dtype=np.int64)
        self._no_buffers = (np.empty((0, n), dtype=np.int64), none, none, none, np.empty(0))
        self._buffers = self._no_buffers  # a swarm's, made at its first use

    def reset(self, rng: np.random.Generator, s: SwarmState) -> None:
        """At t = 0: every agent has heard every other within range, at rest at its start."""
        n = self.n
        self.key = rng.integers(0, 2**64, dtype=np.uint64)  # the run's copies' draws (network_passes.draws)
        self.table = _Table(n)
        self.plans: list[Plan] = []  # each agent's plans, one entry per change
        # Per agent, its plan last kept: number, then mode, segment and route (the objects
        # themselves), then the indexes on segment and route.
        self._last = (np.full(n, -1, dtype=np.int64), [None] * n, [None] * n, [None] * n,
                      np.zeros((n, 2), dtype=np.int64))  # fmt: skip
        pos = s.position
        start = self.table.add(
            0.0,
            np.arange(n),
            pos,
            np.zeros((n, 3)),
            np.zeros(n, dtype=bool),
            np.linalg.norm(s.goal - pos, axis=1),
            self._book(s, np.arange(n)),
            np.zeros(n, dtype=bool),
        )
        # (receiver, sender): the table row of the newest state heard (0: none)
        d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
        heard = np.where(d <= self.comms.range, start[None, :], 0)
        np.fill_diagonal(heard, 0)  # an agent knows itself, it hears nothing of itself
        # each sender's start, but for the receivers that heard nothing of it
        self._heard = Book(heard, start) if self._sparse else heard
        self.pending: list[_Sent] = []
        self.sent = self.lost = self.out_of_range = 0
        self.oldest_max, self.oldest_sum, self.oldest_count = 0.0, 0.0, 0

    @property
    def heard(self) -> np.ndarray:
        """(receiver, sender): the table row of the newest state heard (0: none)."""
        return self._heard.matrix() if self._sparse else self._heard

    def _heard_by(self, i: int) -> np.ndarray:
        """(sender,): the table row of the newest state agent ``i`` heard of each (0: none)."""
        return self._heard.held_by(i) if self._sparse else self._heard[i]

    @property
    def t_heard(self) -> np.ndarray:
        """(receiver, sender): when the newest state heard was true (-inf: none heard)."""
        return self.table.t[self.heard]

    def speakers(self, t0: float, t1: float) -> np.ndarray:
        """The agents whose broadcast falls in the step (t0, t1]."""
        k0 = np.floor(t0 / self.period - self._phase + _EPS)
        k1 = np.floor(t1 / self.period - self._phase + _EPS)
        return np.flatnonzero(k1 > k0)

    def broadcast(
        self, t0: float, s: SwarmState, parked: np.ndarray, acc: np.ndarray, yields: np.ndarray
    ) -> None:
        """The states at the end of the step from ``t0`` to ``s.t`` (``parked``: the agents that
        no longer fly; ``acc``: each agent's acceleration over the step; ``yields``: the fixed
        wings loitering about their goals) of the agents that speak in it."""
        t1, pos, vel = s.t, s.position, s.velocity
        who = self.speakers(t0, t1)
        if not len(who):
            return
        c, n, k = self.comms, self.n, len(who)
        self.sent += k * (n - 1)
        rows = self.table.add(
            t1,
            who,
            pos[who],
            vel[who],
            parked[who],
            norm3(s.goal[who] - pos[who]),
            self._book(s, who),
            yields[who],
        )
        # The acceleration within max_accel: a stop beyond it says nothing of the next steps.
        over = norm3(acc[who]) / self.max_accel[who]
        self.table.acc[rows[0] : rows[0] + k] = acc[who] / np.maximum(over, 1.0)[:, None]
        at = pos if math.isfinite(c.range) else np.zeros((0, 3))
        if self._sparse:
            m = _Sent(who, rows, t1 + c.delay, None)
            ptr, miss, lost, out = _kernel().misses(who, rows, self.key, self._fate(m), at, n)
            m.misses = (ptr, miss)
        else:
            m = _Sent(who, rows, t1 + c.delay, np.empty((n, k), dtype=bool))
            lost, out = fates_numpy(who, rows, self.key, self._fate(m), at, m.heard_by)
        self.lost, self.out_of_range = self.lost + int(lost), self.out_of_range + int(out)
        self.pending.append(m)

    def _book(self, s: SwarmState, who: np.ndarray) -> np.ndarray:
        """The numbers of the plans of agents ``who`` (ascending) in ``s``. A plan is kept when it
        changes (keeping one per state sent would keep the garbage collector busy in a swarm):
        its arrays are replaced, never changed, on a new plan, so their identity names them, and
        the plan kept holds them alive."""
        number, mode, segment, route, at = self._last
        k, w = len(who), who.tolist()
        everyone = k == self.n  # (then ``who`` is every agent in order)
        pick = (lambda seq: seq) if everyone else (lambda seq: list(map(seq.__getitem__, w)))
        now = (pick(s.mode.tolist()), pick(s.segment), pick(s.route))
        held = (pick(mode), pick(segment), pick(route))
        other = np.fromiter(map(is_not, chain(*now), chain(*held)), dtype=bool, count=3 * k)
        indexes = np.column_stack((s.segment_index[who], s.route_index[who]))
        changed = (number[who] < 0) | other.reshape(3, k).any(axis=0) | (at[who] != indexes).any(axis=1)
        for c in np.flatnonzero(changed).tolist():
            i = w[c]
            number[i], mode[i], segment[i], route[i] = len(self.plans), s.mode[i], s.segment[i], s.route[i]
            at[i] = indexes[c]
            self.plans.append(
                (s.mode[i], s.segment[i], int(s.segment_index[i]), s.route[i], int(s.route_index[i]))
            )
        return number[who].copy()

    def deliver(self, t: float) -> None:
        """Every copy that has arrived by ``t`` replaces an older state of its sender."""
        c = self.comms
        keep: list[_Sent] = []
        for m in self.pending:  # oldest broadcasts first: a newer state replaces an older one
            if m.due - c.jitter > t + _EPS:  # nothing of it arrives yet
                keep.append(m)
                continue
            if self._sparse:
                partial = m.due + c.jitter > t + _EPS
                self._heard.deliver(m.senders, m.rows, self.key, self._fate(m), m.misses, t, partial)
            else:
                deliver_numpy(self._heard, m.senders, m.rows, self.key, self._fate(m), m.heard_by, t)
            if m.due + c.jitter > t + _EPS:  # copies still on their way
                keep.append(m)
        self.pending = keep

    def _fate(self, m: _Sent) -> tuple[float, float, float, float]:
        """(loss, the delay's jitter, the time broadcast ``m`` falls due, range)."""
        c = self.comms
        return (c.loss, c.jitter, m.due, c.range)

    def agreed(self, t: float) -> np.ndarray | None:
        """(N, N): the pairs that heard each other's state of ``t`` over an instantaneous network,
        who can agree on their steps within the step from ``t``; None when messages take time."""
        if not self.instant:
            return None
        self.deliver(t)
        fresh = self.t_heard == t
        return fresh & fresh.T

    def oldest(self, beliefs: Beliefs, reach: float) -> np.ndarray:
        """Per flyer of ``beliefs``: the age of the oldest state it acts on, of the agents it
        believes within ``reach`` (the field's agent reach: farther ones change nothing); nan
        when it believes none that near."""
        k, _, rows, d = beliefs.near_superset(reach)
        run = _kernel().oldest_ages if self._sparse else oldest_ages
        return run(k, rows, d, beliefs.age, reach, len(beliefs.idx))

    def message(self, t: float, ids: tuple[str, ...], idx: np.ndarray, oldest: np.ndarray | None) -> dict:
        """The ``/comms`` message of the step ending at ``t``: flyers ``idx`` acted on states at
        most ``oldest`` (rows of ``idx``) old."""
        age = np.full(self.n, np.nan)
        if oldest is not None:
            age[idx] = oldest
            acted = oldest[~np.isnan(oldest)]
            if len(acted):
                self.oldest_max = max(self.oldest_max, float(acted.max()))
                self.oldest_sum, self.oldest_count = (
                    self.oldest_sum + float(acted.sum()),
                    self.oldest_count + len(acted),
                )
        # Each distinct age rounded once (a swarm's ages take a few values: whole steps).
        ok = ~np.isnan(age)
        distinct, which = np.unique(age[ok], return_inverse=True)
        code = np.zeros(self.n, dtype=np.int64)
        code[ok] = which.ravel() + 1
        agents = AgentAges(ids, (None, *(round(x, 6) for x in distinct.tolist())), code)
        return {"t": round(t, 9), "agents": agents, **self.counts()}

    def counts(self) -> dict[str, int]:
        """The run's messages so far: copies sent (one per listener), lost, and out of range."""
        return {"sent": self.sent, "lost": self.lost, "out_of_range": self.out_of_range}

    def run_report(self) -> dict[str, float | int]:
        """``/summary`` ``comms``: the run's messages, and the largest and mean age of the oldest
        state an agent acted on (over the steps and flyers that acted on any)."""
        mean = self.oldest_sum / self.oldest_count if self.oldest_count else 0.0
        return {
            **self.counts(),
            "oldest_age_max": round(self.oldest_max, 6),
            "oldest_age_mean": round(mean, 6),
        }

    def beliefs(
        self,
        idx: np.ndarray,
        t: float,
        pos: np.ndarray,
        vel: np.ndarray,
        parked: np.ndarray,
        goal_distance: np.ndarray,
        near: float = 0.0,
        yields: np.ndarray | None = None,
        reuse: bool = False,
    ) -> Beliefs:
        """What flyers ``idx`` believe at ``t`` (the true states ``pos``, ``vel``, ``parked``,
        ``goal_distance`` of every agent give each flyer its own row and what it senses), with
        every copy that has arrived by ``t`` taken in; the pairs within ``near`` of each flyer
        (:meth:`Beliefs.near_superset`) found on the way; ``yields``: which agents loiter now
        (their own and sensed rows; None: none); ``reuse``: the views and pairs written into the
        network's own buffers (a swarm's), valid until the next call that reuses them."""
        self.deliver(t)
        tb, n = self.table, len(idx)
        idx64 = np.asarray(idx, dtype=np.int64)
        sensing = math.isfinite(self.sensing_range)
        table = (tb.t[: tb.size], tb.pos[: tb.size], tb.vel[: tb.size])
        # With sensing the view changes below: its pairs are found when asked.
        radius = 0.0 if sensing else float(near)
        run, book = (
            (_kernel().compact_near, self._heard.lists) if self._sparse else (compact_near_numpy, self._heard)
        )
        if reuse and self._sparse and not len(self._buffers[0]):
            size = self.n * self.n  # room for every agent flying
            self._buffers = (np.empty((self.n, self.n), dtype=np.int64), np.empty(size, dtype=np.int64),
                             np.empty(size + 1, dtype=np.int64), np.empty(size, dtype=np.int64),
                             np.empty(size))  # fmt: skip
        buffers = self._buffers if reuse and self._sparse else self._no_buffers
        live, view, age, moved, pairs = run(
            book, idx64, tb.mark[: tb.size], table, t, pos[idx], radius, self._stale, buffers
        )
        # The rows heard (moved on by their age), then the true states: of the flyers, or with
        # sensing of every agent (a flyer senses agents within range as they are).
        truth = np.arange(self.n) if sensing else idx
        first = len(live)
        view[np.arange(n), idx] = first + (idx if sensing else np.arange(n))
        if sensing:
            k, j = _within(pos[idx], pos, self.sensing_range)
            view[k, j] = first + j
        yields = np.zeros(self.n, dtype=bool) if yields is None else yields
        rows = (tb.vel, tb.acc, tb.parked, tb.goal_distance, tb.agent, tb.yields)
        run = _kernel().belief_table if self._sparse else belief_table_numpy
        # (position, velocity, parked, to go, age, agent, expected position and velocity, yields)
        now = (pos, vel, parked, goal_distance, yields)
        f = run(live, age, moved, rows, np.asarray(truth, dtype=np.int64), now)
        b = Beliefs(idx, pos[idx], *f[:6], view, *f[6:])
        if radius > 0.0:
            b.__dict__["_near"] = (radius, pairs)
        return b

    def state_for(self, i: int, s: SwarmState, parked: np.ndarray) -> SwarmState:
        """The state ``s`` as agent ``i`` knows it (``parked``: the agents that no longer fly):
        its own row true, every other agent's as heard (moved on by its age, its mode and plan
        as sent) or sensed; an agent it knows nothing of is absent (``collided``)."""
        b = self.beliefs(
            np.array([i]), s.t, s.position, s.velocity, parked, np.linalg.norm(s.goal - s.position, axis=1)
        )
        rows = b.view[0]
        heard = self._heard_by(i)
        position, velocity = b.pos[rows], b.vel[rows]
        mode, segment, route = s.mode.copy(), list(s.segment), list(s.route)
        seg_index, route_index = s.segment_index.copy(), s.route_index.copy()
        for j in range(self.n):
            if j == i:
                continue
            if rows[j] < 0:
                mode[j] = Mode.COLLIDED
                continue
            mode[j], segment[j], seg_index[j], route[j], route_index[j] = self.plans[
                self.table.plan[heard[j]]
            ]
        position[rows < 0], velocity[rows < 0] = s.position[rows < 0], 0.0  # absent, never read
        return SwarmState(
            s.t, s.step, position, velocity, s.goal, mode, segment, seg_index, route, route_index
        )


class AgentView:
    """The running simulation as agent ``agent`` knows it, for the planner deciding for it in a
    world with ``comms``: ``state`` is :meth:`Network.state_for`; everything else (the world,
    the bodies, the random streams, the reports) is the simulation's."""

    def __init__(self, sim: Any, agent: int):
        self._sim = sim
        self.state = sim.network.state_for(agent, sim.state, ~sim.loiter.flying(sim.state, sim.state.active))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)


def _within(at: np.ndarray, pos: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (row of ``at``, row of ``pos``) closer than ``radius``."""
    if len(at) * len(pos) <= 4096:
        k, j = np.nonzero(np.linalg.norm(at[:, None, :] - pos[None, :, :], axis=-1) <= radius)
        return k, j
    from scipy.spatial import cKDTree

    found = cKDTree(pos).query_ball_point(at, radius)
    counts = np.fromiter(map(len, found), dtype=np.int64, count=len(at))
    k = np.repeat(np.arange(len(at)), counts)
    return k, np.fromiter((r for f in found for r in f), dtype=np.int64, count=int(counts.sum()))
