"""Compiled (numba) shortest ways of the static guide (:mod:`swarmplan.flight.guide`).

:func:`dijkstra` is Dijkstra's search over a graph in CSR form from one source, with the same
answers, to the bit, as scipy's ``scipy.sparse.csgraph.dijkstra(graph, directed=True,
indices=source, return_predecessors=True)``. scipy's search keeps a heap of (distance, vertex)
entries, a vertex entering again whenever its distance strictly drops (the older entry passed
over when it comes up), and pops the least distance first and, among equal distances, the
greatest vertex index; the legs of a vertex are relaxed in their CSR order. Distances and
predecessors follow from that order alone, so any queue that pops the vertices in it gives the
same tables: here a binary heap holding each vertex once (its key lowered in place), smaller
than scipy's, and no per-call checks and copies of the graph (nor scipy.sparse at start-up).
"""

from __future__ import annotations

import numpy as np
from numba import njit

NO_WAY = -9999
"""The predecessor of a vertex with no way to it (and of the source), as scipy writes it."""

_MARGIN = 1e-6
"""m: the margin of the bounds the line-of-sight samples are judged by, far beyond rounding."""


@njit(cache=True)
def dijkstra(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, source: int
) -> tuple[np.ndarray, np.ndarray]:
    """Distances (float64) and predecessors (int32, ``NO_WAY`` where none) from ``source``
    over the graph ``(data, indices, indptr)`` (CSR, non-negative weights)."""
    n = len(indptr) - 1
    dist = np.full(n, np.inf)
    pred = np.full(n, NO_WAY, dtype=np.int32)
    at = np.full(n, -1, dtype=np.int64)  # a vertex's place in the heap (-1: not in it)
    hd = np.empty(n)  # the heap: keys (distance, vertex) ...
    hv = np.empty(n, dtype=np.int64)
    size = 1
    dist[source] = 0.0
    hd[0] = 0.0
    hv[0] = source
    at[source] = 0
    while size > 0:
        u = hv[0]
        du = hd[0]
        at[u] = -1
        size -= 1
        if size > 0:  # the last entry sifts down from the root
            kd, kv = hd[size], hv[size]
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and (hd[c + 1] < hd[c] or (hd[c + 1] == hd[c] and hv[c + 1] > hv[c])):
                    c += 1
                if hd[c] < kd or (hd[c] == kd and hv[c] > kv):
                    hd[i] = hd[c]
                    hv[i] = hv[c]
                    at[hv[i]] = i
                    i = c
                else:
                    break
            hd[i] = kd
            hv[i] = kv
            at[kv] = i
        for j in range(indptr[u], indptr[u + 1]):
            w = indices[j]
            nd = du + data[j]
            if dist[w] > nd:
                dist[w] = nd
                pred[w] = u
                i = at[w]
                if i < 0:
                    i = size
                    size += 1
                while i > 0:  # sift up
                    p = (i - 1) // 2
                    if nd < hd[p] or (nd == hd[p] and w > hv[p]):
                        hd[i] = hd[p]
                        hv[i] = hv[p]
                        at[hv[i]] = i
                        i = p
                    else:
                        break
                hd[i] = nd
                hv[i] = w
                at[w] = i
    return dist, pred


@njit(cache=True)
def _cell(x: float, y: float, z: float, lo: np.ndarray, cell: np.ndarray, shape: np.ndarray) -> int:
    """The flat index of the cell holding (x, y, z), as ``StaticGuide.cell_of`` computes it."""
    i = min(max(int(np.floor((x - lo[0]) / cell[0])), 0), shape[0] - 1)
    j = min(max(int(np.floor((y - lo[1]) / cell[1])), 0), shape[1] - 1)
    k = min(max(int(np.floor((z - lo[2]) / cell[2])), 0), shape[2] - 1)
    return (i * shape[1] + j) * shape[2] + k


@njit(cache=True)
def _inside(
    x: float,
    y: float,
    z: float,
    dx: float,
    dy: float,
    dz: float,
    lo: np.ndarray,
    cell: np.ndarray,
    shape: np.ndarray,
) -> float:
    """How far (in units of ``(dx, dy, dz)``) the point (x, y, z) can move along that direction
    and stay in the box of its cell shrunk by ``_MARGIN`` on every side (so that every point
    there has that cell's index whatever the rounding): 0 for a point not in the shrunk box
    (outside the grid too), inf for no direction."""
    out = np.inf
    p = (x, y, z)
    d = (dx, dy, dz)
    for a in range(3):
        f = (p[a] - lo[a]) / cell[a]
        if not 0.0 <= f < shape[a]:
            return 0.0
        i = np.floor(f)
        low, high = lo[a] + i * cell[a] + _MARGIN, lo[a] + (i + 1.0) * cell[a] - _MARGIN
        if not low <= p[a] <= high:
            return 0.0
        if d[a] > 0.0:
            out = min(out, (high - p[a]) / d[a])
        elif d[a] < 0.0:
            out = min(out, (low - p[a]) / d[a])
    return out


@njit(cache=True)
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
        them. ``grid``: the grid's corner, cell sizes, shape, cell centres, their clearance and
    their clearance to the obstacles alone; ``levels``: ``limit``, ``squeeze``, and the floor
    and radius the ground's clearance is measured with.

        A sample counts only in a cell whose centre's clearance is below ``limit`` (the clearance
        is 1-Lipschitz: no sample elsewhere comes within ``squeeze``), and a line whose start cell's
        ``gap`` exceeds its ``length`` (with a margin for rounding) and whose ends lie in layers from
        ``low`` up has none there (``StaticGuide.blocked`` says why); on such a line neither has any
    sample closer to a sample than the ``gap`` of the latter's cell. With ``bounded`` (the
        clearance is 1-Lipschitz everywhere: flat ground, bodies with exact distances) the
        sample's own distance to its cell's centre bounds its clearance both ways: a line with a
        sample surely within ``squeeze`` is blocked whatever its other samples, and a sample
        surely beyond it needs no exact distance. Each number as numpy's expressions give it."""
    lo, cell, shape, centres, clear, body_clear = grid
    limit, squeeze, floor, radius = levels
    n = len(start)
    m = len(t)
    keep = np.ones(n, dtype=np.bool_)
    high = np.zeros(n, dtype=np.bool_)  # both ends in layers from ``low`` up: so every sample
    hit = np.zeros(n, dtype=np.bool_)
    top = shape[2] - 1
    for r in range(n):
        sz = start[r, 2]
        ez = sz + (end[r, 2] - sz)
        ks = min(max(np.floor((sz - lo[2]) / cell[2]), 0.0), top)
        ke = min(max(np.floor((ez - lo[2]) / cell[2]), 0.0), top)
        high[r] = min(ks, ke) >= low
        reach = length[r] * (1.0 + 1e-9) + 1e-6
        if reach < gap_max and high[r] and gap[_cell(start[r, 0], start[r, 1], sz, lo, cell, shape)] > reach:
            keep[r] = False
    margin = _MARGIN
    at = np.empty(1024, dtype=np.int64)  # the samples to measure: r * m + q, and their cells
    of = np.empty(1024, dtype=np.int64)
    count = 0
    for r in range(n):
        if not keep[r]:
            continue
        first = count
        dx, dy, dz = end[r, 0] - start[r, 0], end[r, 1] - start[r, 1], end[r, 2] - start[r, 2]
        span = length[r] * (1.0 + 1e-9)
        q = 0
        while q < m:
            x, y, z = start[r, 0] + t[q] * dx, start[r, 1] + t[q] * dy, start[r, 2] + t[q] * dz
            c = _cell(x, y, z, lo, cell, shape)
            if clear[c] >= limit:
                # Samples on until the line leaves this cell's box (less a margin) are in it,
                # and on a line in the layers of the gap table those within the cell's gap of
                # the box are in cells whose boxes are that close to it: none near a surface.
                ahead = _inside(x, y, z, dx, dy, dz, lo, cell, shape)
                if ahead == np.inf:  # a line of length 0: every sample is this one
                    break
                if high[r]:
                    ahead += max(gap[c] - margin, 0.0) / span
                tq = t[q]
                q += 1
                while q < m and t[q] - tq < ahead:
                    q += 1
                continue
            if bounded:
                off = np.sqrt((x - centres[c, 0]) ** 2 + (y - centres[c, 1]) ** 2 + (z - centres[c, 2]) ** 2)
                if clear[c] + off < squeeze - margin:
                    hit[r] = True
                    break
                if clear[c] - off > squeeze + margin:
                    q += 1
                    continue
                # Flat ground: the sample's height above it as numpy's ``blocked`` computes it
                # decides for the ground, and the obstacles alone may be out of reach.
                if (z - 0.0) - floor - radius < squeeze:
                    hit[r] = True
                    break
                if body_clear[c] - off > squeeze + margin:
                    q += 1
                    continue
            if count == len(at):
                at = np.concatenate((at, np.empty(len(at), dtype=np.int64)))
                of = np.concatenate((of, np.empty(len(of), dtype=np.int64)))
            at[count] = r * m + q
            of[count] = c
            count += 1
            q += 1
        if hit[r]:  # its samples kept so far need no measuring
            count = first
    rows = np.empty(count, dtype=np.int64)
    pts = np.empty((count, 3))
    for k in range(count):
        r, q = at[k] // m, at[k] % m
        rows[k] = r
        for a in range(3):
            pts[k, a] = start[r, a] + t[q] * (end[r, a] - start[r, a])
    cells = of[:count].copy()
    return rows, pts, cells, hit


@njit(cache=True)
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
    ``reach``-es (every body with ``every``; inf when none), for spheres, boxes, cylinders and
    capsules (``code`` 0-3; ``prm``: radius, half sizes, or radius and half height): per pair
    the operations of ``rotate_rows_of`` and ``SHAPE_DISTANCE`` on the same numbers, in their
    order (the same bits as ``StaticGuide._body_distance``'s numpy)."""
    n, m = len(p), len(position)
    out = np.full(n, np.inf)
    for i in range(n):
        best = np.inf
        for b in range(m):
            if not every and not reach[cells[i], b]:
                continue
            r0, r1, r2 = p[i, 0] - position[b, 0], p[i, 1] - position[b, 1], p[i, 2] - position[b, 2]
            rot = rotation[b]
            x = r0 * rot[0, 0] + r1 * rot[1, 0] + r2 * rot[2, 0] + 0.0
            y = r0 * rot[0, 1] + r1 * rot[1, 1] + r2 * rot[2, 1] + 0.0
            z = r0 * rot[0, 2] + r1 * rot[1, 2] + r2 * rot[2, 2] + 0.0
            c = code[b]
            if c == 0:
                d = np.sqrt(x * x + y * y + z * z) - prm[b, 0]
            elif c == 1:
                qx, qy, qz = abs(x) - prm[b, 0], abs(y) - prm[b, 1], abs(z) - prm[b, 2]
                ux, uy, uz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
                d = np.sqrt(ux * ux + uy * uy + uz * uz) + min(max(max(qx, qy), qz), 0.0)
            elif c == 2:
                dr = np.sqrt(x * x + y * y) - prm[b, 0]
                dz = abs(z) - prm[b, 1]
                d = np.hypot(max(dr, 0.0), max(dz, 0.0)) + min(max(dr, dz), 0.0)
            else:
                h = prm[b, 1]
                dz = z - min(max(z, -h), h)
                d = np.sqrt(x * x + y * y + dz * dz) - prm[b, 0]
            if d < best:
                best = d
        out[i] = best
    return out


@njit(cache=True)
def way_points(
    pos: np.ndarray,
    goal: np.ndarray,
    table: np.ndarray,
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ways: tuple[np.ndarray, np.ndarray, np.ndarray],
    hops: int,
) -> np.ndarray:
    """The points of attraction of agents at ``pos`` (n, 3) on the ways of ``table`` (n,) to
    ``goal``: the centre of the cell ``hops`` legs on from the agent's cell, or the goal where
    that is the way's end or no way leads from the agent's cell. ``grid``: the grid's corner,
    cell sizes, shape and cell centres; ``ways``: the next cells, distances and end cells of
    the tables (``StaticGuide.targets``)."""
    lo, cell, shape, centres = grid
    nxt, dist, source = ways
    out = np.empty((len(pos), 3))
    for r in range(len(pos)):
        row = table[r]
        c = _cell(pos[r, 0], pos[r, 1], pos[r, 2], lo, cell, shape)
        lost = not np.isfinite(dist[row, c])
        for _ in range(hops):
            if nxt[row, c] >= 0:
                c = nxt[row, c]
        if lost or c == source[row]:
            out[r] = goal[r]
        else:
            out[r] = centres[c]
    return out


@njit(cache=True)
def flat_hits(
    p: np.ndarray,
    rows: np.ndarray,
    cells: np.ndarray,
    out: np.ndarray,
    inner: tuple[np.ndarray, np.ndarray],
    bodies: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    levels: tuple[float, float, float],
) -> None:
    """Mark ``out[rows[k]]`` where sample ``p[k]`` (in ``cells[k]``) comes within ``squeeze``
    of flat ground or a body (``levels``: squeeze, floor, radius), the samples measured as
    ``StaticGuide.blocked`` measures them in numpy: the height above the ground, the distance
    to the bodies the sample's cell reaches (to every body when a sample lies outside
    ``inner``, the grid's box less a margin: ``bodies`` = reach table, positions, rotations,
    codes, parameters), the lesser, less the radius."""
    squeeze, floor, radius = levels
    lo, hi = inner
    every = False
    for k in range(len(p)):
        for a in range(3):
            if p[k, a] < lo[a] or p[k, a] > hi[a]:
                every = True
    reach, position, rotation, code, prm = bodies
    d = body_distance(p, cells, reach, every, position, rotation, code, prm)
    for k in range(len(p)):
        e = min((p[k, 2] - 0.0) - floor, d[k]) - radius
        if e < squeeze:
            out[rows[k]] = True


@njit(cache=True)
def cells_of(pts: np.ndarray, lo: np.ndarray, cell: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """The flat index of the cell holding each of ``pts`` (n, 3) (``StaticGuide.cell_of``)."""
    out = np.empty(len(pts), dtype=np.int64)
    for k in range(len(pts)):
        out[k] = _cell(pts[k, 0], pts[k, 1], pts[k, 2], lo, cell, shape)
    return out
