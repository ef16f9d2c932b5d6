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
The graph is the guide's grid of 26 neighbours (:func:`reverse_graph` builds it): a leg's start
cell and, away from surfaces, its cost follow from its offset, so only the legs into cells near
surfaces are stored (and re-priced by the ways' loads).
"""

from __future__ import annotations

import numpy as np

from swarmplan.geometry._shape_kernel import sdf
from swarmplan.runtime.compiled import njit

NO_WAY = -9999
"""The predecessor of a vertex with no way to it (and of the source), as scipy writes it."""

_MARGIN = 1e-6
"""m: the margin of the bounds the line-of-sight samples are judged by, far beyond rounding."""


@njit(cache=True)
def dijkstra(
    indptr: np.ndarray,
    data: np.ndarray,
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    source: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Distances (float64) and predecessors (int32, ``NO_WAY`` where none) from ``source``
    over the guide's reversed graph (``reverse_graph``: CSR ``indptr`` and ``data``; its
    ``indices`` are implicit). ``grid``: per cell the bits of its legs (``mask``: bit q set
    for a leg along offset q) and whether its row holds their costs (``read``: elsewhere the
    leg along offset q costs ``length[q]``), and per offset its flat ``delta`` and ``length``.
    The leg's start cell is the cell less ``delta[q]``: a search reads the stored legs of the
    cells near surfaces only."""
    mask, read, delta, length = grid
    n = len(indptr) - 1
    m = len(delta)
    dist = np.full(n, np.inf)
    pred = np.full(n, NO_WAY, dtype=np.int32)
    at = np.full(n, -1, dtype=np.int32)  # a vertex's place in the heap (-1: not in it)
    hd = np.empty(n + 1)  # the heap: keys (distance, vertex), and a sentinel past its end
    hv = np.empty(n + 1, dtype=np.int32)
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
            hd[size] = np.inf  # never the lesser child
            hv[size] = -1
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                d0, d1 = hd[c], hd[c + 1]
                c += np.int64((d1 < d0) | ((d1 == d0) & (hv[c + 1] > hv[c])))  # no branch
                cd, cv = hd[c], hv[c]
                if cd < kd or (cd == kd and cv > kv):
                    hd[i] = cd
                    hv[i] = cv
                    at[cv] = i
                    i = c
                else:
                    break
            hd[i] = kd
            hv[i] = kv
            at[kv] = i
        bits = mask[u]
        j = indptr[u]
        row = read[u]
        for q in range(m):
            if not (bits >> np.uint32(q)) & np.uint32(1):
                continue
            w = u - delta[q]
            if row:
                nd = du + data[j]
                j += 1
            else:
                nd = du + length[q]
            if dist[w] > nd:
                dist[w] = nd
                pred[w] = u
                i = at[w]
                if i < 0:
                    i = size
                    size += 1
                while i > 0:  # sift up
                    p = (i - 1) >> 1
                    pd = hd[p]
                    if nd < pd or (nd == pd and w > hv[p]):
                        hd[i] = pd
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
    ``reach``-es (every body with ``every``; inf when none), for the analytic shapes (``code``
    and ``prm``: ``bodies.body_table``): per pair the operations of ``rotate_rows_of`` and the
    shapes' distance ``_shape_kernel.sdf`` (numpy twin ``shapes.DISTANCE``) on the same
    numbers, in their order (the same bits as ``StaticGuide._body_distance``'s numpy)."""
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
            d = sdf(code[b], x, y, z, prm[b, 0], prm[b, 1], prm[b, 2])
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
        # element by element: a row assigned whole compiles numba's shape-mismatch message
        if lost or c == source[row]:
            out[r, 0], out[r, 1], out[r, 2] = goal[r, 0], goal[r, 1], goal[r, 2]
        else:
            out[r, 0], out[r, 1], out[r, 2] = centres[c, 0], centres[c, 1], centres[c, 2]
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


@njit(cache=True)
def reverse_graph(
    free: np.ndarray,
    prox: np.ndarray,
    side: np.ndarray,
    legs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    shape: np.ndarray,
    costs: tuple[float, float],
    cut: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The guide's reversed graph in CSR form (``StaticGuide``: row v holds the legs into cell v,
    by their start cells, ascending), rows only for the cells near surfaces (``prox`` > 0: the
    legs into any other cell cost their lengths, see :func:`dijkstra`), in two passes over the
    cells: count, then fill. ``legs``:
    the 26 offsets (sorted so that their start cells ascend), their flat deltas, their lengths
    and, per offset, the row of ``side`` (the cells' normals on the leg's right-hand side, as
    numpy's product computes them) or -1 for a vertical leg; ``costs``: ``NEAR`` and ``RIGHT``;
    ``cut``: per cell the bits of the legs into it that run through a body (left out).
    Each cost is the numpy expression's, operation by operation (the same bits). Also per cell
    the bits of its row's offsets (bit q: the leg along offset q, for :func:`dijkstra`)."""
    offsets, delta, length, row = legs
    near, right = costs
    nx, ny, nz = shape[0], shape[1], shape[2]
    n = nx * ny * nz
    m = len(delta)
    indptr = np.zeros(n + 1, dtype=np.int32)
    mask = np.zeros(n, dtype=np.uint32)
    for pass_ in range(2):
        if pass_ == 1:
            for v in range(n):
                indptr[v + 1] += indptr[v]
            indices = np.empty(indptr[n], dtype=np.int32)
            data = np.empty(indptr[n])
        else:
            indices = np.empty(0, dtype=np.int32)
            data = np.empty(0)
        v = 0
        for i in range(nx):
            for j in range(ny):
                for k in range(nz):
                    at = indptr[v]
                    count = 0
                    for q in range(m):
                        si, sj, sk = i - offsets[q, 0], j - offsets[q, 1], k - offsets[q, 2]
                        if si < 0 or si >= nx or sj < 0 or sj >= ny or sk < 0 or sk >= nz:
                            continue
                        u = v - delta[q]
                        if not (free[v] or not free[u]):
                            continue
                        if (cut[v] >> np.uint32(q)) & np.uint32(1):
                            continue
                        if pass_ == 0:
                            mask[v] |= np.uint32(1) << np.uint32(q)
                        elif prox[v] > 0.0:
                            indices[at + count] = u
                            if free[v]:
                                s = 0.0
                                if row[q] >= 0:
                                    s = max(side[row[q], v], 0.0)
                                data[at + count] = length[q] * (1.0 + prox[v] * (near + right * s))
                            else:
                                data[at + count] = 10.0 * length[q]
                        count += 1
                    if pass_ == 0 and prox[v] > 0.0:
                        indptr[v + 1] = count
                    v += 1
    return indptr, indices, data, mask


@njit(cache=True)
def reach_table(
    lo: np.ndarray, cell: np.ndarray, shape: np.ndarray, near: np.ndarray, far: np.ndarray, limit: float
) -> np.ndarray:
    """Per cell of the grid (corner ``lo``, cell sizes ``cell``, ``shape``) and per body with
    the box ``near`` to ``far`` (m, 3): whether the distance between the cell's box and the
    body's box is below ``limit`` (``StaticGuide._reach_bodies``: numpy's operations in its
    order, the squares summed from the first axis on)."""
    nx, ny, nz = shape[0], shape[1], shape[2]
    m = len(near)
    out = np.zeros((nx * ny * nz, m), dtype=np.bool_)
    v = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                a0 = lo[0] + i * cell[0]
                a1 = lo[1] + j * cell[1]
                a2 = lo[2] + k * cell[2]
                b0, b1, b2 = a0 + cell[0], a1 + cell[1], a2 + cell[2]
                for b in range(m):
                    g0 = max(max(a0 - far[b, 0], near[b, 0] - b0), 0.0)
                    g1 = max(max(a1 - far[b, 1], near[b, 1] - b1), 0.0)
                    g2 = max(max(a2 - far[b, 2], near[b, 2] - b2), 0.0)
                    out[v, b] = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2) < limit
                v += 1
    return out


@njit(cache=True)
def _line_min_plus(
    src: np.ndarray, out: np.ndarray, start: int, stride: int, size: int, term: np.ndarray
) -> None:
    """``out`` on one line of the grid (``size`` cells from ``start``, ``stride`` apart): per
    cell the least ``src`` of a cell s cells away plus ``term[s]`` (``src`` >= 0, ``term``
    non-decreasing: the candidates past a ``term`` no less than the least so far cannot be less)."""
    for p in range(size):
        v = start + p * stride
        best = src[v] + term[0]
        for s in range(1, size):
            t = term[s]
            if t >= best:
                break
            if s <= p:
                best = min(best, src[v - s * stride] + t)
            if p + s < size:
                best = min(best, src[v + s * stride] + t)
        out[v] = best


@njit(cache=True)
def gap_squares(
    near: np.ndarray, shape: np.ndarray, terms: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> np.ndarray:
    """Per cell of the grid (flat, of ``shape``) the least sum over the axes, in their order, of
    ``terms[axis][s]`` (s: the cells between it and a ``near`` cell along that axis) over the
    near cells: the minimum one axis after the other, each the same sums as numpy's shift by
    shift (``StaticGuide._sight_bounds``). Along the first axis the sources are 0 or inf, so
    the least is the term of the distance to the nearest near cell on the line."""
    nx, ny, nz = shape[0], shape[1], shape[2]
    t0, t1, t2 = terms
    first = np.full(len(near), np.inf)
    for j in range(ny):
        for k in range(nz):
            start = j * nz + k
            stride = ny * nz
            last = -1  # the nearest near cell before, then after
            for i in range(nx):
                v = start + i * stride
                if near[v]:
                    last = i
                if last >= 0:
                    first[v] = 0.0 + t0[i - last]
            last = -1
            for i in range(nx - 1, -1, -1):
                v = start + i * stride
                if near[v]:
                    last = i
                if last >= 0:
                    first[v] = min(first[v], 0.0 + t0[last - i])
    second = np.empty(len(near))
    for i in range(nx):
        for k in range(nz):
            _line_min_plus(first, second, i * ny * nz + k, nz, ny, t1)
    third = np.empty(len(near))
    for i in range(nx):
        for j in range(ny):
            _line_min_plus(second, third, (i * ny + j) * nz, 1, nz, t2)
    return third
