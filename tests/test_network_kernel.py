"""The network's compiled passes (swarm worlds) give the numpy answers of small worlds: the
pairs each flyer believes within a radius, the fate of each copy of a broadcast, the rows each
flyer holds, and the copies delivered."""

from __future__ import annotations

import numpy as np

from swarmplan.core import Mode, SwarmState
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim.network import Beliefs, Network, compact, copies, held_pairs
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


def test_copies_compiled_and_numpy_agree():
    """Every combination of jitter and range: the same arrivals, counts and earliest arrival;
    a copy to its own sender never arrives."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(3)
    n, k = 25, 9
    who = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    lost_u = rng.random((n, k))
    for jitter_u in (np.zeros((0, 0)), rng.uniform(-1.0, 1.0, (n, k))):
        for far in (np.zeros((0, 0), dtype=bool), rng.random((n, k)) < 0.3):
            want = copies(lost_u, 0.2, jitter_u, 0.03, 1.5, who, far)
            got = kernel.copies(lost_u, 0.2, jitter_u, 0.03, 1.5, who, far)
            np.testing.assert_array_equal(want[0], got[0])
            assert want[1:] == tuple(got[1:])
            assert np.isinf(want[0][who, np.arange(k)]).all()
            listener = np.ones((n, k), dtype=bool)
            listener[who, np.arange(k)] = False
            near = listener & ~far if far.size else listener
            assert want[1] == int((near & (lost_u < 0.2)).sum())
            assert want[2] == (int((listener & far).sum()) if far.size else 0)
            assert want[3] == want[0].min()


def test_compaction_compiled_and_numpy_agree():
    """The rows held, ascending, and each flyer's view of them; the compiled scratch is left as found."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(4)
    heard = rng.integers(0, 200, (40, 40)).astype(np.int64)
    heard[rng.random((40, 40)) < 0.3] = 0
    idx = np.sort(rng.choice(40, 15, replace=False)).astype(np.int64)
    mark = np.full(260, -1, dtype=np.int64)
    want, got = compact(heard, idx, mark), kernel.compact(heard, idx, mark)
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(w, g)
    assert (mark == -1).all()
    live, view = want
    held = heard[idx]
    np.testing.assert_array_equal(live[view[held > 0]], held[held > 0])
    assert (view[held == 0] == -1).all() and (np.diff(live) > 0).all()


def test_delivery_compiled_and_numpy_agree():
    """Random broadcasts with jitter and losses, delivered step by step by both paths: the
    same rows heard at every step."""
    kernel = kernel_module("swarmplan.sim._network_kernel")
    rng = np.random.default_rng(5)
    n = 30
    a = Network(Comms(20.0, 0.1, 0.08, 0.2), None, np.full(n, 5.0), 0.05)
    b = Network(Comms(20.0, 0.1, 0.08, 0.2), None, np.full(n, 5.0), 0.05)

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
        a.deliver(s.t)  # numpy (30 x 30 pairs)
        for m in list(b.pending):
            if kernel.deliver(b.heard, m.senders, m.rows, m.arrives, b.table.t, s.t, 1e-9) == np.inf:
                b.pending.remove(m)
        np.testing.assert_array_equal(a.heard, b.heard)
    assert (a.heard > n).sum() > 0.5 * n * n  # most pairs heard something sent in flight
