"""Agent-agent queries through a k-d tree (``scipy.spatial.cKDTree``) instead of all pairs.

Each function returns exactly what its all-pairs counterpart returns (same pairs in the same
order, same values): the tree only proposes candidate pairs within a radius that provably
contains every pair the exact test can accept, and the exact test then runs on those.

- :func:`agent_contacts_indexed` ↔ ``geometry.collision.agent_contacts``;
- :func:`agent_clearance_indexed` ↔ ``Simulation._agent_clearance``;
- :func:`separation_violations` ↔ the ``inside`` matrix of ``Simulation._near_misses``.
"""

from __future__ import annotations

from functools import cache
from itertools import chain

import numpy as np

from swarmplan.geometry.collision import segment_segment_min_distance
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module, read_only, use_compiled, use_compiled_checks

SMALL = 32
"""Up to this many agents every pair is a candidate (cheaper than building a tree, and no
scipy.spatial import at start-up); the exact tests that follow give the same answers."""


@cache
def _all_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)``, kept per ``n`` (read-only)."""
    i, j = np.triu_indices(n, 1)
    i.setflags(write=False)
    j.setflags(write=False)
    return i, j


def _pairs(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i < j, sorted as ``np.triu_indices`` lists them: every pair closer than
    ``radius`` (and, for small or unbounded queries, the others too)."""
    if len(points) <= SMALL or not np.isfinite(radius):
        return _all_pairs(len(points))
    from scipy.spatial import cKDTree

    p = cKDTree(points).query_pairs(radius, output_type="ndarray")
    if not len(p):
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    i, j = np.minimum(p[:, 0], p[:, 1]), np.maximum(p[:, 0], p[:, 1])
    order = np.lexsort((j, i))
    return i[order].astype(np.intp), j[order].astype(np.intp)


def agent_contacts_indexed(
    p0: np.ndarray,
    p1: np.ndarray,
    radii: np.ndarray,
    active: np.ndarray,
    margin: float = 0.0,
    compiled: bool | None = None,
) -> list[tuple[int, int]]:
    """``agent_contacts`` with candidates from a sweep and prune on the step's midpoints (compiled,
    ``swept_kernels.agent_contacts``): two points moving along their steps stay within half of
    each step of their midpoints, so a contact needs the midpoints closer than both half-steps
    + both radii + ``margin``; the candidates' distances are ``segment_segment_min_distance``'s
    arithmetic, term for term, and the pairs come in ``np.triu_indices`` order. Below swarm size
    (``use_compiled_checks``, all ``n`` agents of the world in ``p0``) a tree's candidates and
    numpy's test give the same pairs. ``compiled``: the compiled path or not (None: by size; a
    world with fixed wings runs it at any size, ``runtime.compiled.use_compiled_checks``)."""
    n = len(p0)
    if n < 2:
        return []
    if not (use_compiled_checks(n) if compiled is None else compiled):
        half = 0.5 * norm3(p1 - p0)
        reach = 2.0 * float(half.max()) + 2.0 * float(radii.max()) + margin
        i, j = _pairs(0.5 * (p0 + p1), reach * (1.0 + 1e-9) + 1e-9)
        keep = active[i] | active[j]
        i, j = i[keep], j[keep]
        d = segment_segment_min_distance(p0[i], p1[i], p0[j], p1[j])
        hit = d < radii[i] + radii[j] + margin
        return list(zip(i[hit].tolist(), j[hit].tolist(), strict=True))
    i, j = kernel_module("swarmplan.geometry.swept_kernels").agent_contacts(  # one signature: read-only
        read_only(np.ascontiguousarray(p0, dtype=float)),
        read_only(np.ascontiguousarray(p1, dtype=float)),
        read_only(np.ascontiguousarray(radii, dtype=float)),
        read_only(np.ascontiguousarray(active, dtype=bool)),
        float(margin),
    )
    return list(zip(i.tolist(), j.tolist(), strict=True))


def agent_clearance_indexed(pos: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Per agent: min over the others of |p_i - p_j| - r_i - r_j (inf alone). The nearest
    centre is found first; a farther one can only win by the spread of the radii. Swarms
    from ``runtime.compiled.COMPILED_FROM`` agents on take a compiled sweep instead of the
    tree (the same values: each pair's as here, the minimum exact)."""
    n = len(pos)
    if n < 2:
        return np.full(n, np.inf)
    if n <= SMALL:
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (radius[:, None] + radius[None])
        np.fill_diagonal(d, np.inf)
        return d.min(axis=1)
    if use_compiled(n):
        out = np.empty(n)
        kernels = kernel_module("swarmplan.geometry._distance_kernels")
        kernels.agent_clearance(np.asarray(pos, dtype=float), np.asarray(radius, dtype=float), out)
        return out
    from scipy.spatial import cKDTree

    tree = cKDTree(pos)
    dn, _ = tree.query(pos, k=2)
    spread = float(radius.max() - radius.min())
    # Candidates of every agent in one flat list (row i repeated once per candidate), then one
    # array operation for their distances and a minimum per row.
    lists = tree.query_ball_point(pos, dn[:, 1] + spread + 1e-9 * (1.0 + dn[:, 1]), return_sorted=False)
    counts = np.fromiter(map(len, lists), dtype=np.intp, count=n)
    js = np.fromiter(chain.from_iterable(lists), dtype=np.intp, count=int(counts.sum()))
    ii = np.repeat(np.arange(n), counts)
    other = ii != js
    ii, js = ii[other], js[other]
    out = np.full(n, np.inf)
    np.minimum.at(out, ii, norm3(pos[ii] - pos[js]) - (radius[ii] + radius[js]))
    return out


def separation_violations(
    pos: np.ndarray, separation: np.ndarray, radius: np.ndarray, active: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j), i < j in triu order, inside each other's separation ellipsoid
    (|dp / (max(sep_i, sep_j) + r_i + r_j)| < 1) with at least one of them active."""
    n = len(pos)
    if n < 2:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    reach = float(separation.max()) + 2.0 * float(radius.max())
    i, j = _pairs(pos, reach * (1.0 + 1e-9) + 1e-9)
    scale = np.maximum(separation[i], separation[j]) + (radius[i] + radius[j])[:, None]
    inside = norm3((pos[i] - pos[j]) / scale) < 1.0
    inside &= active[i] | active[j]
    return i[inside], j[inside]
