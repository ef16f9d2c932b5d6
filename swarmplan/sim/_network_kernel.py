"""Compiled phases of the network of a world with ``comms`` (``swarmplan.sim.network``), for
swarms: every (receiver, sender) pair is visited each step, which numpy does in many passes
over (N, N) arrays and a loop does in one. Each function is its numpy counterpart's arithmetic
in the same order (tests/test_network_kernel.py holds them to the same answers)."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True, inline="always")
def _held_distance(view, pos, at, own, k, j):  # noqa: ANN001, ANN202
    """The distance from flyer k to the row it holds of agent j; inf when it holds none, or j is itself."""
    r = view[k, j]
    if r < 0 or j == own[k]:
        return np.inf
    dx, dy, dz = pos[r, 0] - at[k, 0], pos[r, 1] - at[k, 1], pos[r, 2] - at[k, 2]
    return math.sqrt((dx * dx + dy * dy) + dz * dz)


@njit(cache=True, nogil=True)
def held_pairs(view, pos, at, own, radius):  # noqa: ANN001, ANN201
    """(flyer row k, agent j, table row, distance) for every agent j that flyer k (at
    ``at[k]``, agent ``own[k]``) holds a row of (``view[k, j]`` >= 0) within ``radius`` of it,
    itself left out, in (k, j) order."""
    n, n_all = view.shape
    count = 0
    for k in range(n):
        for j in range(n_all):
            if _held_distance(view, pos, at, own, k, j) < radius:
                count += 1
    ks = np.empty(count, dtype=np.int64)
    js = np.empty(count, dtype=np.int64)
    rows = np.empty(count, dtype=np.int64)
    ds = np.empty(count)
    c = 0
    for k in range(n):
        for j in range(n_all):
            d = _held_distance(view, pos, at, own, k, j)
            if d < radius:
                ks[c], js[c], rows[c], ds[c] = k, j, view[k, j], d
                c += 1
    return ks, js, rows, ds


@njit(cache=True, nogil=True)
def deliver(heard, senders, rows, arrives, t_row, t, eps):  # noqa: ANN001, ANN201
    """Copies of one broadcast (``senders``, their table ``rows``, ``arrives`` (N, k)) that have
    arrived by ``t`` replace older rows in ``heard`` (receiver, sender) and are marked taken
    (inf); returns whether any copy is still on its way."""
    n, k = arrives.shape
    left = False
    for r in range(n):
        for c in range(k):
            a = arrives[r, c]
            if a <= t + eps:
                s = senders[c]
                if t_row[heard[r, s]] < t_row[rows[c]]:
                    heard[r, s] = rows[c]
                arrives[r, c] = np.inf
            elif a < np.inf:
                left = True
    return left
