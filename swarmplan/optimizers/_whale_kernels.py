"""Compiled per-generation arithmetic of ``woa`` and ``rscdwoa`` (:mod:`swarmplan.optimizers.whale`).

Why numba here: with 30 whales every numpy call costs more than the arithmetic it does; one
WOA generation was ~25 numpy calls, an RSCDWOA generation with its differential-evolution
stage ~80: 6-9 µs of overhead per evaluation at d = 50 against the 1 µs target.
The random numbers are drawn by numpy in batches (passing the Generator into numba costs
~10 µs per call to unbox it) and the kernels repeat the numpy code's floating-point
operations in the same order. Random integers (partners, donors, the forced crossover
coordinate) come from uniforms of the batch, ``floor(u k)``: one ``integers`` call costs as
much as ~8 ``random`` calls of its size. An RSCDWOA generation is one ``rng.random`` call,
plus with the DE stage one more and the normals of the reverse search; same distributions,
another stream than the numpy code.
Which equation each step is: see the docstrings of :mod:`swarmplan.optimizers.whale`.
"""

from __future__ import annotations

import math

import numpy as np

from swarmplan.runtime.compiled import njit

#: Layout of the per-run constants vector ``c`` (one array instead of a dozen scalar
#: arguments: each argument costs numba's dispatcher ~0.1 µs).
C_B, C_ELL_LO, C_ELL_SPAN, C_Q_INCL, C_TENT, C_BETA, C_MU = range(7)
C_K, C_LAM, C_F, C_OMEGA, C_CRATE, C_ALPHA = range(7, 13)
N_C = 13
_TWO_PI = 2.0 * np.pi
_CHAOS_EPS = 1e-9  # whale._CHAOS_EPS


@njit(cache=True, nogil=True)
def _clip(x, lo, hi):  # noqa: ANN001, ANN202
    # np.minimum(np.maximum(x, lo), hi) / np.clip for non-NaN values
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@njit(cache=True, nogil=True)
def _unit_index(x, k):  # noqa: ANN001, ANN202
    # floor(x k) for x in [0, 1): a uniform index in range(k)
    return min(int(x * k), k - 1)


@njit(cache=True, nogil=True)
def woa_move(X, best, coef, qp, a, c, box, Xn, de_on, idx):  # noqa: ANN001, ANN201
    """WOA position update (eqs 2-10, RSCDWOA's 11, 12 and 15) of every whale into ``Xn``, clipped.

    ``coef`` rows 0-2 drive ``A = 2 a coef_0 - a``, ``C = 2 coef_1`` and the spiral parameter
    ``l = ell_lo + ell_span coef_2`` (uniform draws for WOA, chaotic values for RSCDWOA);
    ``q = qp[0]`` picks encircling (``q < 0.5``, or ``<= 0.5`` when ``c[C_Q_INCL]``) or the
    spiral; whale ``i``'s random partner is ``(i + o_i) % n`` with ``o_i = 1 + floor(qp[1, i]
    (n - 1))`` uniform in ``1..n-1`` (a uniform of the generation's one ``rng.random`` batch:
    one ``integers`` call costs as much as ~8 ``random`` calls of its size). With ``de_on``
    the encircling whales are instead listed in ``idx`` for the DE stage (their rows are left
    for it to fill) and their number is returned.
    """
    n, d = X.shape
    q, pu = qp[0], qp[1]
    b, ell_lo, ell_span = c[C_B], c[C_ELL_LO], c[C_ELL_SPAN]
    q_incl = c[C_Q_INCL] != 0.0
    two_a = 2.0 * a
    m = 0
    for i in range(n):
        enc = q[i] <= 0.5 if q_incl else q[i] < 0.5
        if enc and de_on:
            idx[m] = i
            m += 1
            continue
        if enc:
            A = two_a * coef[0, i] - a
            C = 2.0 * coef[1, i]
            p = -1  # encircle X_* (|A| < 1) or search for prey around a random other whale
            if abs(A) >= 1.0:
                p = (i + 1 + _unit_index(pu[i], n - 1)) % n
            for j in range(d):
                ref = X[p, j] if p >= 0 else best[j]
                x = ref - A * abs(C * ref - X[i, j])
                Xn[i, j] = _clip(x, box[0, j], box[1, j])
        else:
            ell = ell_lo + ell_span * coef[2, i]
            fac = math.exp(b * ell) * math.cos(_TWO_PI * ell)
            for j in range(d):
                x = abs(best[j] - X[i, j]) * fac + best[j]
                Xn[i, j] = _clip(x, box[0, j], box[1, j])
    return m


@njit(cache=True, nogil=True)
def settle(X, F, Xn, Fn, idx, m, z, box, Xr, best_x, best_f):  # noqa: ANN001, ANN201
    """After the generation's evaluation: the DE whales' greedy selection (eq 23, the trial
    wins ties), the ``X*`` update, and the DE whales' secondary reflection reverse points
    (eq 16, ``whale.secondary_reflection`` with the normal draws ``z``) into ``Xr``.

    ``idx[:m]`` are the DE whales (``m = 0``: plain WOA generation). Returns the best cost.
    """
    d = X.shape[1]
    for t in range(m):
        i = idx[t]
        if Fn[i] > F[i]:
            Fn[i] = F[i]
            for j in range(d):
                Xn[i, j] = X[i, j]
    best_f = _update_best(Xn, Fn, best_x, best_f)
    for t in range(m):
        i = idx[t]
        for j in range(d):
            h = 0.5 * (box[0, j] + box[1, j])
            x = Xn[i, j]
            mid = 0.5 * (x + h)
            half = 0.5 * abs(h - x)
            Xr[t, j] = _clip(mid + (half / 3.0) * z[t, j], mid - half, mid + half)
    return best_f


@njit(cache=True, nogil=True)
def _update_best(X, F, best_x, best_f):  # noqa: ANN001, ANN202
    k = -1
    for i in range(F.size):  # first index of the minimum, taken only when it beats X*
        if F[i] < best_f:
            best_f = F[i]
            k = i
    if k >= 0:
        for j in range(X.shape[1]):
            best_x[j] = X[k, j]
    return best_f


@njit(cache=True, nogil=True)
def reverse_accept(Xn, Fn, idx, Xr, Fr, best_x, best_f):  # noqa: ANN001, ANN201
    """Reverse points that are strictly better replace their whale; then the ``X*`` update."""
    d = Xn.shape[1]
    for t in range(Fr.size):
        i = idx[t]
        if Fr[t] < Fn[i]:
            Fn[i] = Fr[t]
            for j in range(d):
                Xn[i, j] = Xr[t, j]
    return _update_best(Xn, Fn, best_x, best_f)


@njit(cache=True, nogil=True)
def chaos_advance(w, c, dead):  # noqa: ANN001, ANN201
    """One step of every chaotic sequence in ``w`` (eq 14 tent or eq 13 logistic), in place.

    Marks in ``dead`` the values that left (0, 1), hit a fixed point or are not finite (see
    ``whale.chaos_step``, which restarts them from fresh draws) and returns their number.
    """
    tent = c[C_TENT] != 0.0
    beta, mu = c[C_BETA], c[C_MU]
    count = 0
    for r in range(w.shape[0]):
        for i in range(w.shape[1]):
            v = w[r, i]
            if tent:
                nxt = v / beta if v < beta else (1.0 - v) / (1.0 - beta)
            else:
                nxt = mu * v * (1.0 - v)
            bad = nxt <= _CHAOS_EPS or nxt >= 1.0 - _CHAOS_EPS or nxt == v or not np.isfinite(nxt)
            dead[r, i] = bad
            count += bad
            w[r, i] = nxt
    return count


#: Uniforms one DE whale takes (:func:`de_trials`) besides its ``3 d`` per-coordinate
#: draws: ``p1``, ``p2``, ``r1``, ``r2``, ``chi``.
DE_SCALARS = 5


@njit(cache=True, nogil=True)
def de_trials(X, F, idx, m, u, c, box, Xn):  # noqa: ANN001, ANN201
    """DE trial vectors (eqs 17-22) of the ``m`` whales ``idx[:m]`` into their rows of ``Xn``, clipped.

    ``u`` is the DE stage's one uniform batch, ``DE_SCALARS + 3 d`` values per whale, whale
    after whale: the neighbours ``p1 != p2`` of eq (18) and the random whales ``r1 != r2``
    (both ``!= i``) of eq (19) as uniform indices, the forced coordinate ``chi`` of eq (21);
    then per coordinate ``gamma_1 / lambda`` and ``gamma_2 / lambda`` (eq 17) and one draw
    ``v`` for both the perturbation (eq 22) and the crossover (eq 21). The perturbation,
    probability ``alpha``, overwrites whatever the crossover chose, so per coordinate the
    outcomes are: perturbed (``alpha``), else ``V`` or ``X_i`` as the crossover decides. One
    uniform gives exactly that: ``v < alpha`` perturbs, to the box point
    ``lower + (v / alpha) span`` (``v / alpha`` is uniform in [0, 1) given ``v < alpha``);
    otherwise ``w = (v - alpha) / (1 - alpha)`` is uniform in [0, 1) and independent of the
    perturbation test, and is the crossover draw (take ``V`` when ``w <= C_rate`` or
    ``j = chi``). Same distribution as two independent draws, half the uniforms.
    """
    n, d = X.shape
    k = int(c[C_K])
    width = 2 * k + 1
    lam, Fs, omega, c_rate, alpha = c[C_LAM], c[C_F], c[C_OMEGA], c[C_CRATE], c[C_ALPHA]
    one_m_omega = 1.0 - omega
    per = DE_SCALARS + 3 * d
    keep = 1.0 - alpha  # probability of no perturbation (alpha = 1: every v < alpha)
    g = 0  # population best (first index of the minimum)
    for i in range(n):
        if F[i] < F[g]:
            g = i
    for t in range(m):
        i = idx[t]
        b = t * per
        # ring neighbourhood [i-k, i+k] (Fig. 4): its best member lb, and two distinct
        # members p1 != p2 drawn uniformly from it
        lb = (i - k) % n
        for cc in range(1, width):
            j = (i + cc - k) % n
            if F[j] < F[lb]:
                lb = j
        s1 = _unit_index(u[b], width)
        s2 = _unit_index(u[b + 1], width - 1)
        s2 += 1 if s2 >= s1 else 0
        p1 = (i + s1 - k) % n
        p2 = (i + s2 - k) % n
        # r1 != r2, both != i: offsets 1..n-1 and 1..n-2 (the second skips the first's)
        o1 = 1 + _unit_index(u[b + 2], n - 1)
        o2 = 1 + _unit_index(u[b + 3], n - 2)
        o2 += 1 if o2 >= o1 else 0
        r1 = (i + o1) % n
        r2 = (i + o2) % n
        chi = _unit_index(u[b + 4], d)
        b += DE_SCALARS
        for j in range(d):
            xi = X[i, j]
            g1 = lam * u[b + j]
            g2 = lam * u[b + d + j]
            L = xi + g1 * (X[lb, j] - xi) + g2 * (X[p1, j] - X[p2, j])  # eq (18)
            G = X[g, j] + Fs * (X[g, j] - xi) + Fs * (X[r1, j] - X[r2, j])  # eq (19)
            V = omega * G + one_m_omega * L  # eq (20)
            v = u[b + 2 * d + j]
            if v < alpha:  # eq (22): perturbed to a uniform point of the box
                x = box[0, j] + (v / alpha) * box[2, j]
            elif (v - alpha) / keep <= c_rate or j == chi:  # eq (21): the donor's coordinate
                x = V
            else:
                x = xi
            Xn[i, j] = _clip(x, box[0, j], box[1, j])
