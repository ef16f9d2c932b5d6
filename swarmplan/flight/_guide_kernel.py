"""Compiled (numba) shortest ways of the static guide (:mod:`swarmplan.flight.guide`).

:func:`dijkstra` is Dijkstra's search over a graph in CSR form from one source, with the same
answers, to the bit, as scipy's ``scipy.sparse.csgraph.dijkstra(graph, directed=True,
indices=source, return_predecessors=True)``. scipy's search keeps a heap of (distance, vertex)
entries, a vertex entering again whenever its distance strictly drops (the older entry passed
over when it comes up), and pops the least distance first and, among equal distances, the
greatest vertex index; the legs of a vertex are relaxed in their CSR order. Distances and
predecessors follow from that order alone, so any queue that pops the vertices in it gives the
same tables: here a binary heap holding each vertex once (its key lowered in place), smaller
than scipy's, and no per-call checks and copies of the graph (nor scipy.sparse at start-up).
"""

from __future__ import annotations

import numpy as np
from numba import njit

NO_WAY = -9999
"""The predecessor of a vertex with no way to it (and of the source), as scipy writes it."""


@njit(cache=True)
def dijkstra(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, source: int
) -> tuple[np.ndarray, np.ndarray]:
    """Distances (float64) and predecessors (int32, ``NO_WAY`` where none) from ``source``
    over the graph ``(data, indices, indptr)`` (CSR, non-negative weights)."""
    n = len(indptr) - 1
    dist = np.full(n, np.inf)
    pred = np.full(n, NO_WAY, dtype=np.int32)
    done = np.zeros(n, dtype=np.bool_)
    at = np.full(n, -1, dtype=np.int64)  # a vertex's place in the heap (-1: not in it)
    hd = np.empty(n)  # the heap: keys (distance, vertex) ...
    hv = np.empty(n, dtype=np.int64)
    size = 1
    dist[source] = 0.0
    hd[0] = 0.0
    hv[0] = source
    at[source] = 0
    while size > 0:
        u = hv[0]
        du = hd[0]
        done[u] = True
        at[u] = -1
        size -= 1
        if size > 0:  # the last entry sifts down from the root
            kd, kv = hd[size], hv[size]
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and (hd[c + 1] < hd[c] or (hd[c + 1] == hd[c] and hv[c + 1] > hv[c])):
                    c += 1
                if hd[c] < kd or (hd[c] == kd and hv[c] > kv):
                    hd[i] = hd[c]
                    hv[i] = hv[c]
                    at[hv[i]] = i
                    i = c
                else:
                    break
            hd[i] = kd
            hv[i] = kv
            at[kv] = i
        for j in range(indptr[u], indptr[u + 1]):
            w = indices[j]
            if done[w]:
                continue
            nd = du + data[j]
            if dist[w] > nd:
                dist[w] = nd
                pred[w] = u
                i = at[w]
                if i < 0:
                    i = size
                    size += 1
                while i > 0:  # sift up
                    p = (i - 1) // 2
                    if nd < hd[p] or (nd == hd[p] and w > hv[p]):
                        hd[i] = hd[p]
                        hv[i] = hv[p]
                        at[hv[i]] = i
                        i = p
                    else:
                        break
                hd[i] = nd
                hv[i] = w
                at[w] = i
    return dist, pred
