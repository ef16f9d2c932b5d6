"""The network's compiled passes (swarm worlds) give the numpy answers of small worlds: the
pairs each flyer believes within a radius, the fate of each copy of a broadcast, the rows each
flyer holds, and the copies delivered."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.core import Mode, SwarmState
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim import network
from swarmplan.sim.network import (
    Beliefs,
    Network,
    compact_near_numpy,
    deliver_numpy,
    draws,
    fates_numpy,
    held_pairs,
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
    return Beliefs(idx, at, pos, pos * 0, z > 0, z, z, np.arange(rows) % n_all, view, pos, pos * 0)


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


def test_delivery_of_one_broadcast_compiled_and_numpy_agree():
    """Every combination of loss, jitter and range, asked at several times: the same rows heard
    and the same counts; a copy never reaches its own sender, nor a receiver out of range."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(3)
    n, k = 25, 9
    senders = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    rows = np.arange(100, 100 + k, dtype=np.int64)
    at = rng.uniform(0, 30, (n, 3))
    key = np.uint64(77)
    for loss, jitter, ranged in [(0.0, 0.0, False), (0.3, 0.0, True), (0.2, 0.05, False), (0.2, 0.05, True)]:
        fate = (loss, jitter, 1.1, 20.0 if ranged else math.inf)
        where = at if ranged else np.zeros((0, 3))
        start = rng.integers(0, 100, (n, n)).astype(np.int64)
        a, b = start.copy(), start.copy()
        heard_a, heard_b = np.empty((n, k), dtype=bool), np.empty((n, k), dtype=bool)
        lost, out = fates_numpy(senders, rows, key, fate, where, heard_a)
        assert (lost, out) == tuple(kernel.fates(senders, rows, key, fate, where, heard_b))
        np.testing.assert_array_equal(heard_a, heard_b)
        for t in (1.04, 1.08, 1.1, 1.13, 1.2):
            deliver_numpy(a, senders, rows, key, fate, heard_a, t)
            kernel.deliver(b, senders, rows, key, fate, heard_b, t)
            np.testing.assert_array_equal(a, b)
            if t == 1.04 and jitter == 0.0:
                assert (a == start).all()  # nothing before it falls due
        changed = a != start
        assert not changed[senders, senders].any()
        if ranged:
            d = np.linalg.norm(at[:, None] - at[None, senders], axis=-1)
            assert not (changed[:, senders] & (d > 20.0)).any()
        # Every copy has arrived by 1.2 s (due 1.1 s, jitter 0.05 s) and is newer than what was heard.
        assert int(changed.sum()) == int(heard_a.sum()) == n * k - k - lost - out
        assert (lost > 0) == (loss > 0) and (out > 0) == ranged


def test_compaction_compiled_and_numpy_agree():
    """The rows held, in the order first met, each flyer's view of them, their ages and positions moved on,
    and the pairs within a radius; the compiled scratch is left as found."""
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
    for radius in (0.0, 2.5, 6.0, 100.0):
        for old in (never, stale):
            want = compact_near_numpy(heard, idx, mark, table, 2.5, at, radius, old)
            got = kernel.compact_near(heard, idx, mark, table, 2.5, at, radius, old)
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
    held = heard[idx]
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


def test_delivery_compiled_and_numpy_agree(monkeypatch):
    """Random broadcasts with jitter and losses, delivered step by step by both paths: the
    same rows heard at every step."""
    rng = np.random.default_rng(5)
    n = 30
    a = Network(Comms(20.0, 0.1, 0.08, 0.2), None, np.full(n, 5.0), np.full(n, 3.0), 0.05)
    b = Network(Comms(20.0, 0.1, 0.08, 0.2), None, np.full(n, 5.0), np.full(n, 3.0), 0.05)

    s = SwarmState(0.0, 0, rng.uniform(0, 50, (n, 3)), np.zeros((n, 3)), rng.uniform(0, 50, (n, 3)),
                   np.array([Mode.APF] * n, dtype=object), [None] * n, np.zeros(n, int), [None] * n,
                   np.zeros(n, int))  # fmt: skip
    a.reset(np.random.default_rng(1), s)
    b.reset(np.random.default_rng(1), s)
    for step in range(40):
        t0, s.t = s.t, (step + 1) * 0.05
        s.position = s.position + rng.normal(0, 0.1, (n, 3))
        acc = rng.normal(0, 1.0, (n, 3))
        a.broadcast(t0, s, np.zeros(n, bool), acc)
        b.broadcast(t0, s, np.zeros(n, bool), acc)
        a.deliver(s.t)  # numpy (30 agents)
        with monkeypatch.context() as m:
            m.setattr(network, "use_compiled", lambda n, fixed_wings=False: True)
            b.deliver(s.t)
        np.testing.assert_array_equal(a.heard, b.heard)
        assert (a.lost, a.out_of_range) == (b.lost, b.out_of_range)
    assert (a.heard > n).sum() > 0.5 * n * n  # most pairs heard something sent in flight


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
