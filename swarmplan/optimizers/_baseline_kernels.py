"""Compiled generation steps of PSO, DE, GA (``baselines.py``) and ABC (``bee_colony.py``).

Why numba (target: optimizer overhead <= 1 µs per evaluation at d = 50): with populations
of 30-50 the numpy versions spent 3-13 µs per evaluation in 15-40 Python-level numpy calls
per generation (fancy indexing, masks, ``np.where`` chains, argsorts), each worth about a
microsecond before any arithmetic. Each algorithm now runs a generation as: one batched
uniform draw in numpy (a Generator argument costs ~20 µs to unbox per numba call, so the
kernels never take one), one kernel that builds the candidates, ``Problem.evaluate``, one
kernel for the selection. The equations are the algorithms' own; see each class's
docstring for the citation. The module is imported when an algorithm first needs it
(numba's import costs ~0.5 s), ``cache=True`` keeps the compiled code on disk.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.optimizers._kernels import fitness_cumsum
from swarmplan.runtime.compiled import njit

# --------------------------------------------------------------------------- PSO


@njit(cache=True)
def pso_move(X, V, P, g, R, w, c1, c2, vmax, lower, upper):  # noqa: ANN001, ANN201
    """In place: ``v <- w v + c1 r1 (p_i - x) + c2 r2 (p_g - x)``, clamp to ``+-vmax``,
    ``x <- x + v``, absorbing walls (coordinate onto the bound, velocity zeroed).

    ``R`` is ``(2, n, d)``: ``r1 = R[0]``, ``r2 = R[1]``. The operation order is numpy's
    (``V *= w; V += c1 * r1 * (P - X) + c2 * r2 * (P[g] - X); np.clip``), so the values are
    bit-identical to the vectorized form.
    """
    n, d = X.shape
    for i in range(n):
        for j in range(d):
            x = X[i, j]
            v = V[i, j] * w + (c1 * R[0, i, j] * (P[i, j] - x) + c2 * R[1, i, j] * (P[g, j] - x))
            lo_v = -vmax[j]
            v = v if v > lo_v else lo_v  # np.clip(v, -vmax, vmax): max then min
            v = v if v < vmax[j] else vmax[j]
            x = x + v
            if x < lower[j] or x > upper[j]:
                x = x if x > lower[j] else lower[j]
                x = x if x < upper[j] else upper[j]
                v = 0.0
            X[i, j] = x
            V[i, j] = v


@njit(cache=True)
def pso_personal_best(X, F, P, Pf):  # noqa: ANN001, ANN201
    """In place: ``p_i <- x_i`` where ``f(x_i) < f(p_i)``; returns the index of the best
    personal best (first on ties, as ``np.argmin``)."""
    n, d = X.shape
    g = 0
    for i in range(n):
        if F[i] < Pf[i]:
            Pf[i] = F[i]
            for j in range(d):
                P[i, j] = X[i, j]
        if Pf[i] < Pf[g]:
            g = i
    return g


# --------------------------------------------------------------------------- shared


@njit(cache=True)
def partners(u1, u2, u3, i, n):  # noqa: ANN001, ANN201
    """Three distinct indices of ``[0, n)``, none equal to ``i``, drawn uniformly without
    replacement from three uniforms: ``floor(u1 (n-1))``, ``floor(u2 (n-2))``,
    ``floor(u3 (n-3))``, each mapped onto the indices not taken yet (stepping over the
    excluded ones in increasing order)."""
    r1 = _index(u1, n - 1)
    if r1 >= i:
        r1 += 1
    lo, hi = min(i, r1), max(i, r1)
    r2 = _index(u2, n - 2)
    if r2 >= lo:
        r2 += 1
    if r2 >= hi:
        r2 += 1
    a, b, c = lo, hi, r2  # sort the three excluded ones: a < b < c
    if c < b:
        b, c = c, b
        if b < a:
            a, b = b, a
    r3 = _index(u3, n - 3)
    if r3 >= a:
        r3 += 1
    if r3 >= b:
        r3 += 1
    if r3 >= c:
        r3 += 1
    return r1, r2, r3


@njit(cache=True)
def _pow(x, e):  # noqa: ANN001, ANN202
    """``x ** e`` for ``x >= 0`` as ``2 ** (e log2 x)``: within ~1e-16 relative of libm's
    ``pow`` and ~40 % cheaper here (SBX calls it for every recombined coordinate)."""
    return math.exp2(e * math.log2(x))


@njit(cache=True)
def _index(u, m):  # noqa: ANN001, ANN202
    """``floor(u * m)`` for ``u`` in [0, 1): a uniform integer in ``[0, m)``."""
    r = int(u * m)
    return r if r < m else m - 1


# --------------------------------------------------------------------------- DE


@njit(cache=True)
def de_trials(X, R, F, CR, lower, upper, U):  # noqa: ANN001, ANN201
    """DE/rand/1/bin trial vectors (Storn & Price 1997) with JADE's midpoint bound repair,
    written into ``U`` (``(n, d)``, the caller's buffer).

    ``R`` is ``(n, d + 4)`` uniforms: columns 0-2 pick ``r1, r2, r3`` (distinct, != i, each
    uniform without replacement), column 3 the forced crossover coordinate, columns 4.. the
    binomial crossover tests ``u <= CR``.
    """
    n, d = X.shape
    for i in range(n):
        r1, r2, r3 = partners(R[i, 0], R[i, 1], R[i, 2], i, n)
        jr = _index(R[i, 3], d)
        for j in range(d):
            x = X[i, j]
            if R[i, 4 + j] <= CR or j == jr:
                v = X[r1, j] + F * (X[r2, j] - X[r3, j])
                if v < lower[j]:
                    v = 0.5 * (lower[j] + x)
                elif v > upper[j]:
                    v = 0.5 * (upper[j] + x)
                U[i, j] = v
            else:
                U[i, j] = x


@njit(cache=True)
def de_select(X, F, U, Fu):  # noqa: ANN001, ANN201
    """Greedy one-to-one selection, in place: the trial replaces its parent when ``f(u) <= f(x)``."""
    n, d = X.shape
    for i in range(n):
        if Fu[i] <= F[i]:
            F[i] = Fu[i]
            for j in range(d):
                X[i, j] = U[i, j]


# --------------------------------------------------------------------------- GA


def ga_draws(n_off: int, d: int, k: int, pm: float) -> tuple[int, int]:
    """``(total, mutation)``: the size of :func:`ga_offspring`'s uniform batch and of its
    mutation part (two uniforms per expected mutation plus an 8-sigma margin; should it ever
    run short, :func:`ga_mutate` continues from a fresh batch)."""
    n_pairs = (n_off + 1) // 2
    events = n_off * d * pm
    mutation = 2 * math.ceil(events + 8.0 * math.sqrt(events) + 8.0) + 1
    return 2 * n_pairs * k + n_pairs + n_pairs * d + mutation, mutation


@njit(cache=True)
def ga_offspring(X, F, k, R, pc, eta_c, pm, eta_m, lower, upper, children):  # noqa: ANN001, ANN201
    """Fill ``children`` (``(n_off, d)``): binary tournaments, SBX, clip, polynomial mutation.

    ``R`` holds :func:`ga_draws` uniforms (``n_pairs = ceil(n_off / 2)``), used in this order:

    * ``2 n_pairs k`` tournament entrants, ``floor(u * n)``; the lowest cost wins (the first
      on ties);
    * per pair, ``u < pc``: the pair crosses (Deb & Agrawal 1995, SBX);
    * per pair and coordinate, ``u < 1/2``: the coordinate is recombined, with ``u' = 2 u``
      (uniform in [0, 1) given ``u < 1/2``) as SBX's spread variable:
      ``beta = (2 u')^(1/(eta+1))`` if ``u' <= 1/2`` else ``(1 / (2 (1 - u')))^(1/(eta+1))``,
      children ``mean +- beta (p1 - p2) / 2`` (rows ``q`` and ``n_pairs + q``; the last one
      is dropped when ``n_off`` is odd), then clipped into the box;
    * the rest: the mutation, see :func:`ga_mutate`.

    Reusing the crossover test's uniform, rescaled, as the spread variable is exact in
    distribution. Returns :func:`ga_mutate`'s position (``< n_off * d`` if the batch ran out).
    """
    n, d = X.shape
    n_off = children.shape[0]
    n_pairs = (n_off + 1) // 2
    pos = 0
    winners = np.empty(2 * n_pairs, dtype=np.int64)
    for t in range(2 * n_pairs):
        best = _index(R[pos], n)
        pos += 1
        for _ in range(1, k):
            e = _index(R[pos], n)
            pos += 1
            if F[e] < F[best]:
                best = e
        winners[t] = best
    e_c = 1.0 / (eta_c + 1.0)
    cross_at = pos
    pos += n_pairs
    for q in range(n_pairs):
        a, b = winners[q], winners[n_pairs + q]
        crosses = R[cross_at + q] < pc
        second = n_pairs + q < n_off
        for j in range(d):
            u = R[pos]
            pos += 1
            mean = 0.5 * (X[a, j] + X[b, j])
            half = 0.5 * (X[a, j] - X[b, j])
            if crosses and u < 0.5:
                u = 2.0 * u
                beta = _pow(2.0 * u, e_c) if u <= 0.5 else _pow(0.5 / (1.0 - u), e_c)
                half *= beta
            children[q, j] = min(max(mean + half, lower[j]), upper[j])
            if second:
                children[n_pairs + q, j] = min(max(mean - half, lower[j]), upper[j])
    return ga_mutate(children, R[pos:], 0, pm, eta_m, lower, upper)


@njit(cache=True)
def ga_mutate(children, R, start, pm, eta_m, lower, upper):  # noqa: ANN001, ANN201
    """Bounded polynomial mutation (Deb & Goyal 1996; bounded form of Deb & Deb 2014), each
    coordinate with probability ``pm``, in place, from flat coordinate ``start`` on.

    The mutated coordinates are found by geometric skipping: the number of untouched
    coordinates before the next mutated one is ``floor(log(1 - u) / log(1 - pm))``, which is
    exactly the gap of independent per-coordinate trials, so a generation needs about two
    uniforms per mutation (gap, then the mutation's own ``u``) instead of one per
    coordinate. Returns the flat position reached: ``n_off * d`` when done, less when ``R``
    ran out (the caller continues with a fresh batch).
    """
    n, d = children.shape
    total = n * d
    if pm <= 0.0:
        return total
    log_q = np.log1p(-pm)  # -inf for pm = 1: every gap is 0
    e_m = 1.0 / (eta_m + 1.0)
    pos = start
    r = 0
    while r + 1 < R.shape[0]:
        gap = np.log(1.0 - R[r]) / log_q
        if pos + gap >= total:  # compared as floats: a gap can exceed any integer
            return total
        c = pos + int(gap)
        i, j = c // d, c % d
        u = R[r + 1]
        r += 2
        lo, hi = lower[j], upper[j]
        span = hi - lo if hi > lo else 1.0
        x = children[i, j]
        # Deb's two branches folded into one: v = min(u, 1 - u), dist = delta1 or delta2
        left = u < 0.5
        v = u if left else 1.0 - u
        dist = (x - lo) / span if left else (hi - x) / span
        val = 2.0 * v + (1.0 - 2.0 * v) * _pow(1.0 - dist, eta_m + 1.0)
        mag = 1.0 - _pow(val, e_m)
        y = x - mag * span if left else x + mag * span
        children[i, j] = min(max(y, lo), hi)
        pos = c + 1
    return pos


@njit(cache=True)
def ga_survivors(X, F, children, Fc):  # noqa: ANN001, ANN201
    """In place: the population becomes its ``n - n_off`` lowest-cost members (the elite, in
    ``argsort(kind="stable")`` order) followed by the children."""
    n, d = X.shape
    elite = n - children.shape[0]
    keep = np.empty((elite, d))
    keep_f = np.empty(elite)
    taken = np.empty(n, dtype=np.bool_)  # (np.empty + a loop: np.zeros/np.full compile slower)
    for i in range(n):
        taken[i] = False
    for e in range(elite):
        best = -1
        for i in range(n):
            if not taken[i] and (best < 0 or F[i] < F[best]):
                best = i
        taken[best] = True
        keep_f[e] = F[best]
        for j in range(d):
            keep[e, j] = X[best, j]
    # plain loops: numba's array slice assignment takes seconds to compile
    for e in range(elite):
        F[e] = keep_f[e]
        for j in range(d):
            X[e, j] = keep[e, j]
    for i in range(children.shape[0]):
        F[elite + i] = Fc[i]
        for j in range(d):
            X[elite + i, j] = children[i, j]


# --------------------------------------------------------------------------- ABC


@njit(cache=True)
def abc_moves(X, fit, R, onlookers, lower, upper, V, src):  # noqa: ANN001, ANN201
    """Candidates ``v_ij = x_ij + phi (x_ij - x_kj)`` (Karaboga & Basturk 2007), one per bee.

    ``R`` is ``(4, m)`` uniforms. Employed bees (``onlookers`` false, ``m = SN``) start from
    source ``i``; onlookers pick their source by roulette on ``fit(f) = 1/(1+f)`` for
    ``f > 0`` else ``1+|f|`` (paper 000 eq 20; non-finite fitness counts 0, uniform choice if
    all are 0) with ``R[3]``. Per bee: partner ``k != i`` from ``R[0]``, dimension ``j`` from
    ``R[1]``, ``phi = -1 + 2 R[2]`` (``U(-1, 1)``); the changed coordinate is clipped into the
    box. Writes the candidates into ``V`` (``(m, d)``) and their sources into ``src``.
    """
    sn, d = X.shape
    m = R.shape[1]
    if onlookers:
        cdf = np.empty(sn)
        total = fitness_cumsum(fit, cdf)
        for i in range(sn):
            cdf[i] = cdf[i] / total if total > 0 else (i + 1.0) / sn
        for b in range(m):
            u = R[3, b]
            s = 0
            while s < sn - 1 and cdf[s] <= u:  # np.searchsorted(cdf, u, side="right")
                s += 1
            src[b] = s
    else:
        for b in range(m):
            src[b] = b
    for b in range(m):
        s = src[b]
        k = _index(R[0, b], sn - 1)
        k += k >= s  # a partner other than the source itself
        j = _index(R[1, b], d)
        phi = -1.0 + 2.0 * R[2, b]
        for c in range(d):
            V[b, c] = X[s, c]
        val = X[s, j] + phi * (X[s, j] - X[k, j])
        V[b, j] = min(max(val, lower[j]), upper[j])


@njit(cache=True)
def abc_greedy(X, fit, trial, src, V, fv):  # noqa: ANN001, ANN201
    """Greedy selection, in place: each source keeps the best candidate built from it (the
    first on ties) if that beats it (trial counter reset), else its counter grows by one;
    sources no bee tried are left alone. Returns the index of the largest trial counter."""
    sn, d = X.shape
    best = np.empty(sn, dtype=np.int64)
    for s in range(sn):
        best[s] = -1
    for b in range(src.shape[0]):
        s = src[b]
        if best[s] < 0 or fv[b] < fv[best[s]]:
            best[s] = b
    top = 0
    for s in range(sn):
        b = best[s]
        if b >= 0:
            if fv[b] < fit[s]:
                fit[s] = fv[b]
                for c in range(d):
                    X[s, c] = V[b, c]
                trial[s] = 0
            else:
                trial[s] += 1
        if trial[s] > trial[top]:
            top = s
    return top
