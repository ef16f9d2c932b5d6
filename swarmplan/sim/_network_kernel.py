"""Compiled phases of the network of a world with ``comms`` (``swarmplan.sim.network``), for
swarms: every (receiver, sender) pair is visited each step, which numpy does in many passes
over (N, N) arrays and a loop does in one. Each function is its numpy counterpart's arithmetic
in the same order (tests/test_network_kernel.py holds them to the same answers)."""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def held_pairs(view, pos, at, own, radius):  # noqa: ANN001, ANN201
    """(flyer row k, agent j, table row, distance) for every agent j that flyer k (at
    ``at[k]``, agent ``own[k]``) holds a row of (``view[k, j]`` >= 0) within ``radius`` of it,
    itself left out, in (k, j) order."""
    n, n_all = view.shape
    # Distances first (inf: none held, or itself), then the pairs: the arithmetic is written
    # once, inline (a helper taking the arrays costs a reference count per call and pair).
    dist = np.full((n, n_all), np.inf)
    count = 0
    for k in range(n):
        for j in range(n_all):
            r = view[k, j]
            if r < 0 or j == own[k]:
                continue
            dx, dy, dz = pos[r, 0] - at[k, 0], pos[r, 1] - at[k, 1], pos[r, 2] - at[k, 2]
            d = math.sqrt((dx * dx + dy * dy) + dz * dz)
            dist[k, j] = d
            if d < radius:
                count += 1
    ks = np.empty(count, dtype=np.int64)
    js = np.empty(count, dtype=np.int64)
    rows = np.empty(count, dtype=np.int64)
    ds = np.empty(count)
    c = 0
    for k in range(n):
        for j in range(n_all):
            if dist[k, j] < radius:
                ks[c], js[c], rows[c], ds[c] = k, j, view[k, j], dist[k, j]
                c += 1
    return ks, js, rows, ds


@njit(cache=True, nogil=True)
def deliver(heard, senders, rows, arrives, t_row, t, eps):  # noqa: ANN001, ANN201
    """Copies of one broadcast (``senders``, their table ``rows``, ``arrives`` (N, k)) that have
    arrived by ``t`` replace older rows in ``heard`` (receiver, sender) and are marked taken
    (inf); returns the earliest arrival of the copies still on their way (inf: none)."""
    n, k = arrives.shape
    first = np.inf
    for r in range(n):
        for c in range(k):
            a = arrives[r, c]
            if a <= t + eps:
                s = senders[c]
                if t_row[heard[r, s]] < t_row[rows[c]]:
                    heard[r, s] = rows[c]
                arrives[r, c] = np.inf
            else:
                first = min(first, a)
    return first


@njit(cache=True, nogil=True)
def copies(lost_u, loss, jitter_u, jitter, due, who, far):  # noqa: ANN001, ANN201
    """When each copy of one broadcast arrives (N, k): at ``due`` (+ ``jitter`` times the uniform
    draw ``jitter_u``, when given), inf for a copy lost (draw ``lost_u`` below ``loss``), out of
    range (``far``, when given) or sent to its sender itself (``who[c]`` is the sender of column
    c); with the copies lost (in range) and out of range, and the earliest arrival."""
    n, k = lost_u.shape
    arrives = np.empty((n, k))
    lost = 0
    out = 0
    first = np.inf
    ranged = far.shape[0] > 0
    jittered = jitter_u.shape[0] > 0
    for r in range(n):
        for c in range(k):
            a = due
            if jittered:
                a += jitter * jitter_u[r, c]
            if r == who[c]:
                a = np.inf
            elif ranged and far[r, c]:
                out += 1
                a = np.inf
            elif lost_u[r, c] < loss:
                lost += 1
                a = np.inf
            arrives[r, c] = a
            first = min(first, a)
    return arrives, lost, out, first


@njit(cache=True, nogil=True)
def compact(heard, idx, mark):  # noqa: ANN001, ANN201
    """The table rows (ascending) that flyers ``idx`` hold in ``heard`` (receiver, sender; 0:
    none), and each flyer's view of them (n, N: the position among those rows, -1: none).
    ``mark`` (one per table row, all -1) is scratch, all -1 again on return."""
    n = idx.shape[0]
    n_all = heard.shape[1]
    found = np.empty(n * n_all, dtype=np.int64)
    count = 0
    for k in range(n):
        for j in range(n_all):
            r = heard[idx[k], j]
            if r > 0 and mark[r] < 0:
                mark[r] = 0
                found[count] = r
                count += 1
    live = np.sort(found[:count])
    for c in range(count):
        mark[live[c]] = c
    view = np.empty((n, n_all), dtype=np.int64)
    for k in range(n):
        for j in range(n_all):
            r = heard[idx[k], j]
            view[k, j] = mark[r] if r > 0 else -1
    for c in range(count):
        mark[live[c]] = -1
    return live, view
