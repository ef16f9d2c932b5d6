"""Compiled steps of AFSA / IAFSA (:mod:`swarmplan.optimizers.fish_swarm`, paper 002).

Why numba here (target: optimizer overhead <= 1 µs per evaluation at d = 50): a fish
generation was ~150 numpy calls (views, centres, the prey rounds with fancy indexing, three
kinds of moves, concatenation, selection), at ~1 µs each before they touch a number, for
~150 evaluations. The kernels below do the per-fish work in a few passes; random numbers
are drawn in numpy, batched per round, and passed in (a ``Generator`` argument costs ~20 µs
per call to unbox, see ``core.Problem``). The Gram matrix stays in BLAS.

The numpy definitions these follow are ``fish_swarm.neighbours``, ``swarm_centres``,
``best_in_view``, ``in_view`` and ``toward`` (tests compare them).
"""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import njit


@njit(cache=True, nogil=True)
def fish_view(U, F, sq, gram, vis, delta, centres, best, flags):  # noqa: ANN001, ANN201
    """Per fish ``i``: the fish ``k != i`` with ``|u_k - u_i| <= vis_i`` (distance from the Gram
    matrix, as ``neighbours``); ``centres[i]`` their mean (eq 19), ``best[i]`` the best of them
    (eq 18; first on ties); ``flags[0, i]``: swarming may be tried (someone in view, not
    crowded: ``n_f / n < delta``); ``flags[1, i]``: following may be tried (also: the best in
    view is better than fish ``i``). ``centres[i]`` is left untouched where swarming may not be
    tried: a crowded view (every fish in view of every other, as in high dimension with the
    box-diagonal Visual) would cost ``n^2 d`` additions for nothing."""
    n, d = U.shape
    for i in range(n):
        nf = 0
        b = -1
        for k in range(n):
            if k != i and _sees(sq, gram, vis, i, k):
                nf += 1
                if b < 0 or F[k] < F[b]:
                    b = k
        ok = nf > 0 and nf / n < delta
        flags[0, i] = ok
        flags[1, i] = ok and F[b] < F[i]
        best[i] = b if b >= 0 else 0
        if ok:  # second pass, same order of additions as one pass would make
            for j in range(d):
                centres[i, j] = 0.0
            for k in range(n):
                if k != i and _sees(sq, gram, vis, i, k):
                    for j in range(d):
                        centres[i, j] += U[k, j]
            for j in range(d):
                centres[i, j] /= nf


@njit(cache=True, nogil=True)
def _sees(sq, gram, vis, i, k):  # noqa: ANN001, ANN202
    d2 = sq[i] + sq[k] - 2.0 * gram[i, k]
    if d2 < 0.0:
        d2 = 0.0
    return np.sqrt(d2) <= vis[i]


#: how the rows of ``G`` become eq 16 / eq 21 offsets (see ``fish_swarm.in_view``)
CUBE = 0  # prey_region="cube": per-coordinate uniform in [-radius, radius], G uniform in [0, 1)
BALL_CUBE_DIRECTION = 1  # ball, direction = unit(2 G - 1) with G uniform in [0, 1)
BALL_NORMAL_DIRECTION = 2  # ball, direction = unit(G) with G standard normal (isotropic)


@njit(cache=True, nogil=True)
def _dir(G, a, j, mode):  # noqa: ANN001, ANN202
    # coordinate j of row a's direction before normalisation: -1 + 2u reproduces
    # rng.uniform(-1, 1) bit for bit from the same rng.random draws
    if mode == BALL_NORMAL_DIRECTION:
        return G[a, j]
    return -1.0 + 2.0 * G[a, j]


@njit(cache=True, nogil=True)
def _row_norm(G, a, mode, d):  # noqa: ANN001, ANN202
    if mode == CUBE:
        return 1.0
    s = 0.0
    for j in range(d):
        g = _dir(G, a, j, mode)
        s += g * g
    s = np.sqrt(s)
    return s if s > 0.0 else 1.0


@njit(cache=True, nogil=True)
def _offset(G, a, radius, length, mode, j, norm):  # noqa: ANN001, ANN202
    # eq 16 / eq 21 offset coordinate j (see fish_swarm.in_view): ball = unit direction times
    # radius * rand(0, 1); cube = per-coordinate uniform in [-radius, radius]
    if mode == CUBE:
        return radius * _dir(G, a, j, mode)
    return (_dir(G, a, j, mode) / norm) * (radius * length)


@njit(cache=True, nogil=True)
def prey_tries(U, fish, vis, G, lens, mode, T, X, lower, span):  # noqa: ANN001, ANN201
    """One round of eq 16 tries, row ``a`` for fish ``fish[a]``: ``u + offset`` (radius
    ``vis``, directions from the first ``d`` columns of ``G`` as ``mode`` says, lengths
    ``lens``) clipped to the unit box in ``T``, and its box position in ``X``."""
    d = U.shape[1]
    for a in range(fish.shape[0]):
        i = fish[a]
        norm = _row_norm(G, a, mode, d)
        for j in range(d):
            t = U[i, j] + _offset(G, a, vis[i], lens[a], mode, j, norm)
            if t < 0.0:
                t = 0.0
            if t > 1.0:
                t = 1.0
            T[a, j] = t
            X[a, j] = lower[j] + t * span[j]


@njit(cache=True, nogil=True)
def prey_hits(FT, F, fish, searching, T, target, found):  # noqa: ANN001, ANN201
    """Eqs 16-17's sequential rule for one round: prey fish ``p = searching[a]`` (fish
    ``fish[a]``) stops at its first try better than its cost (``target[p] = T[a]``); the
    others stay, compacted at the front of ``searching``. Returns how many still search."""
    keep = 0
    for a in range(searching.shape[0]):
        p = searching[a]
        if FT[a] < F[fish[a]]:
            found[p] = True
            for j in range(T.shape[1]):  # an explicit loop: slice assignment costs ~3 s to compile
                target[p, j] = T[a, j]
        else:
            searching[keep] = p
            keep += 1
    return keep


@njit(cache=True, nogil=True)
def _toward(U, i, tgt, k, scale, M, row):  # noqa: ANN001, ANN202
    # eqs 17, 18, 20: u_i + unit(tgt_k - u_i) * scale (zero direction when they coincide);
    # rows by index, not as slices (array views cost compile time)
    d = U.shape[1]
    s = 0.0
    for j in range(d):
        v = tgt[k, j] - U[i, j]
        s += v * v
    s = np.sqrt(s)
    for j in range(d):
        v = tgt[k, j] - U[i, j]
        M[row, j] = U[i, j] + ((v / s) if s > 1e-300 else 0.0) * scale


@njit(cache=True, nogil=True)
def fish_moves(U, centres, best, flags, prey, best_U, steps, draws, enhanced, box, out, rows):  # noqa: ANN001, ANN201
    """All moves of a generation, one row each, fish by fish: swarm (eq 20, towards
    ``centres[i]``), follow (eq 18; ``enhanced``: IAFSA's eqs 29-30 with the bulletin board
    ``best_U``), prey (eq 17 towards ``target``, ``prey = (prey_pos, target, found)``) or, when
    no try was better, a random move of at most ``rand_radius`` (eq 21: ``Step``, or ``Visual``
    with ``random_move="visual"``; ``steps = (step, rand_radius)``; directions from ``G`` row by
    row as ``mode`` says). ``u[row]`` is the move's ``rand(0, 1)`` (IAFSA following: its ``R``;
    random move: its length; ``draws = (u, G, mode)``). Rows are clipped to the unit box (``M``)
    and mapped to the box (``X``; ``box = (lower, span)``, ``out = (M, X)``). ``rows[0, i]`` /
    ``rows[1, i]`` are the rows of fish ``i``'s swarming / following outcome (the prey row when
    it fell back)."""
    prey_pos, target, found = prey
    step, rand_radius = steps
    u, G, mode = draws
    lower, span = box
    M, X = out
    n, d = U.shape
    row = 0
    g = 0
    for i in range(n):
        if flags[0, i]:
            _toward(U, i, centres, i, step[i] * u[row], M, row)
            rows[0, i] = row
            row += 1
        if flags[1, i]:
            b = best[i]
            if enhanced:
                R = u[row]
                s1 = 0.0
                s2 = 0.0
                for j in range(d):
                    v1 = U[b, j] - U[i, j]
                    v2 = best_U[j] - U[i, j]
                    s1 += v1 * v1
                    s2 += v2 * v2
                s1 = np.sqrt(s1)
                s2 = np.sqrt(s2)
                for j in range(d):
                    e1 = (U[b, j] - U[i, j]) / s1 if s1 > 1e-300 else 0.0
                    e2 = (best_U[j] - U[i, j]) / s2 if s2 > 1e-300 else 0.0
                    M[row, j] = U[i, j] + step[i] * (R * e1 + (1.0 - R) * e2)
            else:
                _toward(U, i, U, b, step[i] * u[row], M, row)
            rows[1, i] = row
            row += 1
        p = prey_pos[i]
        if p >= 0:
            if found[p]:
                _toward(U, i, target, p, step[i] * u[row], M, row)
            else:
                norm = _row_norm(G, g, mode, d)
                for j in range(d):
                    M[row, j] = U[i, j] + _offset(G, g, rand_radius[i], u[row], mode, j, norm)
                g += 1
            if not flags[0, i]:
                rows[0, i] = row
            if not flags[1, i]:
                rows[1, i] = row
            row += 1
    for r in range(row):
        for j in range(d):
            t = M[r, j]
            if t < 0.0:
                t = 0.0
            if t > 1.0:
                t = 1.0
            M[r, j] = t
            X[r, j] = lower[j] + t * span[j]


@njit(cache=True, nogil=True)
def fish_select(M, FM, rows, U, F):  # noqa: ANN001, ANN201
    """Algorithm A1 line 16: each fish takes the better of its swarming and following
    outcomes (following only if strictly better); writes ``U`` and ``F``."""
    n, d = U.shape
    for i in range(n):
        r = rows[0, i]
        if FM[rows[1, i]] < FM[r]:
            r = rows[1, i]
        F[i] = FM[r]
        for j in range(d):
            U[i, j] = M[r, j]


@njit(cache=True, nogil=True)
def spiral_visual(U, best_U, u, b, v0, absolute, hbar, vis, stp):  # noqa: ANN001, ANN201
    """IAFSA's eq 28 and eq 31 per fish: ``w = 2 u - 1`` (bit for bit ``rng.uniform(-1, 1)``
    from the same draws), ``Dis_i = |u_i - X_gm|``, ``vis_i = Dis_i e^{b w} cos(2 pi w)``
    (its absolute value with ``absolute``) ``+ v0``, ``stp_i = vis_i / hbar``. One pass instead
    of ~10 numpy calls per generation."""
    n, d = U.shape
    for i in range(n):
        w = -1.0 + 2.0 * u[i]
        s = 0.0
        for j in range(d):
            v = U[i, j] - best_U[j]
            s += v * v
        spiral = np.sqrt(s) * np.exp(b * w) * np.cos(2.0 * np.pi * w)
        if absolute:
            spiral = abs(spiral)
        vis[i] = spiral + v0
        stp[i] = vis[i] / hbar
