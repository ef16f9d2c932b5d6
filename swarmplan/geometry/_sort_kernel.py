"""The kernels' one compiled sort and search: :func:`argsort`, the order that sorts a 1-d
array, ties in their first order and NaN last, as ``np.argsort(a, kind="stable")``;
:func:`search_left` and :func:`search_right`, ``np.searchsorted(xs, v, side="left")`` and
``side="right"`` in a sorted array (NaN last). Held to numpy bit for bit by
tests/test_sort_kernel.py.

Why not numba's own ``np.argsort``, ``np.sort`` and ``np.searchsorted``: numba compiles them into
every kernel that calls them, once per kernel and type of array in every process that compiles
such a kernel (0.5-1.5 s of CPU each). These are kernels of their own, compiled once per type
of array and cached on disk like every kernel, and the kernels that sort or search call them.
"""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def argsort(a: np.ndarray) -> np.ndarray:
    """The indexes (int64) that sort the 1-d array ``a``: ascending, equal values in their
    order in ``a``, NaN last (numpy's order for a stable sort)."""
    n = a.shape[0]
    val = np.empty(n, a.dtype)
    idx = np.empty(n, np.int64)
    for i in range(n):
        val[i] = a[i]
        idx[i] = i
    val2 = np.empty(n, a.dtype)
    idx2 = np.empty(n, np.int64)
    width = 1
    while width < n:
        lo = 0
        while lo < n:
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, o = lo, mid, lo
            while i < mid and j < hi:
                x, y = val[i], val[j]
                # y first only when strictly before x: y < x, or x NaN and y not
                if y < x or (x != x and y == y):
                    val2[o], idx2[o] = y, idx[j]
                    j += 1
                else:
                    val2[o], idx2[o] = x, idx[i]
                    i += 1
                o += 1
            while i < mid:
                val2[o], idx2[o] = val[i], idx[i]
                i += 1
                o += 1
            while j < hi:
                val2[o], idx2[o] = val[j], idx[j]
                j += 1
                o += 1
            lo = hi
        val, val2 = val2, val
        idx, idx2 = idx2, idx
        width *= 2
    return idx


@njit(cache=True, nogil=True)
def search_left(xs: np.ndarray, v: float) -> int:
    """``np.searchsorted(xs, v, side="left")``: the first index whose value is not before
    ``v`` in the sorted array ``xs`` (NaN after every number)."""
    lo, hi = 0, xs.shape[0]
    while lo < hi:
        mid = lo + ((hi - lo) >> 1)
        m = xs[mid]
        if m < v or (v != v and m == m):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def search_right(xs: np.ndarray, v: float) -> int:
    """``np.searchsorted(xs, v, side="right")``: the first index whose value is after ``v``
    in the sorted array ``xs`` (NaN after every number)."""
    lo, hi = 0, xs.shape[0]
    while lo < hi:
        mid = lo + ((hi - lo) >> 1)
        if v != v or xs[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo
