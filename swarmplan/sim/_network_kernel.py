"""Compiled phases of the network of a world with ``comms`` (``swarmplan.sim.network``), for
swarms. What every receiver holds of every sender is kept sparse: each sender's base row (the
newest state delivered to all that took it) and the few receivers holding another (a copy lost,
out of range, or arrived ahead of its broadcast), so a delivery writes the copies missed, not
one entry per receiver, and a flyer's view is the base rows changed at its own entries. The
losses of a broadcast are drawn in one vectorized pass per sender. Each function gives its
numpy counterpart's answers on the (receiver, sender) matrix, with the same arithmetic in the
same order (tests/test_network_kernel.py holds them to the same answers)."""

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
    js = np.empty(n * n_all + 1, dtype=np.int64)  # one more: the last candidate is written, then dropped
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


@njit(cache=True, nogil=True)
def oldest_ages(k, rows, d, age, reach, n):  # noqa: ANN001, ANN201
    """``network_passes.oldest_ages``: per flyer row of ``n``, the largest ``age`` of the rows of the
    pairs (flyer row ``k``, table row ``rows``, distance ``d``) closer than ``reach``; nan for
    a flyer with none (a nan age wins, as in ``np.maximum``)."""
    out = np.full(n, -np.inf)
    for p in range(k.shape[0]):
        a = age[rows[p]] if d[p] < reach else -np.inf
        f = k[p]
        if a > out[f] or a != a:
            out[f] = a
    for f in range(n):
        if not math.isfinite(out[f]):
            out[f] = np.nan
    return out


@njit(cache=True, nogil=True)
def belief_table(live, age, moved, table, truth, now):  # noqa: ANN001, ANN201
    """``network_passes.belief_table_numpy`` in one pass over the rows: the rows held, then the
    true states of agents ``truth``."""
    vel_row, acc_row, parked_row, to_go_row, agent_row, yields_row = table
    pos, vel, parked, to_go, yields = now
    n_live = live.shape[0]
    m_all = n_live + truth.shape[0]
    b_pos, b_vel = np.empty((m_all, 3)), np.empty((m_all, 3))
    e_pos, e_vel = np.empty((m_all, 3)), np.empty((m_all, 3))
    b_parked, b_yields = np.empty(m_all, dtype=np.bool_), np.empty(m_all, dtype=np.bool_)
    b_to_go, b_age, b_agent = np.empty(m_all), np.empty(m_all), np.empty(m_all, dtype=np.int64)
    for m in range(n_live):
        r, a = live[m], age[m]
        for c in range(3):
            b_pos[m, c] = moved[m, c]
            b_vel[m, c] = vel_row[r, c]
            e_pos[m, c] = moved[m, c] + 0.5 * acc_row[r, c] * (a * a)
            e_vel[m, c] = vel_row[r, c] + acc_row[r, c] * a
        b_parked[m], b_to_go[m], b_age[m] = parked_row[r], to_go_row[r], a
        b_agent[m], b_yields[m] = agent_row[r], yields_row[r]
    for q in range(truth.shape[0]):
        i, m = truth[q], n_live + q
        for c in range(3):
            b_pos[m, c] = e_pos[m, c] = pos[i, c]
            b_vel[m, c] = e_vel[m, c] = vel[i, c]
        b_parked[m], b_to_go[m], b_age[m], b_agent[m], b_yields[m] = parked[i], to_go[i], 0.0, i, yields[i]
    return b_pos, b_vel, b_parked, b_to_go, b_age, b_agent, e_pos, e_vel, b_yields


_SPREAD_ROW = np.uint64(0x9E3779B97F4A7C15)
_SPREAD_COPY = np.uint64(0xD1B54A32D192ED03)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_TWO = np.uint64(2)


@njit(cache=True, nogil=True)
def draw(key, row, receiver, salt):  # noqa: ANN001, ANN201
    """``network_passes.draws`` for one copy: the uniform draw in [0, 1) of the copy of table row
    ``row`` to ``receiver`` (``salt`` 0: its loss, 1: its jitter)."""
    z = key + np.uint64(row) * _SPREAD_ROW + (np.uint64(receiver) * _TWO + np.uint64(salt)) * _SPREAD_COPY
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return float(z >> _S11) * 2.0**-53


@njit(cache=True, nogil=True)
def misses(senders, rows, key, fate, at, n):  # noqa: ANN001, ANN201
    """``network_passes.fates_numpy`` kept sparse: for each copy c of one broadcast (``senders``, their
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
    gone = np.zeros(n, dtype=np.uint8)  # per receiver: 1 when it does not take the copy
    far = np.zeros(n, dtype=np.uint8)
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
            far[s] = 0
        if loss > 0.0:  # draw(key, row, r, 0) for every receiver r, in one vectorized pass
            z0 = key + np.uint64(row) * _SPREAD_ROW
            for r in range(n):
                z = z0 + np.uint64(r) * step
                z = (z ^ (z >> _S30)) * _MIX1
                z = (z ^ (z >> _S27)) * _MIX2
                z = z ^ (z >> _S31)
                gone[r] = (z >> _S11) < below
        else:
            gone[:] = 0
        gone[s] = 1  # its own copy: neither lost nor out of range
        if ranged:
            for r in range(n):
                out += far[r]
                lost += gone[r] & (1 - far[r])
                gone[r] |= far[r]
            lost -= 1
        else:
            for r in range(n):
                lost += gone[r]
            lost -= 1
        for r in range(n):  # written whatever it is, kept by moving c on (no branch to mispredict)
            miss[c] = r
            c += gone[r]
    ptr[k] = c
    return ptr, miss[:c].copy(), lost, out


@njit(cache=True, nogil=True)
def deliver(book, spare, senders, rows, key, fate, ptr, miss, t):  # noqa: ANN001, ANN201, PLR0913
    """``network_passes.deliver_numpy`` on the sparse book of what every receiver holds (``book`` =
    (base, start, holders, values): receiver r holds of sender s the row ``values[e]`` when it
    is ``holders[e]`` for some e in ``start[s]:start[s + 1]`` (ascending), else the sender's
    base row ``base[s]``; a receiver holds an entry of its own exactly when its row is not the
    base): the copies of one broadcast (``senders``, ascending, their table ``rows``) taken by
    every receiver but ``miss[ptr[c]:ptr[c + 1]]`` (:func:`misses`) that have arrived by ``t``.
    When every copy has arrived, each sender's base becomes its row and only the receivers that
    missed it, or hold a newer row (arrived ahead of its broadcast), keep entries of their own:
    a merge of two short lists per sender, not one write per receiver. The new lists are
    written to ``spare`` = (start, holders, values), with room for those held and those of the
    copies missed (of every receiver while copies are still on their way: the merge writes at
    most one entry past those it keeps, within that room); returns whether they were written
    (``base`` changes in place)."""
    base, start, holders, values = book
    new_start, new_holders, new_values = spare
    jitter, due = fate[1], fate[2]
    n = base.shape[0]
    k = senders.shape[0]
    if jitter == 0.0 and due > t + 1e-9:  # every copy arrives at once, later
        return False
    partial = due + jitter > t + 1e-9  # some copies are still on their way
    m = 0
    c = 0
    for s in range(n):  # every sender's list in turn, in one pass over the book
        new_start[s] = m
        e, e_end = start[s], start[s + 1]
        if c == k or senders[c] != s:  # not in this broadcast
            for f in range(e, e_end):
                new_holders[m], new_values[m] = holders[f], values[f]
                m += 1
            continue
        row, q, q_end = rows[c], ptr[c], ptr[c + 1]
        c += 1
        if partial:  # every receiver in turn: those whose copy has arrived take it
            for r in range(n):
                own = e < e_end and holders[e] == r
                v = values[e] if own else base[s]
                e += own
                missed = q < q_end and miss[q] == r
                q += missed
                if not missed and row > v and due + jitter * (2.0 * draw(key, row, r, 1) - 1.0) <= t + 1e-9:
                    v = row
                if v != base[s]:
                    new_holders[m], new_values[m] = r, v
                    m += 1
            continue
        # every copy has arrived: the row is the base but for those that missed it (and keep
        # what they hold), and those holding a newer row (arrived ahead of its broadcast); each
        # step written whatever it is, kept by moving m on (no branch to mispredict)
        base_s = base[s]
        while q < q_end or e < e_end:
            rq = miss[q] if q < q_end else n
            re = holders[e] if e < e_end else n
            held = values[e] if e < e_end else 0
            missed = rq <= re  # (then rq is a receiver: re is n only past the holders)
            both = rq == re
            new_holders[m] = rq if missed else re
            new_values[m] = (held if both else base_s) if missed else held
            m += missed or held > row
            q += missed
            e += both or not missed
        base[s] = row
    new_start[n] = m
    return True


@njit(cache=True, nogil=True)
def compact_near(book, idx, mark, table, t, at, radius, stale, buffers):  # noqa: ANN001, ANN201, PLR0912, PLR0913, PLR0915
    """``network_passes.compact_near_numpy`` on the sparse book (:func:`deliver`): the table rows that
    flyers ``idx`` hold (each sender's base row held by any flyer, in sender order, then the
    rows held as flyers' own entries, in the order first met), each flyer's view of them (n, N:
    the position among those rows, -1: none, or a row too old to act on: its agent may be
    farther from it than both agents' stopping reach, ``stale`` = (max_accel, stopping reach)
    per agent; ``mark``, one per table row, all -1, is scratch, all -1 again on return), the
    ages at ``t`` of the rows held and their positions moved on by them at the velocity sent
    (``table`` = (time, position, velocity) per table row), and the pairs (flyer row k, agent j,
    row, distance) of flyers ``idx`` (at ``at``) within ``radius`` of those positions, in (k, j)
    order. A flyer's view is its senders' base rows but for its own entries: one copy of a row
    of N and a few changes per flyer. ``buffers`` = (views (at least n, N), flyer rows, agents,
    rows, distances (each at least n N, the agents one more)): buffers the views and pairs are
    written to and returned from (a run's, reused from step to step: memory freshly allocated
    costs its first writes more than the pass), or empty ones: new arrays."""
    base, start, holders, values = book
    t_row, pos_row, vel_row = table
    max_accel, reach = stale
    n = idx.shape[0]
    n_all = base.shape[0]
    # Each flyer's own entries (sender, row), flyer by flyer (from the senders' lists of holders).
    flyer = np.full(n_all, -1, dtype=np.int64)
    for k in range(n):
        flyer[idx[k]] = k
    per = np.zeros(n + 1, dtype=np.int64)
    own_entries = np.zeros(n_all, dtype=np.int64)  # per sender: flyers holding an entry of their own
    for s in range(n_all):
        for e in range(start[s], start[s + 1]):
            k = flyer[holders[e]]
            if k >= 0:
                per[k + 1] += 1
                own_entries[s] += 1
    for k in range(n):
        per[k + 1] += per[k]
    fill = per[:n].copy()
    e_s = np.empty(per[n], dtype=np.int64)
    e_row = np.empty(per[n], dtype=np.int64)
    for s in range(n_all):
        for e in range(start[s], start[s + 1]):
            k = flyer[holders[e]]
            if k >= 0:
                e_s[fill[k]], e_row[fill[k]] = s, values[e]
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
        if own_entries[s] < n and base[s] > 0:  # some flyer holds the base row (0: none)
            r = base[s]
            m = count_live
            of_base[s] = m
            live[m] = r
            age[m] = t - t_row[r]
            doubt[m] = 0.5 * max_accel[s] * age[m] * age[m]  # network_passes.belief_doubt
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
    views, ks, js, rows, ds = buffers
    if views.shape[0] < n or ks.shape[0] < n * n_all:
        views = np.empty((n, n_all), dtype=np.int64)
        ks = np.empty(n * n_all, dtype=np.int64)
        js = np.empty(n * n_all + 1, dtype=np.int64)  # one more: the last candidate is written, then dropped
        rows = np.empty(n * n_all, dtype=np.int64)
        ds = np.empty(n * n_all)
    view = views[:n]
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
    # (slices, not copies: they live as long as the beliefs, one step, and the buffers)
    return live[:count_live], view, age[:count_live], moved[:count_live], (ks[:c], js[:c], rows[:c], ds[:c])
