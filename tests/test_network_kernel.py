"""The network's compiled passes (swarm worlds) give the numpy answers of small worlds: the
pairs each flyer believes within a radius, and the copies delivered."""

from __future__ import annotations

import numpy as np

from swarmplan.core import Mode, SwarmState
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim.network import SWARM_PAIRS, Beliefs, Network
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
        assert b.view.size <= SWARM_PAIRS  # the numpy answer
        for radius in (0.0, 3.0, 7.5, 100.0):
            want = b._pairs(radius)
            got = kernel.held_pairs(b.view, b.pos, b.at, b.idx.astype(np.int64), radius)
            for w, g in zip(want, got, strict=True):
                np.testing.assert_array_equal(w, g)
            assert (want[1] != b.idx[want[0]]).all() and (want[3] < radius).all()
        assert len(b._pairs(100.0)[0]) == int((b.view >= 0).sum()) - 20  # every held row but its own


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
            if not kernel.deliver(b.heard, m.senders, m.rows, m.arrives, b.table.t, s.t, 1e-9):
                b.pending.remove(m)
        np.testing.assert_array_equal(a.heard, b.heard)
    assert (a.heard > n).sum() > 0.5 * n * n  # most pairs heard something sent in flight
