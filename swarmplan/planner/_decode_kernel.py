"""Compiled decoder of :class:`~swarmplan.planner.segment_cost.SegmentEncoding`.

Why numba: the numpy decoder (a matmul, a clip, two broadcasts and a concatenate on arrays of
a few dozen rows) cost as much per call as scoring the whole population with the compiled
cost (``_segment_kernel``); this loop costs a few microseconds. Its own module: it calls no
other compiled function (numba's cache does not see changes in callees of other files).
"""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True, error_model="numpy")
def decode_segments(X, frame, base, start, end, lo, hi, clip):  # noqa: ANN001, ANN201
    """``SegmentEncoding.decode``: decision vectors X (n, 3K) → polylines (n, K+2, 3), the K
    waypoints at ``base + offsets @ frame`` clipped into ``lo``..``hi`` when ``clip``."""
    n = X.shape[0]
    k = base.shape[0]
    P = np.empty((n, k + 2, 3))
    for c in range(n):
        for a in range(3):
            P[c, 0, a] = start[a]
            P[c, k + 1, a] = end[a]
        for v in range(k):
            o0, o1, o2 = X[c, 3 * v], X[c, 3 * v + 1], X[c, 3 * v + 2]
            for a in range(3):
                val = base[v, a] + (o0 * frame[0, a] + o1 * frame[1, a] + o2 * frame[2, a])
                if clip:
                    val = min(max(val, lo[a]), hi[a])
                P[c, v + 1, a] = val
    return P
