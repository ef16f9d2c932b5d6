"""Compiled per-generation arithmetic of ``ba`` and ``iba_abc`` (:mod:`swarmplan.optimizers.bat`).

Why numba here: at the populations these algorithms run with (30 bats, 6 employed sources
and 24 onlookers) every numpy call costs more than the arithmetic it does, and one
generation of the numpy code was ~40 (``ba``) to ~90 (``iba_abc``) calls: 4-16 µs of
overhead per evaluation at d = 50 against the 1 µs target. Here a generation is
one batched ``rng.random`` draw made in numpy (passing the Generator into numba costs ~10 µs
per call to unbox it, and numpy's batched draw is faster than numba's per-scalar one), the
cost call(s), and two or three kernel calls. The equations, their order of floating-point
operations and (for ``ba``) the random stream are those of the numpy code they replace, so
``ba`` is bit-identical to it (for populations up to 128, see :func:`_mean`); the
docstrings of :mod:`swarmplan.optimizers.bat` say which equation each step is.
"""

from __future__ import annotations

import numpy as np

from swarmplan.optimizers._kernels import fitness_cumsum
from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def _block_sum(a, lo, n):  # noqa: ANN001, ANN202
    """numpy's pairwise summation of ``a[lo:lo+n]`` for ``n <= 128`` (8 accumulators)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _mean(a):  # noqa: ANN001, ANN202
    """``a.mean()``, bit for bit for up to 128 values (numpy's summation order, see
    :func:`_block_sum`). numpy splits longer sums in halves recursively; here they are summed
    in blocks of 128 from the left, which differs from numpy in the last bits only (a
    recursive numba function would not survive the ``cache=True`` reload, and an explicit
    stack costs more compile time than populations of over 128 bats are worth)."""
    n = a.size
    res = 0.0
    for lo in range(0, n, 128):
        res += _block_sum(a, lo, min(128, n - lo))
    return res / n


@njit(cache=True, nogil=True)
def _clip(c, lo, hi):  # noqa: ANN001, ANN202
    # np.minimum(np.maximum(c, lo), hi), NaN kept as NaN like the ufuncs
    if c < lo:
        c = lo
    if c > hi:
        c = hi
    return c


#: Layout of the per-run constants vector ``c`` the kernels take (one array instead of a
#: dozen scalar arguments: each argument costs numba's dispatcher ~0.1 µs).
C_F_MIN, C_F_SPAN, C_WALK, C_USE_BEST, C_ALPHA, C_FLOOR, C_F, C_T_LIMIT, C_A0, C_R0 = range(10)
N_C = 10


@njit(cache=True, nogil=True)
def bat_move(X, V, best_x, A, r, u, c, box, cand):  # noqa: ANN001, ANN201
    """Eqs 8-9 for every bat: candidates into ``cand``, clipped into the box; ``V`` updated in place.

    ``box`` is ``(lower, upper, upper - lower)``. ``u`` holds the generation's uniform draws,
    in the order the numpy code drew them: ``u[:n]`` frequencies, ``u[n:2n]`` the
    ``rand_1 > r_i`` tests, ``u[2n:2n+n*d]`` the walk's ``eps`` (as ``U[0, 1)``;
    ``eps = -1 + 2 u`` is numpy's ``uniform(-1, 1)``).
    """
    n, d = X.shape
    f_min, f_span = c[C_F_MIN], c[C_F_SPAN]
    step = _mean(A) * c[C_WALK]  # the walk's A^t * walk_scale, times the box width below
    for i in range(n):
        f = f_min + f_span * u[i]
        walker = u[n + i] > r[i]
        base = 2 * n + i * d
        for j in range(d):
            v = V[i, j] + (best_x[j] - X[i, j]) * f
            V[i, j] = v
            if walker:
                x = best_x[j] + (-1.0 + 2.0 * u[base + j]) * (step * box[2, j])
            else:
                x = X[i, j] + v
            cand[i, j] = _clip(x, box[0, j], box[1, j])


@njit(cache=True, nogil=True)
def _accept(bats, cand, fc, u, off, best_x, best_f, r_new, c, changed):  # noqa: ANN001, ANN202
    """Eq 10 (see ``bat._bat_acceptance``) then ``X*`` update (``bat._update_best``) on ``bats
    = (X, fit, A, r)`` (positions, costs, loudness, pulse rates); returns the new best cost.
    ``u[off + i]`` is bat ``i``'s ``rand_2``; accepted bats are marked in ``changed``."""
    X, fit, A, r = bats
    n, d = X.shape
    use_best = c[C_USE_BEST] != 0.0
    alpha, floor = c[C_ALPHA], c[C_FLOOR]
    for i in range(n):
        ref = best_f if use_best else fit[i]
        if u[off + i] < A[i] and fc[i] < ref:
            for j in range(d):
                X[i, j] = cand[i, j]
            fit[i] = fc[i]
            A[i] = max(A[i] * alpha, floor)
            r[i] = r_new
            changed[i] = True
    k = -1
    for i in range(n):  # first index of the minimum, taken only when it beats X*
        if fc[i] < best_f:
            best_f = fc[i]
            k = i
    if k >= 0:
        for j in range(d):
            best_x[j] = cand[k, j]
    return best_f


@njit(cache=True, nogil=True)
def bat_accept(bats, cand, fc, u, best_x, best_f, r_new, c, changed):  # noqa: ANN001, ANN201
    """Eq 10 and the ``X*`` update after the BA step on ``bats = (X, fit, A, r)``; returns the
    new best cost.

    ``rand_2`` follows ``bat_move``'s draws in ``u``; ``changed`` is cleared, then marks the
    accepted bats.
    """
    n, d = bats[0].shape
    changed[:] = False
    return _accept(bats, cand, fc, u, n * (d + 2), best_x, best_f, r_new, c, changed)


@njit(cache=True, nogil=True)
def _unit_index(x, k):  # noqa: ANN001, ANN202
    # floor(x k) for x in [0, 1): a uniform index in range(k)
    return min(int(x * k), k - 1)


@njit(cache=True, nogil=True)
def _nth_not_in(t, ne, e0, e1, e2):  # noqa: ANN001, ANN202
    """The ``t``-th (from 0) index of ``range(ne)`` that is none of ``e0, e1, e2`` (-1: unused)."""
    for j in range(ne):
        if j == e0 or j == e1 or j == e2:
            continue
        if t == 0:
            return j
        t -= 1
    return ne - 1  # not reached when t < ne - (number of exclusions)


@njit(cache=True, nogil=True)
def iba_onlookers(bats, cand, fc, u, best_x, best_f, r_new, c, box, on, src, changed):  # noqa: ANN001, ANN201
    """The employed bees' acceptance (as :func:`bat_accept`, ``bats = (X, fit, A, r)``), then the
    onlookers' candidates (eqs 11-13) into ``on`` and their sources into ``src``; returns the
    new best cost.

    ``u[ne (d + 3):]`` holds, per onlooker in blocks of ``m``: roulette, dimension, three
    donors, ``rand_3``, ``eps`` (``u[:ne (d + 3)]`` was the employed bees' BA step).
    """
    X, fit, A, r = bats
    ne, d = X.shape
    m = on.shape[0]
    best_f = bat_accept(bats, cand, fc, u, best_x, best_f, r_new, c, changed)
    # eq 11 with the fitness of eq 20 (bat.roulette_probabilities): cumulative weights
    cdf = np.empty(ne)
    total = fitness_cumsum(fit, cdf)
    if not total > 0:  # no usable fitness: every source equally likely
        for i in range(ne):
            cdf[i] = i + 1.0
        total = float(ne)
    mean_a = _mean(A)
    walk, F = c[C_WALK], c[C_F]
    base = ne * (d + 3)
    for q in range(m):
        target = u[base + q] * total
        k = ne - 1
        for i in range(ne):  # searchsorted(cdf, target, side="right")
            if cdf[i] > target:
                k = i
                break
        src[q] = k
        dim = _unit_index(u[base + m + q], d)
        t = base + 2 * m + 3 * q
        if ne >= 4:  # r1, r2, r3 distinct and not k, uniformly at random (eq 12)
            r1 = _nth_not_in(_unit_index(u[t], ne - 1), ne, k, -1, -1)
            r2 = _nth_not_in(_unit_index(u[t + 1], ne - 2), ne, k, r1, -1)
            r3 = _nth_not_in(_unit_index(u[t + 2], ne - 3), ne, k, r1, r2)
        else:  # too few sources to be distinct: drawn with replacement
            r1 = _unit_index(u[t], ne)
            r2 = _unit_index(u[t + 1], ne)
            r3 = _unit_index(u[t + 2], ne)
        val = X[r1, dim] + F * (X[r2, dim] - X[r3, dim])  # eq 12
        if u[base + 5 * m + q] > r[k]:  # rand_3 > r_k: local search around X*, eq 13
            eps = -1.0 + 2.0 * u[base + 6 * m + q]
            val = best_x[dim] + eps * mean_a * walk * box[2, dim]
        for j in range(d):
            on[q, j] = X[k, j]
        on[q, dim] = _clip(val, box[0, dim], box[1, dim])
    return best_f


@njit(cache=True, nogil=True)
def iba_settle(X, fit, trial, on, fo, src, changed, best_x, best_f, c, scouts):  # noqa: ANN001, ANN201
    """After the onlookers' evaluation: ``X*`` update, greedy replacement of each source by
    its best onlooker candidate (step 11), trial counters and the sources to scout (step 14).

    Returns ``(best_f, number of scouts)``; ``scouts`` marks them (never the best source).
    """
    ne, d = X.shape
    m = on.shape[0]
    k = -1
    for q in range(m):
        if fo[q] < best_f:
            best_f = fo[q]
            k = q
    if k >= 0:
        for j in range(d):
            best_x[j] = on[k, j]
    win = np.full(ne, -1, dtype=np.int64)
    bestval = fit.copy()
    for q in range(m):  # per source the first of its best candidates, if it beats the source
        s = src[q]
        if fo[q] < bestval[s]:
            bestval[s] = fo[q]
            win[s] = q
    for s in range(ne):
        if win[s] >= 0:
            for j in range(d):
                X[s, j] = on[win[s], j]
            fit[s] = fo[win[s]]
            changed[s] = True
    ib = 0
    for s in range(ne):
        trial[s] = 0 if changed[s] else trial[s] + 1
        if fit[s] < fit[ib]:
            ib = s
    t_limit = c[C_T_LIMIT]
    count = 0
    for s in range(ne):
        scouts[s] = trial[s] >= t_limit and s != ib
        count += scouts[s]
    return best_f, count


@njit(cache=True, nogil=True)
def iba_scouts(X, V, A, r, trial, U, scouts, c, box):  # noqa: ANN001, ANN201
    """Step 14: the sources marked in ``scouts`` restart at uniform random points.

    ``U`` holds one row of ``U[0, 1)`` draws per scout (in source order); in place it becomes
    the scouts' points ``lower + U span`` (``Problem.uniform``'s arithmetic), which are copied
    into ``X``; velocity, loudness, pulse rate and trial counter are reset.
    """
    ne, d = X.shape
    t = 0
    for s in range(ne):
        if scouts[s]:
            for j in range(d):
                x = box[0, j] + U[t, j] * box[2, j]
                U[t, j] = x
                X[s, j] = x
                V[s, j] = 0.0
            A[s] = c[C_A0]
            r[s] = c[C_R0]
            trial[s] = 0
            t += 1


@njit(cache=True, nogil=True)
def iba_scouts_settle(fit, Xs, fs, scouts, best_x, best_f):  # noqa: ANN001, ANN201
    """The scouts' costs ``fs`` into ``fit`` and the ``X*`` update; returns the best cost."""
    t = 0
    for s in range(fit.shape[0]):
        if scouts[s]:
            fit[s] = fs[t]
            t += 1
    k = -1
    for t in range(fs.shape[0]):  # first index of the minimum, taken only when it beats X*
        if fs[t] < best_f:
            best_f = fs[t]
            k = t
    if k >= 0:
        for j in range(Xs.shape[1]):
            best_x[j] = Xs[k, j]
    return best_f
