"""The static guide's per-step kernels in numpy, for worlds below swarm size while numba is not
in the process: :func:`cells_of`, :func:`way_points`, :func:`sight_samples`, :func:`flat_hits`
and :func:`body_distance` take the arguments of ``swarmplan.flight._guide_kernel``'s functions of
the same names and give their answers exactly (the same integers, the same doubles, the same
booleans), vectorized with numpy over the lines, their samples and the agents.

Why a second implementation: the compiled one needs numba, whose import costs ~0.45 s of CPU
per process, more than a small world's first steps may take; the guide's grid and the searches
at its start-up need no numba (they can come from a cache), so its per-step calls are what is
left. Exactly: every number is the kernel's expression, operation by operation (IEEE
arithmetic is exact per operation, so the same expression gives the same double whether numba
or numpy evaluates it), and where the kernel passes over work its skips are exact:

- ``sight_samples`` passes over a sample in a cell whose centre's clearance is at least
  ``limit`` (such a sample cannot count), and the kernel's run-ahead within a cell's box and
  gap passes over such samples only; so here every sample of a line the gap table does not
  pass over gets its cell, those in cells at or beyond ``limit`` are dropped, and the rest
  meet the kernel's tests in its order (``bounded``: surely within ``squeeze``, surely beyond
  it, the ground, the bodies alone). A line with a sample surely within ``squeeze`` is
  blocked whichever sample the kernel met first, and its other samples are not measured.
  The samples left to measure are the kernel's, in its order (row by row, along each line).
- ``body_distance``: per pair of a sample and a body the operations of ``rotate_rows_of`` and
  ``shapes.DISTANCE`` (the twin of the kernel's ``_shape_kernel.sdf``), the least over the
  bodies the sample's cell reaches (every body with ``every``).
"""

from __future__ import annotations

import numpy as np

from swarmplan.geometry.batch import rotate_rows_of
from swarmplan.geometry.shapes import DISTANCE

_MARGIN = 1e-6  # _guide_kernel._MARGIN: the margin of the bounds the samples are judged by
_SAMPLES = 1 << 20  # samples per block of lines (a few arrays of this many doubles at once)


def cells_of(pts: np.ndarray, lo: np.ndarray, cell: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """The flat index of the cell holding each of ``pts`` (..., 3) (``StaticGuide.cell_of``): the
    kernel's ``_cell``, the floor of ``(p - lo) / cell`` clipped to the grid (in float, then the
    integer)."""
    ijk = np.minimum(np.maximum(np.floor((pts - lo) / cell), 0.0), shape - 1.0).astype(np.int64)
    return (ijk[..., 0] * int(shape[1]) + ijk[..., 1]) * int(shape[2]) + ijk[..., 2]


def way_points(
    pos: np.ndarray,
    goal: np.ndarray,
    table: np.ndarray,
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ways: tuple[np.ndarray, np.ndarray, np.ndarray],
    hops: int,
) -> np.ndarray:
    """The points of attraction of agents at ``pos`` (n, 3) on the ways of ``table`` (n,) to
    ``goal`` (the kernel's ``way_points``): the centre of the cell ``hops`` legs on from the
    agent's cell, or the goal where that is the way's end or no way leads from the agent's cell."""
    lo, cell, shape, centres = grid
    nxt, dist, source = ways
    table = np.asarray(table, dtype=np.int64)
    c = cells_of(pos, lo, cell, shape)
    lost = ~np.isfinite(dist[table, c])
    for _ in range(hops):
        step = nxt[table, c]
        c = np.where(step >= 0, step, c)
    home = lost | (c == source[table])
    return np.where(home[:, None], np.asarray(goal, dtype=float), centres[c])


def sight_samples(
    start: np.ndarray,
    end: np.ndarray,
    length: np.ndarray,
    t: np.ndarray,
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    levels: tuple[float, float, float, float],
    gap: np.ndarray,
    gap_max: float,
    low: int,
    bounded: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The samples ``start + t (end - start)`` of the lines (n, 3) that need their exact
    distances, row by row (their rows, points and cells), and the rows found blocked without
    them: the kernel's ``sight_samples`` (see the module's description), in blocks of lines."""
    lo, cell, shape, centres, clear, body_clear = grid
    limit, squeeze, floor, radius = levels
    n, m = len(start), len(t)
    hit = np.zeros(n, dtype=np.bool_)
    # The lines the gap table passes over: both ends in layers from ``low`` up, and the start
    # cell's gap beyond the length (with the kernel's margin).
    top = float(shape[2] - 1)
    sz = start[:, 2]
    ez = sz + (end[:, 2] - sz)
    ks = np.minimum(np.maximum(np.floor((sz - lo[2]) / cell[2]), 0.0), top)
    ke = np.minimum(np.maximum(np.floor((ez - lo[2]) / cell[2]), 0.0), top)
    high = np.minimum(ks, ke) >= low
    reach = length * (1.0 + 1e-9) + 1e-6
    passed = (reach < gap_max) & high & (gap[cells_of(start, lo, cell, shape)] > reach)
    lines = np.flatnonzero(~passed)
    d = end - start
    rows, pts, cells = [], [], []
    block = max(1, _SAMPLES // max(m, 1))
    for a in range(0, len(lines), block):
        r = lines[a : a + block]
        p = start[r, None, :] + t[None, :, None] * d[r, None, :]  # (lines, samples, 3)
        c = cells_of(p, lo, cell, shape)
        local, q = np.nonzero(clear[c] < limit)  # row by row, along each line: the kernel's order
        row, p, c = r[local], p[local, q], c[local, q]
        if bounded:
            cc = clear[c]
            o = p - centres[c]
            off = np.sqrt(o[:, 0] * o[:, 0] + o[:, 1] * o[:, 1] + o[:, 2] * o[:, 2])
            within = cc + off < squeeze - _MARGIN  # surely within ``squeeze``: blocked
            beyond = cc - off > squeeze + _MARGIN  # surely beyond it: no exact distance
            ground = ~beyond & ((p[:, 2] - 0.0) - floor - radius < squeeze)  # flat ground decides
            hit[row[within | ground]] = True
            measure = ~beyond & ~(body_clear[c] - off > squeeze + _MARGIN) & ~hit[row]
            row, p, c = row[measure], p[measure], c[measure]
        rows.append(row)
        pts.append(p)
        cells.append(c)
    if not rows:
        return np.empty(0, dtype=np.int64), np.empty((0, 3)), np.empty(0, dtype=np.int64), hit
    return np.concatenate(rows), np.concatenate(pts), np.concatenate(cells), hit


def body_distance(
    p: np.ndarray,
    cells: np.ndarray,
    reach: np.ndarray,
    every: bool,
    position: np.ndarray,
    rotation: np.ndarray,
    code: np.ndarray,
    prm: np.ndarray,
) -> np.ndarray:
    """The distance from each point ``p`` (n, 3) in ``cells`` to the nearest body its cell
    ``reach``-es (every body with ``every``; inf when none): the kernel's ``body_distance``,
    per pair the operations of ``rotate_rows_of`` and ``shapes.DISTANCE``."""
    n, m = len(p), len(position)
    out = np.full(n, np.inf)
    if n == 0 or m == 0:
        return out
    if every:
        pt, body = np.repeat(np.arange(n), m), np.tile(np.arange(m), n)
    else:
        pt, body = np.nonzero(reach[cells])
    if not len(pt):
        return out
    c = position[body]
    local = rotate_rows_of(*(p[pt, k] - c[:, k] for k in range(3)), rotation[body])
    dist = np.empty(len(pt))
    for k in np.unique(code[body]):
        sel = np.flatnonzero(code[body] == k)
        dist[sel] = DISTANCE[int(k)](local[sel], prm[body[sel]])
    first = np.flatnonzero(np.diff(pt, prepend=-1))  # the pairs come point by point
    out[pt[first]] = np.minimum.reduceat(dist, first)
    return out


def flat_hits(
    p: np.ndarray,
    rows: np.ndarray,
    cells: np.ndarray,
    out: np.ndarray,
    inner: tuple[np.ndarray, np.ndarray],
    bodies: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    levels: tuple[float, float, float],
) -> None:
    """Mark ``out[rows[k]]`` where sample ``p[k]`` (in ``cells[k]``) comes within ``squeeze`` of
    flat ground or a body: the kernel's ``flat_hits`` (every body for every sample when one
    sample lies outside ``inner``)."""
    squeeze, floor, radius = levels
    lo, hi = inner
    every = bool(((p < lo) | (p > hi)).any())
    d = body_distance(p, cells, *bodies[:1], every, *bodies[1:])
    e = np.minimum((p[:, 2] - 0.0) - floor, d) - radius
    out[rows[e < squeeze]] = True
