"""The network's compiled passes (swarm worlds, on the sparse book of what each receiver holds)
give the numpy answers of small worlds (on the (receiver, sender) matrix): the pairs each flyer
believes within a radius, the fate of each copy of a broadcast, the rows each flyer holds, and
the copies delivered."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.core import Mode, SwarmState
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim import network
from swarmplan.sim.network import Beliefs, Network
from swarmplan.sim.network_book import holdings
from swarmplan.sim.network_passes import (
    belief_table_numpy,
    compact_near_numpy,
    deliver_numpy,
    draws,
    fates_numpy,
    held_pairs,
    oldest_ages,
)
from swarmplan.world.comms import Comms


def _beliefs(rng: np.random.Generator, n: int, n_all: int) -> Beliefs:
    rows = 3 * n_all
    pos = rng.uniform(0.0, 20.0, (rows, 3))
    idx = np.sort(rng.choice(n_all, n, replace=False))
    view = rng.integers(0, rows, (n, n_all))
    view[rng.random((n, n_all)) < 0.2] = -1
    view[np.arange(n), idx] = rng.integers(0, rows, n)
    at = pos[view[np.arange(n), idx]]
    z = np.zeros(rows)
    return Beliefs(idx, at, pos, pos * 0, z > 0, z, z, np.arange(rows) % n_all, view, pos, pos * 0, z > 0)


def test_held_pairs_compiled_and_numpy_agree():
    kernel = kernel_module("swarmplan.sim._network_kernel")
    for seed in range(4):
        rng = np.random.default_rng(seed)
        b = _beliefs(rng, 20, 60)
        own = b.idx.astype(np.int64)
        for radius in (0.0, 3.0, 7.5, 100.0):
            want = held_pairs(b.view, b.pos, b.at, own, radius)
            got = kernel.held_pairs(b.view, b.pos, b.at, own, radius)
            for w, g in zip(want, got, strict=True):
                np.testing.assert_array_equal(w, g)
            assert (want[1] != b.idx[want[0]]).all() and (want[3] < radius).all()
        assert len(held_pairs(b.view, b.pos, b.at, own, 100.0)[0]) == int((b.view >= 0).sum()) - 20


def test_oldest_ages_compiled_and_numpy_agree():
    """Per flyer, the oldest state among its pairs within reach: the same on both paths, nan
    for a flyer with none within reach."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    for seed in range(4):
        rng = np.random.default_rng(seed)
        b = _beliefs(rng, 20, 60)
        b.age[:] = rng.uniform(0.0, 0.6, len(b.age))
        k, _, rows, d = held_pairs(b.view, b.pos, b.at, b.idx.astype(np.int64), 8.0)
        for reach in (0.0, 2.0, 5.0, 100.0):
            want = oldest_ages(k, rows, d, b.age, reach, 20)
            np.testing.assert_array_equal(want, kernel.oldest_ages(k, rows, d, b.age, reach, 20))
            for f in range(20):
                near = (k == f) & (d < reach)
                assert want[f] == b.age[rows[near]].max() if near.any() else np.isnan(want[f])


def test_belief_table_compiled_and_numpy_agree():
    """The believed states (the rows held moved on, then the true states): the same bits on both
    paths."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(7)
    size, n = 90, 30
    table = (rng.normal(0.0, 3.0, (size, 3)), rng.normal(0.0, 4.0, (size, 3)), rng.random(size) < 0.3,
             rng.uniform(0.0, 50.0, size), rng.integers(0, n, size), rng.random(size) < 0.2)  # fmt: skip
    now = (rng.uniform(0.0, 10.0, (n, 3)), rng.normal(0.0, 3.0, (n, 3)), rng.random(n) < 0.3,
           rng.uniform(0.0, 50.0, n), rng.random(n) < 0.2)  # fmt: skip
    some = np.sort(rng.choice(n, 12, replace=False))
    for held, truth in ((25, np.arange(n)), (40, some), (0, np.arange(3))):
        live = rng.choice(np.arange(1, size), held, replace=False).astype(np.int64)
        age, moved = rng.uniform(0.0, 0.7, held), rng.uniform(0.0, 10.0, (held, 3))
        want = belief_table_numpy(live, age, moved, table, truth.astype(np.int64), now)
        got = kernel.belief_table(live, age, moved, table, truth.astype(np.int64), now)
        for w, g in zip(want, got, strict=True):
            assert w.dtype == g.dtype
            np.testing.assert_array_equal(w, g)


def test_copy_draws_compiled_and_numpy_agree():
    """The counter-based draws: the same bits on both paths, uniform, and each copy's own."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    key = np.uint64(0xDEADBEEF12345678)
    rows, receivers = np.arange(1, 41), np.arange(25)
    for salt in (0, 1):
        u = draws(key, rows[None, :], receivers[:, None], salt)
        got = np.array([[kernel.draw(key, int(row), int(r), salt) for row in rows] for r in receivers])
        np.testing.assert_array_equal(u, got)
        assert ((0.0 <= u) & (u < 1.0)).all()
        assert abs(u.mean() - 0.5) < 4 * math.sqrt(1 / 12 / u.size)
        assert len(np.unique(u)) == u.size
    assert not np.array_equal(draws(key, rows, 3, 0), draws(key, rows, 3, 1))
    assert not np.array_equal(draws(key, rows, 3, 0), draws(key + np.uint64(1), rows, 3, 0))


def _dense(book: tuple) -> np.ndarray:
    """The (receiver, sender) matrix of a sparse book."""
    base, start, holders, values = book
    heard = np.repeat(base[:, None], len(base), axis=1)
    heard[np.repeat(np.arange(len(base)), np.diff(start)), holders[: start[-1]]] = values[: start[-1]]
    return heard.T


def test_delivery_of_one_broadcast_compiled_and_numpy_agree():
    """Every combination of loss, jitter and range, asked at several times: the copies missed
    are exactly those not heard, with the same counts; the sparse book delivered holds the rows
    of the matrix delivered; a copy never reaches its own sender, nor a receiver out of range."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(3)
    n, k = 25, 9
    senders = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    rows = np.arange(100, 100 + k, dtype=np.int64)
    at = rng.uniform(0, 30, (n, 3))
    key = np.uint64(77)
    cases = [(0.0, 0.0, False), (0.3, 0.0, True), (0.0, 0.0, True), (0.2, 0.05, False), (0.2, 0.05, True)]
    for loss, jitter, ranged in cases:
        fate = (loss, jitter, 1.1, 20.0 if ranged else math.inf)
        where = at if ranged else np.zeros((0, 3))
        start = rng.integers(0, 100, (n, n)).astype(np.int64)
        start[rng.random((n, n)) < 0.3] = 0
        a = start.copy()
        book = holdings(start, start[0])
        heard_by = np.empty((n, k), dtype=bool)
        lost, out = fates_numpy(senders, rows, key, fate, where, heard_by)
        ptr, miss, lost_b, out_b = kernel.misses(senders, rows, key, fate, where, n)
        assert (lost, out) == (lost_b, out_b)
        for c in range(k):
            np.testing.assert_array_equal(miss[ptr[c] : ptr[c + 1]], np.flatnonzero(~heard_by[:, c]))
        for t in (1.04, 1.08, 1.1, 1.13, 1.2):
            deliver_numpy(a, senders, rows, key, fate, heard_by, t)
            base = book[0]
            room = int(book[1][-1]) + n * k
            spare = (
                np.empty(n + 1, dtype=np.int64),
                np.empty(room, dtype=np.int64),
                np.empty(room, dtype=np.int64),
            )
            if kernel.deliver(book, spare, senders, rows, key, fate, ptr, miss, t):
                book = (base, *spare)
            np.testing.assert_array_equal(a, _dense(book))
            # a receiver holds an entry of its own exactly when its row is not its sender's base
            base, first = book[:2]
            assert int(first[-1]) == int((a != base[None, :]).sum())
            if t == 1.04 and jitter == 0.0:
                assert (a == start).all()  # nothing before it falls due
        changed = a != start
        assert not changed[senders, senders].any()
        if ranged:
            d = np.linalg.norm(at[:, None] - at[None, senders], axis=-1)
            assert not (changed[:, senders] & (d > 20.0)).any()
        # Every copy has arrived by 1.2 s (due 1.1 s, jitter 0.05 s); those heard and newer changed.
        newer = start[:, senders] < rows[None, :]
        assert int(changed.sum()) == int((heard_by & newer).sum())
        assert int(heard_by.sum()) == n * k - k - lost - out
        assert (lost > 0) == (loss > 0) and (out > 0) == ranged


def _canonical(live, view, age, moved, pairs):
    """The compaction's answers by table row (its own numbering of the rows held set aside)."""
    k, j, rows, d = pairs
    order = np.argsort(live)
    return (live[order], np.where(view >= 0, live[view], -1), age[order], moved[order],
            (k, j, live[rows], d))  # fmt: skip


def test_compaction_compiled_and_numpy_agree():
    """The rows held, each flyer's view of them, their ages and positions moved on, and the
    pairs within a radius: the same on the sparse book as on the matrix (by table row, the
    numbering of the rows held aside), written to new arrays or to buffers used again (left
    dirty by the call before); the compiled scratch is left as found."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(4)
    # Each sender's rows its own (row 1 + j + 40 u: the u-th state sent by agent j).
    heard = (1 + np.arange(40)[None, :] + 40 * rng.integers(0, 6, (40, 40))).astype(np.int64)
    heard[rng.random((40, 40)) < 0.3] = 0
    np.fill_diagonal(heard, 0)
    idx = np.sort(rng.choice(40, 15, replace=False)).astype(np.int64)
    mark = np.full(260, -1, dtype=np.int64)
    t_row = np.sort(rng.uniform(0.0, 2.0, 260))
    table = (t_row, rng.uniform(0.0, 10.0, (260, 3)), rng.normal(0.0, 2.0, (260, 3)))
    at = rng.uniform(0.0, 10.0, (15, 3))
    never = (np.full(40, 2.0), np.full(40, np.inf))  # no row too old
    stale = (rng.uniform(1.0, 5.0, 40), rng.uniform(0.5, 3.0, 40))
    none = np.empty(0, dtype=np.int64)
    fresh = (np.empty((0, 40), dtype=np.int64), none, none, none, np.empty(0))
    size = 40 * 40
    dirty = np.full(size + 1, 7, dtype=np.int64)
    used = (np.full((40, 40), 7, dtype=np.int64), dirty[:size].copy(), dirty, dirty[:size].copy(),
            np.full(size, 7.0))  # fmt: skip
    # about the most common row, the newest, and a row no flyer holds
    for base in (heard[idx[0]], heard.max(axis=0), 1 + np.arange(40) + 40 * 7):
        book = holdings(heard, base)
        for radius in (0.0, 2.5, 6.0, 100.0):
            for old in (never, stale):
                want = _canonical(*compact_near_numpy(heard, idx, mark, table, 2.5, at, radius, old))
                for buffers in (fresh, used):
                    args = (book, idx, mark, table, 2.5, at, radius, old, buffers)
                    got = _canonical(*kernel.compact_near(*args))
                    for w, g in zip([*want[:4], *want[4]], [*got[:4], *got[4]], strict=True):
                        np.testing.assert_array_equal(w, g)
                    assert (mark == -1).all()
    # A row is left out of a flyer's view exactly when its agent may be farther from it than
    # both agents' stopping reach.
    live, view, age, _, _ = compact_near_numpy(heard, idx, mark, table, 2.5, at, 100.0, stale)
    held = heard[idx]
    kk, jj = np.nonzero(held > 0)
    row = np.searchsorted(np.sort(live), held[kk, jj])
    age_of = (2.5 - table[0][np.sort(live)])[row]
    too_old = 0.5 * stale[0][jj] * age_of**2 > stale[1][idx[kk]] + stale[1][jj]
    assert too_old.any() and not too_old.all()
    np.testing.assert_array_equal(view[kk, jj] == -1, too_old)
    live, view, age, moved, (k, j, rows, d) = compact_near_numpy(
        heard, idx, mark, table, 2.5, at, 100.0, never
    )
    np.testing.assert_array_equal(live[view[held > 0]], held[held > 0])
    assert (view[held == 0] == -1).all() and len(np.unique(live)) == len(live)
    flat = held.ravel()
    first = [int(np.flatnonzero(flat == r)[0]) for r in live]
    assert first == sorted(first)  # in the order first met, flyer by flyer
    np.testing.assert_allclose(age, 2.5 - table[0][live])
    np.testing.assert_allclose(moved, table[1][live] + table[2][live] * age[:, None])
    # Every row held by a flyer other than its own, with the exact distances (radius 100).
    assert len(k) == int((held > 0).sum())
    np.testing.assert_allclose(d, np.linalg.norm(moved[rows] - at[k], axis=1))


def _networks(n: int, comms: Comms) -> tuple[Network, Network]:
    """Two networks of ``n`` agents: the matrix (numpy), and the sparse book (compiled)."""
    made = []
    for compiled in (False, True):
        network_use = network.use_compiled
        network.use_compiled = lambda n, fixed_wings=False, c=compiled: c
        try:
            made.append(Network(comms, None, np.full(n, 5.0), np.full(n, 3.0), 0.05))
        finally:
            network.use_compiled = network_use
    return made[0], made[1]


@pytest.mark.parametrize(
    "comms",
    [
        Comms(20.0, 0.1, 0.0, 0.1),
        Comms(20.0, 0.1, 0.08, 0.2),
        Comms(20.0, 0.1, 0.05, 0.2, 30.0),
        Comms(10.0, 0.0, 0.0, 0.3, 25.0),
        Comms(20.0, 0.2, 0.0, 0.0, 30.0),
    ],  # fmt: skip
)
def test_delivery_compiled_and_numpy_agree(comms):
    """Random broadcasts with jitter, losses and range, delivered step by step on the matrix and
    on the sparse book: the same rows heard at every step, the same counts, and the same
    beliefs of the flyers (by table row) with the same pairs near them."""
    rng = np.random.default_rng(5)
    n = 30
    a, b = _networks(n, comms)
    assert not a._sparse and b._sparse
    s = SwarmState(0.0, 0, rng.uniform(0, 50, (n, 3)), np.zeros((n, 3)), rng.uniform(0, 50, (n, 3)),
                   np.array([Mode.APF] * n, dtype=object), [None] * n, np.zeros(n, int), [None] * n,
                   np.zeros(n, int))  # fmt: skip
    a.reset(np.random.default_rng(1), s)
    b.reset(np.random.default_rng(1), s)
    for step in range(40):
        t0, s.t = s.t, (step + 1) * 0.05
        s.position = s.position + rng.normal(0, 0.3, (n, 3))
        s.velocity = rng.normal(0, 1.0, (n, 3))
        acc = rng.normal(0, 1.0, (n, 3))
        a.broadcast(t0, s, np.zeros(n, bool), acc, np.zeros(n, bool))
        b.broadcast(t0, s, np.zeros(n, bool), acc, np.zeros(n, bool))
        idx = np.sort(rng.choice(n, n - 4, replace=False))
        args = (idx, s.t, s.position, s.velocity, np.zeros(n, bool), np.zeros(n))
        ba, bb = a.beliefs(*args, near=12.0), b.beliefs(*args, near=12.0)
        np.testing.assert_array_equal(a.heard, b.heard)
        for i in (0, 7, n - 1):
            np.testing.assert_array_equal(a._heard_by(i), b._heard_by(i))
        assert (a.sent, a.lost, a.out_of_range) == (b.sent, b.lost, b.out_of_range)
        for x, y in ((ba, bb),):
            np.testing.assert_array_equal(x.view >= 0, y.view >= 0)
            for name in ("pos", "vel", "age", "agent", "expected_pos", "expected_vel", "parked"):
                vx, vy = getattr(x, name)[x.view], getattr(y, name)[y.view]
                np.testing.assert_array_equal(vx[x.view >= 0], vy[y.view >= 0])
            # the same rows in the table (in its own order): every maximum over them agrees
            np.testing.assert_array_equal(np.sort(x.age), np.sort(y.age))
            np.testing.assert_array_equal(np.sort(x.vel, axis=0), np.sort(y.vel, axis=0))
            (k1, j1, r1, d1), (k2, j2, r2, d2) = x.near_superset(12.0), y.near_superset(12.0)
            for u, v in ((k1, k2), (j1, j2), (x.pos[r1], y.pos[r2]), (d1, d2)):
                np.testing.assert_array_equal(u, v)
    # most pairs that heard anything heard something sent in flight
    assert (a.heard > n).sum() > 0.5 * (a.heard > 0).sum() > 0


def test_pairs_near_a_flyer_are_answered_from_the_widest_question():
    """A narrower question after a wider one gets the wider answer whole (the caller tests the
    distances), which holds every pair of the narrower one; a wider one is found anew."""
    b = _beliefs(np.random.default_rng(7), 10, 40)
    own = b.idx.astype(np.int64)
    wide = b.near_superset(9.0)
    assert b.near_superset(4.0) is wide
    narrow = held_pairs(b.view, b.pos, b.at, own, 4.0)
    inside = wide[3] < 4.0
    for w, n in zip(wide, narrow, strict=True):
        np.testing.assert_array_equal(w[inside], n)
    wider = b.near_superset(12.0)
    assert len(wider[0]) > len(wide[0]) and (wider[3] < 12.0).all()
