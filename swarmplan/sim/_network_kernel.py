"""Compiled phases of the network of a world with ``comms`` (``swarmplan.sim.network``), for
swarms: every (receiver, sender) pair is visited each step, which numpy does in many passes
over (N, N) arrays and a loop does in one. Each function is its numpy counterpart's arithmetic
in the same order (tests/test_network_kernel.py holds them to the same answers)."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def within(dx, dy, dz, wide, radius):  # noqa: ANN001, ANN201
    """The length of (``dx``, ``dy``, ``dz``) when below ``radius``, else -1 (``wide``: the
    squared radius widened by rounding, beyond which no root is taken)."""
    d2 = (dx * dx + dy * dy) + dz * dz
    if not d2 < wide:
        return -1.0
    d = math.sqrt(d2)
    return d if d < radius else -1.0


@njit(cache=True, nogil=True)
def held_pairs(view, pos, at, own, radius):  # noqa: ANN001, ANN201
    """(flyer row k, agent j, table row, distance) for every agent j that flyer k (at
    ``at[k]``, agent ``own[k]``) holds a row of (``view[k, j]`` >= 0) within ``radius`` of it,
    itself left out, in (k, j) order."""
    n, n_all = view.shape
    # One pass into room for every pair (pages never written are never touched).
    ks = np.empty(n * n_all, dtype=np.int64)
    js = np.empty(n * n_all, dtype=np.int64)
    rows = np.empty(n * n_all, dtype=np.int64)
    ds = np.empty(n * n_all)
    c = 0
    wide = radius * radius * (1.0 + 1e-9)
    for k in range(n):
        for j in range(n_all):
            r = view[k, j]
            if r < 0 or j == own[k]:
                continue
            d = within(pos[r, 0] - at[k, 0], pos[r, 1] - at[k, 1], pos[r, 2] - at[k, 2], wide, radius)
            if d >= 0.0:
                ks[c], js[c], rows[c], ds[c] = k, j, r, d
                c += 1
    return ks[:c].copy(), js[:c].copy(), rows[:c].copy(), ds[:c].copy()


_SPREAD_ROW = np.uint64(0x9E3779B97F4A7C15)
_SPREAD_COPY = np.uint64(0xD1B54A32D192ED03)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_TWO = np.uint64(2)


@njit(cache=True, nogil=True)
def draw(key, row, receiver, salt):  # noqa: ANN001, ANN201
    """``network.draws`` for one copy: the uniform draw in [0, 1) of the copy of table row
    ``row`` to ``receiver`` (``salt`` 0: its loss, 1: its jitter)."""
    z = key + np.uint64(row) * _SPREAD_ROW + (np.uint64(receiver) * _TWO + np.uint64(salt)) * _SPREAD_COPY
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return float(z >> _S11) * 2.0**-53


@njit(cache=True, nogil=True)
def fates(senders, rows, key, fate, at, heard_by):  # noqa: ANN001, ANN201
    """``network.fates_numpy``: which copies of one broadcast (``senders``, their table
    ``rows``) will be heard, into ``heard_by`` (N, k); ``fate`` = (loss, the delay's jitter,
    the time the broadcast falls due, range); ``at`` the agents' positions when it was sent
    (empty: no range). Returns the copies lost and out of range."""
    loss, reach = fate[0], fate[3]
    n = heard_by.shape[0]
    k = senders.shape[0]
    ranged = at.shape[0] > 0
    lost = 0
    out = 0
    for r in range(n):
        for c in range(k):
            s = senders[c]
            ok = r != s
            if ok and ranged:
                dx, dy, dz = at[r, 0] - at[s, 0], at[r, 1] - at[s, 1], at[r, 2] - at[s, 2]
                if math.sqrt((dx * dx + dy * dy) + dz * dz) > reach:
                    out += 1
                    ok = False
            if ok and loss > 0.0 and draw(key, rows[c], r, 0) < loss:
                lost += 1
                ok = False
            heard_by[r, c] = ok
    return lost, out


@njit(cache=True, nogil=True)
def deliver(heard, senders, rows, key, fate, heard_by, t):  # noqa: ANN001, ANN201
    """``network.deliver_numpy``: the copies of one broadcast (``senders``, their table
    ``rows``) heard (``heard_by``, :func:`fates`) that have arrived by ``t`` replace older rows
    in ``heard`` (receiver, sender; a sender's rows are numbered in the order it sent them)."""
    jitter, due = fate[1], fate[2]
    n = heard.shape[0]
    k = senders.shape[0]
    if jitter == 0.0 and due > t + 1e-9:  # every copy arrives at once, later
        return
    for r in range(n):
        if jitter == 0.0:  # every copy heard has arrived (no branch to mispredict on them)
            for c in range(k):
                row = rows[c] if heard_by[r, c] else 0
                heard[r, senders[c]] = max(heard[r, senders[c]], row)
            continue
        for c in range(k):
            row = rows[c]
            if heard_by[r, c] and due + jitter * (2.0 * draw(key, row, r, 1) - 1.0) <= t + 1e-9:
                heard[r, senders[c]] = max(heard[r, senders[c]], row)


@njit(cache=True, nogil=True)
def compact_near(heard, idx, mark, table, t, at, radius, stale):  # noqa: ANN001, ANN201, PLR0913
    """``network.compact_near_numpy``, in one pass over the pairs: the table rows that flyers
    ``idx`` hold in ``heard`` (receiver, sender; 0: none), in the order first met, and each
    flyer's view of them (n, N: the position among those rows, -1: none, or a row too old to act
    on: its agent may be farther from it than both agents' stopping reach, ``stale`` = (max_accel,
    stopping reach) per agent; ``mark``, one per table row, all -1, is scratch, all -1 again on
    return), the ages at ``t`` of the rows held and their positions moved on by them at the
    velocity sent (``table`` = (time, position, velocity) per table row), and :func:`held_pairs`
    of flyers ``idx`` (at ``at``) within ``radius`` of those positions."""
    t_row, pos_row, vel_row = table
    max_accel, reach = stale
    n = idx.shape[0]
    n_all = heard.shape[1]
    room = min(n * n_all, mark.shape[0])
    live = np.empty(room, dtype=np.int64)
    age = np.empty(room)
    doubt = np.empty(room)
    moved = np.empty((room, 3))
    view = np.empty((n, n_all), dtype=np.int64)
    ks = np.empty(n * n_all, dtype=np.int64)
    js = np.empty(n * n_all + 1, dtype=np.int64)  # one more: the last candidate is written, then dropped
    rows = np.empty(n * n_all, dtype=np.int64)
    ds = np.empty(n * n_all)
    # A sender's column holds a few rows (most flyers the newest): its last one met and its
    # position among the rows held, before asking the scratch.
    last = np.zeros(n_all, dtype=np.int64)
    last_at = np.empty(n_all, dtype=np.int64)
    # The position of the row a flyer holds of each agent, by coordinate (contiguous, so the
    # distances to every agent are one vectorized pass; most flyers hold the same rows, so few
    # entries change from one flyer to the next); an agent it knows nothing of: infinitely far.
    now = np.full(n_all, -1, dtype=np.int64)
    px = np.full(n_all, np.inf)
    py = np.full(n_all, np.inf)
    pz = np.full(n_all, np.inf)
    d2 = np.empty(n_all)
    count = 0
    c = 0
    old = 0
    least = np.inf  # the shortest reach of a flyer
    for k in range(n):
        least = min(least, reach[idx[k]])
    wide = radius * radius * (1.0 + 1e-9)
    for k in range(n):
        own = idx[k]
        for j in range(n_all):
            r = heard[own, j]
            if r <= 0:
                m = -1
            elif r == last[j]:
                m = last_at[j]
            else:
                m = mark[r]
                if m < 0:
                    m = count
                    mark[r] = m
                    live[m] = r
                    age[m] = t - t_row[r]
                    doubt[m] = 0.5 * max_accel[j] * age[m] * age[m]  # network.belief_doubt
                    old += doubt[m] > least + reach[j]  # too old for some flyer
                    for e in range(3):
                        moved[m, e] = pos_row[r, e] + vel_row[r, e] * age[m]
                    count += 1
                last[j], last_at[j] = r, m
            view[k, j] = m
            if m != now[j]:
                now[j] = m
                if m < 0:
                    px[j], py[j], pz[j] = np.inf, np.inf, np.inf
                else:
                    px[j], py[j], pz[j] = moved[m, 0], moved[m, 1], moved[m, 2]
        ax, ay, az = at[k, 0], at[k, 1], at[k, 2]
        for j in range(n_all):
            dx, dy, dz = px[j] - ax, py[j] - ay, pz[j] - az
            d2[j] = (dx * dx + dy * dy) + dz * dz
        # The candidates (written at c whatever they are, kept by moving c on: no branch to
        # mispredict), then those within the radius, itself left out.
        first = c
        for j in range(n_all):
            js[c] = j
            c += d2[j] < wide
        kept = first
        for q in range(first, c):
            j = js[q]
            d = math.sqrt(d2[j])
            if d < radius and j != own:
                ks[kept], js[kept], rows[kept], ds[kept] = k, j, view[k, j], d
                kept += 1
        c = kept
    for m in range(count):
        mark[live[m]] = -1
    if old:  # rows too old to act on (rare: a sender long unheard) leave the views and pairs
        for k in range(n):
            own = idx[k]
            for j in range(n_all):
                m = view[k, j]
                if m >= 0 and doubt[m] > reach[own] + reach[j]:
                    view[k, j] = -1
        kept = 0
        for p in range(c):
            if view[ks[p], js[p]] >= 0:
                ks[kept], js[kept], rows[kept], ds[kept] = ks[p], js[p], rows[p], ds[p]
                kept += 1
        c = kept
    pairs = (ks[:c].copy(), js[:c].copy(), rows[:c].copy(), ds[:c].copy())
    return live[:count].copy(), view, age[:count].copy(), moved[:count].copy(), pairs
