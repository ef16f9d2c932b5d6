"""Compiled kernel for the pairwise gravity weights of eq 14 (``central_force.cfo_weights``).

Why numba here: the weights are a dozen elementwise operations on ``n x n`` arrays (mass
differences, the unit step, squared distances from the Gram matrix, the quotient, the mask),
each a separate numpy call with its own temporary: ~150 µs per generation at 100 probes,
1.5 µs per evaluation, most of CFO's overhead. One pass over the pairs does the same
arithmetic in ~10-20 µs. The ``n x n x d`` parts (the Gram matrix ``U U^T`` and ``W U``) stay
in BLAS, which numba loops cannot beat. The operations and their order are numpy's, so the
weights are bit-identical to the numpy version (no fastmath). numba is imported on the first
CFO/MCFO generation (``cache=True`` keeps the compiled code on disk), not with the package.
"""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True, inline="always")
def _repair(x, u, frep):  # noqa: ANN001, ANN202
    """Eq 16: a coordinate ``x`` that left the unit box goes back a fraction ``frep`` of the
    way from its old position ``u`` to the face it crossed."""
    out = x
    if x < 0.0:
        out = 0.0 + frep * (u - 0.0)
    if x > 1.0:
        out = 1.0 - frep * (1.0 - u)
    return out


@njit(cache=True, nogil=True, inline="always")
def _to_box(out, lower, span, upper):  # noqa: ANN001, ANN202
    """A unit-box coordinate in the problem's box, clipped to it (``_to_box`` of central_force)."""
    y = lower + out * span
    if y < lower:
        y = lower
    if y > upper:
        y = upper
    return y


@njit(cache=True, nogil=True)
def gravity_weights(F, sq, gram, inv_scale, G, alpha, beta, W):  # noqa: ANN001, ANN201
    """``W[i, k] = G * ((f_i - f_k) * inv_scale)**alpha / dist_ik**beta`` where probe ``k`` is
    better (difference > 1e-100) and not coincident (squared distance > 1e-24), else 0.
    ``dist_ik**2 = max(sq_i + sq_k - 2 gram_ik, 0)``. Writes into ``W`` (n x n)."""
    n = F.shape[0]
    for i in range(n):
        fi = F[i]
        si = sq[i]
        for k in range(n):
            diff = (fi - F[k]) * inv_scale
            d2 = si + sq[k] - 2.0 * gram[i, k]
            if d2 < 0.0:
                d2 = 0.0
            if diff > 1e-100 and d2 > 1e-24:
                num = diff * diff if alpha == 2.0 else diff**alpha
                den = d2 if beta == 2.0 else np.sqrt(d2) ** beta
                W[i, k] = (G * num) / den
            else:
                W[i, k] = 0.0
    return W


@njit(cache=True, nogil=True)
def rank_masses(F, out):  # noqa: ANN001, ANN201
    """``masses(F, "rank")`` in one pass: average ranks (ties averaged) of ``F`` with infinite
    costs replaced by the worst finite one (all infinite: all zero), minus 1, over ``n - 1``.

    Ranks are half-integers, exact in any order of operations, so the values equal
    ``central_force.average_ranks`` (scipy's ``rankdata``) to the bit.
    """
    n = F.shape[0]
    G = np.empty(n)
    worst = -np.inf
    anyfinite = False
    for i in range(n):
        if np.isfinite(F[i]):
            anyfinite = True
            if F[i] > worst:
                worst = F[i]
    for i in range(n):
        if not anyfinite:
            G[i] = 0.0
        elif np.isfinite(F[i]):
            G[i] = F[i]
        else:
            G[i] = worst
    # counting instead of sorting: n**2 comparisons (~10 µs at 100 probes) compile in a
    # fraction of a second, numba's argsort takes ~3 s
    for i in range(n):
        less = 0
        equal = 0
        for k in range(n):
            if G[k] < G[i]:
                less += 1
            elif G[k] == G[i]:
                equal += 1
        # ties at sorted positions less+1 .. less+equal get their mean rank
        rank = 0.5 * (less + (less + equal) + 1)
        out[i] = (rank - 1.0) / max(n - 1, 1)
    return out


@njit(cache=True, nogil=True)
def move_probes(U, WU, rowsum, dt2, memory, frep, box, out):  # noqa: ANN001, ANN201
    """One CFO/MCFO move for every probe, in the arithmetic order of the numpy expressions
    it replaces (bit-identical): gravity ``a = WU - rowsum * U`` (eq 14); CFO (``s`` empty)
    ``U + (0.5 * a) * dt2``; MCFO (eq 23) ``U + ((s_i * 0.5) * dt2) * a + (c1 * r1_i) *
    (pbest - U) + (c2 * r2_i) * (gbest - U)`` with ``r1 = r[0], r2 = r[1]``, ``memory = (s,
    pbest, gbest, r, c1, c2)``; eq 16 repair in the unit box (old position ``U``), then the box
    position ``clip(lower + u * span)``, ``box = (lower, span, upper)``, into ``out = (Unew,
    Xnew)``."""
    s, pbest, gbest, r, c1, c2 = memory
    lower, span, upper = box
    Unew, Xnew = out
    n, d = U.shape
    mcfo = s.shape[0] > 0
    for i in range(n):
        for j in range(d):
            u = U[i, j]
            a = WU[i, j] - rowsum[i] * u
            if mcfo:
                x = u + ((s[i] * 0.5) * dt2) * a
                x = x + (c1 * r[0, i]) * (pbest[i, j] - u)
                x = x + (c2 * r[1, i]) * (gbest[j] - u)
            else:
                x = u + (0.5 * a) * dt2
            x = _repair(x, u, frep)
            Unew[i, j] = x
            Xnew[i, j] = _to_box(x, lower[j], span[j], upper[j])


@njit(cache=True, nogil=True)
def move_probes_steps(U, WU, rowsum, dt2, memory, frep, box, out):  # noqa: ANN001, ANN201
    """MCFO's move with 004 step 4 read as two moves (``update="steps"``), arguments as
    :func:`move_probes`: first the gravity move ``y = U + ((s_i * 0.5) * dt2) * a`` repaired
    with eq 16 (old position ``U``), then eq 18 on it, ``y + (c1 * r1_i) * (pbest - y) +
    (c2 * r2_i) * (gbest - y)``, repaired with old position ``y``. A kernel of its own so that
    the default move's loop stays as it was (a flag in it cost CFO ~0.1 µs per evaluation)."""
    s, pbest, gbest, r, c1, c2 = memory
    lower, span, upper = box
    Unew, Xnew = out
    n, d = U.shape
    for i in range(n):
        for j in range(d):
            u = U[i, j]
            a = WU[i, j] - rowsum[i] * u
            x = _repair(u + ((s[i] * 0.5) * dt2) * a, u, frep)
            u = x
            x = x + (c1 * r[0, i]) * (pbest[i, j] - u)
            x = x + (c2 * r[1, i]) * (gbest[j] - u)
            x = _repair(x, u, frep)
            Unew[i, j] = x
            Xnew[i, j] = _to_box(x, lower[j], span[j], upper[j])


@njit(cache=True, nogil=True)
def update_pbest(U, F, pbest_U, pbest_F):  # noqa: ANN001, ANN201
    """Personal bests where ``F < pbest_F``; returns ``argmin(pbest_F)`` (first on ties)."""
    n, d = U.shape
    for i in range(n):
        if F[i] < pbest_F[i]:
            pbest_F[i] = F[i]
            for j in range(d):
                pbest_U[i, j] = U[i, j]
    best = 0
    for i in range(n):
        if pbest_F[i] < pbest_F[best]:
            best = i
    return best


@njit(cache=True, nogil=True)
def mutation_candidates(F, F_old, zeta, c3, idx):  # noqa: ANN001, ANN201
    """Eq 19's selection: the probes with ``zeta_i <= c3`` whose new cost is worse than their
    old one (strict), in index order, into ``idx``; returns how many."""
    k = 0
    for i in range(F.shape[0]):
        if zeta[i] <= c3 and F[i] > F_old[i]:
            idx[k] = i
            k += 1
    return k


@njit(cache=True, nogil=True)
def mutate_probes(new, idx, v, factor, span_div, frep, lower, span, upper, X):  # noqa: ANN001, ANN201
    """Eq 19 for the probes ``idx`` (in place on ``new``): ``xi = v - 0.5`` from ``v ~ U[0, 1)``
    (the same floats as ``rng.uniform(-0.5, 0.5)``, which computes ``-0.5 + 1.0 * u``),
    ``m = (xi * factor)`` (``/ span_div`` when ``span_div`` is not empty: ``xi`` in the
    problem's units), eq 16 repair of ``new + m`` with old position ``new``, box positions in
    ``X``."""
    d = new.shape[1]
    raw = span_div.shape[0] > 0
    for a in range(idx.shape[0]):
        i = idx[a]
        for j in range(d):
            m = (v[a, j] - 0.5) * factor
            if raw:
                m = m / span_div[j]
            u = new[i, j]
            x = u + m
            out = _repair(x, u, frep)
            new[i, j] = out
            X[a, j] = _to_box(out, lower[j], span[j], upper[j])
