"""The static guide's grid graph: the 26 neighbours of a cell and the legs between cells
(:mod:`swarmplan.flight.guide`; the searches over it: ``_guide_kernel.dijkstra``), the source
cell of a goal's search and the least height the ways keep."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

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
    sees: Callable[[np.ndarray], np.ndarray] | None = None,
) -> int:
    """The source of the search for a goal in ``cell`` (``grid``: the cells' indices, centres
    and the grid's shape): the cell, or the free neighbour with the most clearance when the
    goal's own cell is not free; with no free neighbour either (a goal tucked into a corner by
    more than a cell), the free cell nearest the goal's cell (by their centres) in the first
    ring of cells round it (at 2, 3, ... cells along the farthest axis) that holds one: a
    source that is not free would be entered by no free cell, and no way would lead there.
    With ``sees`` (cells -> whether the goal is in sight from each one's centre), the cell and
    its free neighbours from which the goal is in sight come first: a goal under a slab or
    behind a wall thinner than a cell has free neighbours on the far side of the body too, and
    a way that ended there left the agent pulled at the goal through the body."""
    ijk, centres, shape = grid
    nb = ijk[cell] + OFFSETS
    nb = nb[((nb >= 0) & (nb < shape)).all(axis=1)]
    flat = (nb[:, 0] * shape[1] + nb[:, 1]) * shape[2] + nb[:, 2]
    if sees is not None:
        if free[cell] and bool(sees(np.array([cell]))[0]):
            return cell
        near = flat[free[flat]]
        if len(near):
            seen = near[sees(near)]
            if len(seen):
                return int(seen[np.argmax(clear[seen])])
    if free[cell]:
        return cell
    if free[flat].any() or not free.any():
        return int(flat[np.argmax(clear[flat])])
    at = ijk[cell]
    for k in range(2, int(shape.max()) + 1):
        lo, hi = np.maximum(at - k, 0), np.minimum(at + k, shape - 1)
        axes = (np.arange(a, b + 1) for a, b in zip(lo, hi, strict=True))
        box = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        box = box[np.abs(box - at).max(axis=1) == k]  # the ring at k cells
        flat = (box[:, 0] * shape[1] + box[:, 1]) * shape[2] + box[:, 2]
        ring = flat[free[flat]]
        if len(ring):
            return int(ring[np.argmin(np.linalg.norm(centres[ring] - centres[cell], axis=1))])
    return cell


def ways_floor(world: World, params: AgentParams) -> float:
    """The least height above the ground the guide's ways keep (less the radius): the lowest
    ``min_altitude``, lowered to the lowest start or goal (its height above the ground less its
    agent's radius, at least 0): a goal below every ``min_altitude`` (the field reaches it, its
    push fading near the goal) must lie in free cells, or no way leads there, and a fast
    agent's ``min_altitude`` (tens of metres) left every way to such a goal through cells that
    are not free, bodies included."""
    if not len(params.min_altitude):
        return 0.0
    ends = np.array([p for a in world.agents for p in (a.start, a.goal)], dtype=float).reshape(-1, 3)
    above = ends[:, 2] - world.terrain_height(ends[:, :2]) - np.repeat(params.radius, 2)
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
