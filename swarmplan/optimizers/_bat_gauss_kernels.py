"""Compiled steps of ``iba_gauss`` (:mod:`swarmplan.optimizers.bat_gauss`, paper 003).

Why numba here (target: optimizer overhead <= 1 µs per evaluation at d = 50): a generation
of 100 bats was ~40 numpy calls on (n, d) arrays (velocity operator, Gaussian walk, masked
assignment, clip, acceptance with fancy indexing) at ~1 µs each before they touch a number.
Two kernels do the same arithmetic in numpy's operation order (bit-identical, no fastmath);
the random numbers are drawn in numpy in the same order as before and passed in (a
``Generator`` argument costs ~20 µs per call to unbox, see ``core.Problem``).
"""

from __future__ import annotations

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def move_bats(bats, best, op, w, freq, u, N, scale, box, cand):  # noqa: ANN001, ANN201
    """Steps 1-2 of a generation, in place on ``V``, ``cm`` and ``cand``; ``bats = (X, V, cm,
    fit, r)`` (positions, velocities, chaotic maps, costs, pulse rates), ``freq = (f_lo,
    f_span)``, ``box = (lower, upper)``.

    ``cm <- (4 cm)(1 - cm)``; ``V <- w V + mix`` with operator ``op`` (0: eq 18, 1: eqs 19-20,
    2: eq 21 with the worst bat); ``cand = X + V``, or where ``u[-1, i] > r_i`` the walk
    ``best + 0.5 (N[0, k] + 2 N[1, k]) * scale`` (eq 15), ``k`` counting the walking bats in
    order (``N`` has one row per walking bat); then clipped into the box. ``u[0]`` is the
    frequency draw ``beta`` of eqs 18 and 21 (unused by the chaotic operator)."""
    X, V, cm, fit, r = bats
    f_lo, f_span = freq
    lower, upper = box
    n, d = X.shape
    last = u.shape[0] - 1
    worst = 0
    if op == 2:
        for i in range(n):
            if fit[i] > fit[worst]:
                worst = i
    k = 0
    for i in range(n):
        c = cm[i]
        c = (4.0 * c) * (1.0 - c)
        cm[i] = c
        if op == 1:
            fi = c * (f_lo + f_span * c)
        else:
            fi = f_lo + f_span * u[0, i]
        local = u[last, i] > r[i]
        for j in range(d):
            if op == 2:
                mix = (X[i, j] - X[worst, j]) * fi
            else:
                mix = (best[j] - X[i, j]) * fi
            v = w * V[i, j] + mix
            V[i, j] = v
            x = X[i, j] + v
            if local:
                x = best[j] + (0.5 * (N[0, k, j] + 2.0 * N[1, k, j])) * scale[j]
            if x < lower[j]:
                x = lower[j]
            if x > upper[j]:
                x = upper[j]
            cand[i, j] = x
        if local:
            k += 1


@njit(cache=True, nogil=True)
def accept_bats(X, fit, A, r, cand, fc, u, own, best_f, alpha, floor, r_new):  # noqa: ANN001, ANN201
    """Eq 10 acceptance (``bat._bat_acceptance``) in place: where ``u_i < A_i`` and ``fc_i`` beats
    ``best_f`` (``own``: the bat's own cost), take the candidate, ``A_i <- max(A_i alpha, floor)``,
    ``r_i <- r_new``. Returns ``argmin(fc)`` (first on ties)."""
    n, d = X.shape
    for i in range(n):
        ref = fit[i] if own else best_f
        if u[i] < A[i] and fc[i] < ref:
            for j in range(d):
                X[i, j] = cand[i, j]
            fit[i] = fc[i]
            a = A[i] * alpha
            A[i] = a if a >= floor else floor
            r[i] = r_new
    k = 0
    for i in range(n):
        if fc[i] < fc[k]:
            k = i
    return k
