"""Compiled helpers of :class:`swarmplan.optimizers.core.Problem`, usable by every algorithm.

Why numba here: at the populations the planner uses (30 x d = 50) an optimizer's own cost is
the number of Python-level numpy calls per generation, not their arithmetic (each call costs
about a microsecond before it touches a number; issue 10 asks for <= 1 µs of overhead per
*evaluation*, i.e. ~30 µs per generation for everything). One compiled loop replaces the
5-10 numpy calls of a clip + copy or a NaN scan + argmin with one call.

Rules the kernels follow (so that they stay cheap to compile and to call):

* no ``np.random.Generator`` arguments: unboxing a Generator costs ~20 µs per call here
  (more than a whole generation's budget), so algorithms draw their random numbers in one
  batched numpy call and pass the array;
* typed by usage (no explicit signatures), ``cache=True`` (compiled once per machine);
* this module is imported lazily (numba's import takes ~0.5 s), at the first
  ``Problem.evaluate`` (see :func:`swarmplan.optimizers.core.kernels`).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def clip_rows(X, k, lower, upper):  # noqa: ANN001, ANN201
    """A new C-ordered ``(k, d)`` array: the first ``k`` rows of ``X`` clipped into the box.

    Same values as ``np.minimum(np.maximum(X[:k], lower), upper)`` (NaN stays NaN).
    """
    d = X.shape[1]
    out = np.empty((k, d))
    for i in range(k):
        for j in range(d):
            x = X[i, j]
            if x < lower[j]:
                x = lower[j]
            if x > upper[j]:
                x = upper[j]
            out[i, j] = x
    return out


@njit(cache=True)
def finish_costs(f):  # noqa: ANN001, ANN201
    """``(fe, i, fe[i])``: a float copy of the costs ``f`` with NaN replaced by ``inf``, the
    index of the smallest (the first one on ties, as ``np.argmin``) and its value."""
    k = f.shape[0]
    fe = np.empty(k)
    best = 0
    for i in range(k):
        v = f[i]
        if np.isnan(v):
            v = np.inf
        fe[i] = v
        if v < fe[best]:
            best = i
    return fe, best, fe[best]


@njit(cache=True)
def scale_into_box(U, lower, span):  # noqa: ANN001, ANN201
    """In place: ``U <- lower + U * span`` per row (uniforms in [0, 1) -> points in the box).

    Same values as ``lower + U * span`` in numpy (one product, one sum per coordinate).
    """
    n, d = U.shape
    for i in range(n):
        for j in range(d):
            U[i, j] = lower[j] + U[i, j] * span[j]
    return U
