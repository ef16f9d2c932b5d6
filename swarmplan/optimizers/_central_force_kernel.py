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
from numba import njit


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
