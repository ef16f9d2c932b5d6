"""Compiled helpers of :class:`swarmplan.optimizers.base.Problem`, usable by every algorithm.

Why numba here: at the populations the planner uses (30 x d = 50) an optimizer's own cost is
the number of Python-level numpy calls per generation, not their arithmetic (each call costs
about a microsecond before it touches a number; the target is <= 1 µs of overhead per
*evaluation*, i.e. ~30 µs per generation for everything). One compiled loop replaces the
5-10 numpy calls of a clip + copy or a NaN scan + argmin with one call.

Rules the kernels follow (so that they stay cheap to compile and to call):

* no ``np.random.Generator`` arguments: unboxing a Generator costs ~20 µs per call here
  (more than a whole generation's budget), so algorithms draw their random numbers in one
  batched numpy call and pass the array;
* typed by usage (no explicit signatures), ``cache=True`` (compiled once per machine);
* this module is imported lazily (numba's import takes ~0.5 s), when the first ``Problem``
  is built (see :func:`swarmplan.optimizers.base.kernels`); other algorithms may call these
  kernels too (``core.kernels().clip_into(...)``).
"""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True)
def clip_into(X, out, lower, upper):  # noqa: ANN001, ANN201
    """``out[i] = X[i]`` clipped into the box, for the ``len(out)`` first rows of ``X``.

    Same values as ``np.minimum(np.maximum(X[:k], lower), upper)`` (NaN stays NaN). ``out``
    is allocated by the caller: a numba-allocated array costs ~1 µs more to hand back.
    """
    k, d = out.shape
    for i in range(k):
        for j in range(d):
            x = X[i, j]
            if x < lower[j]:
                x = lower[j]
            if x > upper[j]:
                x = upper[j]
            out[i, j] = x


@njit(cache=True)
def finish_costs(f, out):  # noqa: ANN001, ANN201
    """``out[:] = f`` with NaN replaced by ``inf``; returns the index of the smallest (the
    first one on ties, as ``np.argmin``)."""
    best = 0
    for i in range(out.shape[0]):
        v = f[i]
        if np.isnan(v):
            v = np.inf
        out[i] = v
        if v < out[best]:
            best = i
    return best


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


@njit(cache=True)
def fitness_cumsum(fit, cdf):  # noqa: ANN001, ANN201
    """The bee colonies' roulette (000 eq 11, fitness of eq 20): cumulative weights into ``cdf``.

    Weight ``1/(1+f)`` for ``f > 0``, ``1+|f|`` otherwise, 0 when not finite; returns the
    total. Shared by ``abc`` and ``iba_abc`` (same arithmetic, same order).
    """
    total = 0.0
    for i in range(fit.shape[0]):
        f = fit[i]
        w = 1.0 / (1.0 + f) if f > 0 else 1.0 + abs(f)
        if not np.isfinite(w):
            w = 0.0
        total += w
        cdf[i] = total
    return total
