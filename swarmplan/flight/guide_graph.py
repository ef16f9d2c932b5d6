"""The static guide's grid graph: the 26 neighbours of a cell and the legs between cells
(:mod:`swarmplan.flight.guide`; the searches over it: ``_guide_kernel.dijkstra``), the source
cell of a goal's search and the least height the ways keep."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.flight.kinematics import checked_radius
from swarmplan.runtime.compiled import kernel_module

if TYPE_CHECKING:
    from swarmplan.flight.kinematics import AgentParams
    from swarmplan.world.model import World


@dataclasses.dataclass
class Graph:
    """A graph over the cells in CSR form (row v: the legs into v, by their start cell; rows
    only for the cells near surfaces: the legs into any other cell cost their lengths)."""

    indptr: np.ndarray  # int32, (cells + 1,)
    indices: np.ndarray  # int32: the legs' start cells
    data: np.ndarray  # float64: the legs' costs
    # What the search needs besides (``_guide_kernel.dijkstra``): per cell the bits of the
    # offsets of its legs and whether it has a row (near surfaces), per offset the flat delta
    # and the length.
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _offsets() -> np.ndarray:
    o = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)])
    return o[np.abs(o).sum(axis=1) > 0]


OFFSETS = _offsets()  # the 26 neighbours' offsets
AROUND = np.vstack([np.zeros((1, 3), dtype=OFFSETS.dtype), OFFSETS])  # and the cell itself


def legs(shape: np.ndarray, cell: np.ndarray) -> tuple[np.ndarray, ...]:
    """The 26 offsets ordered so that the start cells of the legs into a cell ascend, their flat
    deltas and lengths, per offset its row among the unit vectors to the right of the legs not
    vertical (-1 for a vertical one), and those vectors."""
    offsets = OFFSETS
    ny, nz = int(shape[1]), int(shape[2])
    delta = (offsets[:, 0] * ny + offsets[:, 1]) * nz + offsets[:, 2]
    order = np.argsort(-delta, kind="stable")
    offsets, delta = offsets[order], delta[order]
    length = np.empty(len(offsets))
    row = np.full(len(offsets), -1, dtype=np.int64)
    rights = []
    for k, o in enumerate(offsets):
        step = o * cell
        length[k] = float(np.linalg.norm(step))
        e = step / length[k]
        right = np.array([e[1], -e[0], 0.0])
        nr = float(np.linalg.norm(right))
        if nr > 0.2:
            row[k] = len(rights)
            rights.append(right / nr)
    return offsets, delta, length, row, np.array(rights).reshape(-1, 3)


def source_cell(
    free: np.ndarray,
    clear: np.ndarray,
    grid: tuple[np.ndarray, ...],
    cell: int,
    sight: tuple[np.ndarray, Callable[[np.ndarray, np.ndarray], np.ndarray]] | None = None,
) -> int:
    """The source of the search for a goal in ``cell`` (``grid``: the cells' indices, centres
    and the grid's shape): the cell, or the free neighbour with the most clearance when the
    goal's own cell is not free; with no free neighbour either (a goal tucked into a corner by
    more than a cell), the free cell nearest the goal's cell (by their centres) in the first
    ring of cells round it (at 2, 3, ... cells along the farthest axis) that holds one: a
    source that is not free would be entered by no free cell, and no way would lead there.
    With ``sight`` (the goal's point and segments -> whether each meets a body), the cell and
    its free neighbours from whose centres the goal is in sight come first: a goal under a slab or
    behind a wall thinner than a cell has free neighbours on the far side of the body too, and
    a way that ended there left the agent pulled at the goal through the body. Where none of
    them sees it (a goal just above a plate thinner than a cell, the cells beside it taken by
    the plate inflated by the largest body), the free cell nearest the goal's cell that sees
    it, in the first ring that holds one, is the source."""
    ijk, centres, shape = grid
    flat = _ring(ijk[cell], 1, shape)
    if sight is not None:
        goal, hits = sight

        def sees(cells: np.ndarray) -> np.ndarray:
            return ~hits(centres[cells], np.broadcast_to(goal, (len(cells), 3)))

        if free[cell] and bool(sees(np.array([cell]))[0]):
            return cell
        near = flat[free[flat]]
        if len(near):
            seen = near[sees(near)]
            if len(seen):
                return int(seen[np.argmax(clear[seen])])
        found = _nearest_in_rings(grid, cell, lambda ring: ring[sees(ring)] if len(ring) else ring, free)
        if found >= 0:
            return found
    if free[cell]:
        return cell
    if free[flat].any() or not free.any():
        return int(flat[np.argmax(clear[flat])])
    found = _nearest_in_rings(grid, cell, lambda ring: ring, free)
    return found if found >= 0 else cell


def _nearest_in_rings(
    grid: tuple[np.ndarray, ...], cell: int, keep: Callable[[np.ndarray], np.ndarray], free: np.ndarray
) -> int:
    """The free cell ``keep`` keeps nearest ``cell`` (by the centres) in the first ring round it
    (2, 3, ... cells along the farthest axis) that holds one, or -1."""
    ijk, centres, shape = grid
    for k in range(2, int(shape.max()) + 1):
        ring = _ring(ijk[cell], k, shape)
        ring = keep(ring[free[ring]])
        if len(ring):
            return int(ring[np.argmin(np.linalg.norm(centres[ring] - centres[cell], axis=1))])
    return -1


def _ring(at: np.ndarray, k: int, shape: np.ndarray) -> np.ndarray:
    """The flat indices of the grid's cells ``k`` cells from cell ``at`` along the farthest axis
    (k = 1: the 26 neighbours, in ``OFFSETS``' order)."""
    if k == 1:
        nb = at + OFFSETS
        nb = nb[((nb >= 0) & (nb < shape)).all(axis=1)]
    else:
        lo, hi = np.maximum(at - k, 0), np.minimum(at + k, shape - 1)
        axes = (np.arange(a, b + 1) for a, b in zip(lo, hi, strict=True))
        box = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        nb = box[np.abs(box - at).max(axis=1) == k]
    return (nb[:, 0] * shape[1] + nb[:, 1]) * shape[2] + nb[:, 2]


def crossing_legs(
    cells: tuple[np.ndarray, ...],
    radius: float,
    leg: tuple[np.ndarray, np.ndarray, np.ndarray],
    hits: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> np.ndarray:
    """Per cell the bits of the legs into it (bit q: the leg along offset q of ``leg`` = the
    offsets, flat deltas and lengths of :func:`legs`) that run through a body, both ends free
    (``cells``: the cells' indices, the grid's shape, the centres, free, near surfaces and
    clearance to the bodies less ``radius``; ``hits``: segments -> whether each meets a body):
    a body thinner than a cell (a wall, a slab) lies between the centres of two free cells, and
    a way along that leg led agents into its face, their point of attraction beyond it. Only
    the legs into cells near surfaces can (a cell farther from every body than a leg is long
    covers its legs), and of those only the legs whose two ends' distances to the bodies do not
    add up to the leg's length (each end's ball of its distance is clear, the distance being
    1-Lipschitz); ``hits`` decides those. A leg that only grazes a body's margin (a diagonal
    round a corner) is kept: the field's push keeps the agent off it there."""
    ijk, shape, centres, free, near, body = cells
    offsets, delta, length = leg
    cut = np.zeros(len(free), dtype=np.uint32)
    into = np.flatnonzero(near & free)
    rows = []
    for q in range(len(offsets)):
        src = ijk[into] - offsets[q]
        v = into[((src >= 0) & (src < shape)).all(axis=1)]
        u = v - delta[q]
        at_risk = free[u] & (body[u] + body[v] + 2.0 * radius < length[q])
        rows.append((q, v[at_risk], u[at_risk]))
    if not any(len(v) for _, v, _ in rows):
        return cut
    q_all = np.concatenate([np.full(len(v), q, dtype=np.int64) for q, v, _ in rows])
    v_all = np.concatenate([v for _, v, _ in rows])
    u_all = np.concatenate([u for _, _, u in rows])
    crossed = hits(centres[u_all], centres[v_all])
    np.bitwise_or.at(cut, v_all[crossed], (np.uint32(1) << q_all[crossed].astype(np.uint32)))
    return cut


CHUNK = 4096
"""Points per query of :func:`traced_hits`'s distances (the memory of a (points, bodies) table)."""


def traced_hits(
    a: np.ndarray, b: np.ndarray, distance: Callable[[np.ndarray], np.ndarray], touch: float, steps: int
) -> np.ndarray:
    """Per row: whether the segment ``a`` -> ``b`` meets a body, marched from ``a`` by the
    distance to the nearest body at each point (``distance``: points -> (points, bodies)
    distances; sphere tracing, exact for a 1-Lipschitz distance): met at a distance under
    ``touch`` within ``steps`` steps."""
    span = b - a
    size = np.linalg.norm(span, axis=1)
    unit = span / np.maximum(size, 1e-12)[:, None]
    t = np.zeros(len(a))
    hit = np.zeros(len(a), dtype=bool)
    live = np.arange(len(a))
    for _ in range(steps):
        if not len(live):
            break
        p = a[live] + t[live, None] * unit[live]
        c = np.concatenate([distance(p[k : k + CHUNK]).min(axis=1) for k in range(0, len(p), CHUNK)])
        met = c < touch
        hit[live[met]] = True
        t[live] += c
        live = live[~met & (t[live] < size[live])]
    return hit


def cell_gaps(near: np.ndarray, cell: np.ndarray, shape: np.ndarray) -> tuple[np.ndarray, float]:
    """Per cell the distance from its box to the nearest box of the cells ``near`` (bool, the
    grid's shape), and its largest value (inf, inf when there is none). The box-to-box distance
    between cells (i, j, k) and (i', j', k') is the root of the sum over the axes of
    ((|i - i'| - 1)^+ * cell)^2: a sum of one term per axis, so its minimum over the near cells
    is taken one axis after the other (a min-plus product with the term of that axis), exactly
    (compiled: ``gap_squares``)."""
    if not near.any():
        return np.full(near.size, np.inf), np.inf
    terms = tuple(
        np.array([(max(s - 1, 0) * cell[axis]) ** 2 for s in range(int(shape[axis]))]) for axis in range(3)
    )
    gap = np.sqrt(kernel_module("swarmplan.flight._guide_kernel").gap_squares(near.ravel(), shape, terms))
    return gap, float(gap.max())


def ways_floor(world: World, params: AgentParams) -> float:
    """The least height above the ground the guide's ways keep (less the radius the safety filter
    checks, ``kinematics.checked_radius``): the lowest ``min_altitude``, lowered to the lowest
    start or goal (its height above the ground less its agent's checked radius, at least 0): a
    goal below every ``min_altitude`` (the field reaches it, its push fading near the goal) must
    lie in free cells, or no way leads there, and a fast agent's ``min_altitude`` (tens of
    metres) left every way to such a goal through cells that are not free, bodies included."""
    if not len(params.min_altitude):
        return 0.0
    ends = np.array([p for a in world.agents for p in (a.start, a.goal)], dtype=float).reshape(-1, 3)
    above = ends[:, 2] - world.terrain_height(ends[:, :2]) - np.repeat(checked_radius(params.radius), 2)
    return max(0.0, min(float(np.min(params.min_altitude)), float(above.min())))


def past_way_end(
    pos: np.ndarray, goal: np.ndarray, ends: np.ndarray, goal_cells: np.ndarray, grid: tuple[np.ndarray, ...]
) -> np.ndarray:
    """Per agent at ``pos`` (n, 3): whether it flies at its ``goal`` itself rather than along its
    way, whose end cell (``ends``; ``grid``: the cells' indices and centres) lies farther than a
    cell from its goal's (``goal_cells``; :func:`source_cell`) and farther from the goal than
    the agent: such a way would lead it away from the goal, back up to its end."""
    ijk, centres = grid
    far = np.abs(ijk[ends] - ijk[goal_cells]).max(axis=1) > 1
    if not far.any():
        return far
    return far & (np.linalg.norm(pos - goal, axis=1) < np.linalg.norm(centres[ends] - goal, axis=1))


def face_room(
    clear: np.ndarray, centres: np.ndarray, bounds: tuple[np.ndarray, np.ndarray], radius: float
) -> np.ndarray:
    """The cells' ``clear`` (to the bodies and the ground, less ``radius``) taking in the flight
    volume's faces but the floor (``bounds``: its corners): the field holds an agent's body off
    them as off a wall, so a way between a face and a body keeps the room the body needs (the
    line of sight stays the bodies' and the ground's)."""
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    faces = np.minimum((centres[:, :2] - lo[:2]).min(axis=1), (hi - centres).min(axis=1)) - radius
    return np.minimum(clear, faces)


def by_way_end(
    pos: np.ndarray,
    goal: np.ndarray,
    cells: np.ndarray,
    ends: np.ndarray,
    goal_cells: np.ndarray,
    grid: tuple[np.ndarray, ...],
) -> np.ndarray:
    """Per agent at ``pos`` (n, 3) in ``cells``: whether it is in its goal's cell (``goal_cells``),
    a leg from its way's end (``ends``, the search's source) or nearer its ``goal`` than that
    end's centre (``grid``: the cells' indices and centres). With its goal in sight such an
    agent flies at the goal: not back out of a cell not free by the goal, nor round the legs
    the other ways have loaded near the end."""
    ijk, centres = grid
    near = (cells == goal_cells) | (np.abs(ijk[cells] - ijk[ends]).max(axis=1) <= 1)
    return near | (np.linalg.norm(pos - goal, axis=1) < np.linalg.norm(centres[ends] - goal, axis=1))
