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
def misses(senders, rows, key, fate, at, n):  # noqa: ANN001, ANN201
    """``network.fates_numpy`` kept sparse: for each copy c of one broadcast (``senders``, their
    table ``rows``), the receivers that do not take it (its sender, those out of range, those
    that lose it), ascending, ``miss[ptr[c]:ptr[c + 1]]``; ``fate`` = (loss, the delay's jitter,
    the time the broadcast falls due, range), ``at`` the agents' positions when it was sent
    (empty: no range), ``n`` the agents. Returns (ptr, miss, copies lost, copies out of range).
    A copy is lost when its draw (:func:`draw`) is below the loss: its 53 bits below the loss
    times 2^53, the same test in integers (the scaling is exact)."""
    loss, reach = fate[0], fate[3]
    k = senders.shape[0]
    ranged = at.shape[0] > 0
    ptr = np.empty(k + 1, dtype=np.int64)
    miss = np.empty(n * k + 1, dtype=np.int64)  # one more: the last receiver is written, then dropped
    below = np.uint64(math.ceil(loss * 2.0**53)) if loss > 0.0 else np.uint64(0)
    drop = np.zeros(n, dtype=np.bool_)
    far = np.zeros(n, dtype=np.bool_)
    step = _TWO * _SPREAD_COPY
    c = 0
    lost = 0
    out = 0
    for q in range(k):
        s, row = senders[q], rows[q]
        ptr[q] = c
        if ranged:
            for r in range(n):
                dx, dy, dz = at[r, 0] - at[s, 0], at[r, 1] - at[s, 1], at[r, 2] - at[s, 2]
                far[r] = math.sqrt((dx * dx + dy * dy) + dz * dz) > reach
            far[s] = False
        if loss > 0.0:  # draw(key, row, r, 0) for every receiver r, in one vectorized pass
            z0 = key + np.uint64(row) * _SPREAD_ROW
            for r in range(n):
                z = z0 + np.uint64(r) * step
                z = (z ^ (z >> _S30)) * _MIX1
                z = (z ^ (z >> _S27)) * _MIX2
                z = z ^ (z >> _S31)
                drop[r] = (z >> _S11) < below
        for r in range(n):
            gone = far[r]
            lose = drop[r] and not gone
            miss[c] = r  # written whatever it is, kept by moving c on (no branch to mispredict)
            c += gone or lose or r == s
            out += gone
            lost += lose and r != s
    ptr[k] = c
    return ptr, miss[:c].copy(), lost, out


@njit(cache=True, nogil=True, inline="always")
def held(heard, stamp, gen, base, r, s):  # noqa: ANN001, ANN201
    """The table row receiver ``r`` holds of sender ``s`` (0: none): its own entry while stamped
    with the sender's generation, else the sender's base row (``heard`` and ``stamp`` by
    sender, then receiver: a sender's entries are one row of memory)."""
    return heard[s, r] if stamp[s, r] == gen[s] else base[s]


@njit(cache=True, nogil=True)
def take_copy(book, r, s, row):  # noqa: ANN001, ANN201
    """Receiver ``r`` takes sender ``s``'s table ``row`` (a copy arrived ahead of the rest of its
    broadcast) unless it holds a newer one."""
    heard, stamp, gen, base, count, holders = book
    if row <= held(heard, stamp, gen, base, r, s):
        return
    if stamp[s, r] != gen[s]:
        holders[s, count[s]] = r
        count[s] += 1
        stamp[s, r] = gen[s]
    heard[s, r] = row


@njit(cache=True, nogil=True)
def deliver(book, senders, rows, key, fate, ptr, miss, t, scratch):  # noqa: ANN001, ANN201, PLR0913
    """``network.deliver_numpy`` on the sparse book of what every receiver holds (``book`` =
    (heard, stamp, gen, base, count, holders): receiver r holds of sender s its own entry
    ``heard[s, r]`` while ``stamp[s, r] == gen[s]`` (r is then one of ``holders[s, :count[s]]``),
    else the sender's base row ``base[s]``): the copies of one broadcast (``senders``, their
    table ``rows``) taken by every receiver but ``miss[ptr[c]:ptr[c + 1]]`` (:func:`misses`)
    that have arrived by ``t``. When every copy has arrived, each sender's base becomes its row
    and only the receivers that missed it, or hold a newer row, keep entries of their own:
    ``O(misses)``, not one write per receiver. ``scratch`` (N,) all False, and again on return."""
    heard, stamp, gen, base, count, holders = book
    jitter, due = fate[1], fate[2]
    n = heard.shape[0]
    k = senders.shape[0]
    if jitter == 0.0 and due > t + 1e-9:  # every copy arrives at once, later
        return
    if due + jitter > t + 1e-9:  # some copies are still on their way: those arrived, one by one
        for c in range(k):
            s, row, q = senders[c], rows[c], ptr[c]
            for r in range(n):
                if q < ptr[c + 1] and miss[q] == r:
                    q += 1
                    continue
                if due + jitter * (2.0 * draw(key, row, r, 1) - 1.0) <= t + 1e-9:
                    take_copy(book, r, s, row)
        return
    keep = np.empty(n, dtype=np.int64)
    kept = np.empty(n, dtype=np.int64)
    for c in range(k):
        s, row = senders[c], rows[c]
        m = 0
        for q in range(ptr[c], ptr[c + 1]):  # those that missed it keep what they hold
            r = miss[q]
            scratch[r] = True
            keep[m], kept[m] = r, held(heard, stamp, gen, base, r, s)
            m += 1
        for e in range(count[s]):  # those holding a newer row (arrived ahead) keep it
            r = holders[s, e]
            if not scratch[r] and heard[s, r] > row:
                keep[m], kept[m] = r, heard[s, r]
                m += 1
        for q in range(ptr[c], ptr[c + 1]):
            scratch[miss[q]] = False
        gen[s] += 1
        base[s] = row
        for e in range(m):
            r = keep[e]
            heard[s, r], stamp[s, r], holders[s, e] = kept[e], gen[s], r
        count[s] = m


@njit(cache=True, nogil=True)
def compact_near(book, idx, mark, table, t, at, radius, stale):  # noqa: ANN001, ANN201, PLR0912, PLR0913, PLR0915
    """``network.compact_near_numpy`` on the sparse book (:func:`deliver`): the table rows that
    flyers ``idx`` hold (each sender's base row held by any flyer, in sender order, then the
    rows held as flyers' own entries, in the order first met), each flyer's view of them (n, N:
    the position among those rows, -1: none, or a row too old to act on: its agent may be
    farther from it than both agents' stopping reach, ``stale`` = (max_accel, stopping reach)
    per agent; ``mark``, one per table row, all -1, is scratch, all -1 again on return), the
    ages at ``t`` of the rows held and their positions moved on by them at the velocity sent
    (``table`` = (time, position, velocity) per table row), and the pairs (flyer row k, agent j,
    row, distance) of flyers ``idx`` (at ``at``) within ``radius`` of those positions, in (k, j)
    order. A flyer's view is its senders' base rows but for its own entries: one copy of a row
    of N and a few changes per flyer."""
    heard, stamp, gen, base, count, holders = book
    t_row, pos_row, vel_row = table
    max_accel, reach = stale
    n = idx.shape[0]
    n_all = heard.shape[0]
    # Each flyer's own entries (sender, row), flyer by flyer (from the senders' lists of holders).
    flyer = np.full(n_all, -1, dtype=np.int64)
    for k in range(n):
        flyer[idx[k]] = k
    per = np.zeros(n + 1, dtype=np.int64)
    own_entries = np.zeros(n_all, dtype=np.int64)  # per sender: flyers holding an entry of their own
    for s in range(n_all):
        for e in range(count[s]):
            k = flyer[holders[s, e]]
            if k >= 0:
                per[k + 1] += 1
                own_entries[s] += 1
    for k in range(n):
        per[k + 1] += per[k]
    fill = per[:n].copy()
    e_s = np.empty(per[n], dtype=np.int64)
    e_row = np.empty(per[n], dtype=np.int64)
    for s in range(n_all):
        for e in range(count[s]):
            r = holders[s, e]
            k = flyer[r]
            if k >= 0:
                e_s[fill[k]], e_row[fill[k]] = s, heard[s, r]
                fill[k] += 1
    # The rows held: each base row some flyer holds, then the flyers' own rows.
    room = n_all + per[n]
    live = np.empty(room, dtype=np.int64)
    age = np.empty(room)
    doubt = np.empty(room)
    moved = np.empty((room, 3))
    of_base = np.full(n_all, -1, dtype=np.int64)
    count_live = 0
    least = np.inf  # the shortest reach of a flyer
    for k in range(n):
        least = min(least, reach[idx[k]])
    old = 0
    for s in range(n_all):
        if own_entries[s] < n:  # some flyer holds the base row
            r = base[s]
            m = count_live
            of_base[s] = m
            live[m] = r
            age[m] = t - t_row[r]
            doubt[m] = 0.5 * max_accel[s] * age[m] * age[m]  # network.belief_doubt
            old += doubt[m] > least + reach[s]
            for c in range(3):
                moved[m, c] = pos_row[r, c] + vel_row[r, c] * age[m]
            count_live += 1
    n_base = count_live
    e_at = np.empty(per[n], dtype=np.int64)  # each own entry's position among the rows held
    for q in range(per[n]):
        r = e_row[q]
        if r <= 0:
            e_at[q] = -1
            continue
        m = mark[r]
        if m < 0:
            m = count_live
            mark[r] = m
            live[m] = r
            s = e_s[q]
            age[m] = t - t_row[r]
            doubt[m] = 0.5 * max_accel[s] * age[m] * age[m]
            old += doubt[m] > least + reach[s]
            for c in range(3):
                moved[m, c] = pos_row[r, c] + vel_row[r, c] * age[m]
            count_live += 1
        e_at[q] = m
    for m in range(n_base, count_live):
        mark[live[m]] = -1
    # Each flyer's view, and the pairs within the radius: the base positions by coordinate,
    # changed by the flyer's own entries and changed back.
    view = np.empty((n, n_all), dtype=np.int64)
    px = np.empty(n_all)
    py = np.empty(n_all)
    pz = np.empty(n_all)
    for s in range(n_all):
        m = of_base[s]
        if m < 0:
            px[s], py[s], pz[s] = np.inf, np.inf, np.inf
        else:
            px[s], py[s], pz[s] = moved[m, 0], moved[m, 1], moved[m, 2]
    d2 = np.empty(n_all)
    ks = np.empty(n * n_all, dtype=np.int64)
    js = np.empty(n * n_all + 1, dtype=np.int64)  # one more: the last candidate is written, then dropped
    rows = np.empty(n * n_all, dtype=np.int64)
    ds = np.empty(n * n_all)
    c = 0
    wide = radius * radius * (1.0 + 1e-9)
    for k in range(n):
        own = idx[k]
        view[k, :] = of_base
        for q in range(per[k], per[k + 1]):
            s, m = e_s[q], e_at[q]
            view[k, s] = m
            if m < 0:
                px[s], py[s], pz[s] = np.inf, np.inf, np.inf
            else:
                px[s], py[s], pz[s] = moved[m, 0], moved[m, 1], moved[m, 2]
        ax, ay, az = at[k, 0], at[k, 1], at[k, 2]
        for j in range(n_all):
            dx, dy, dz = px[j] - ax, py[j] - ay, pz[j] - az
            d2[j] = (dx * dx + dy * dy) + dz * dz
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
        for q in range(per[k], per[k + 1]):  # back to the base positions
            s = e_s[q]
            m = of_base[s]
            if m < 0:
                px[s], py[s], pz[s] = np.inf, np.inf, np.inf
            else:
                px[s], py[s], pz[s] = moved[m, 0], moved[m, 1], moved[m, 2]
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
    return live[:count_live].copy(), view, age[:count_live].copy(), moved[:count_live].copy(), pairs
