"""The static guide's grid graph: the 26 neighbours of a cell and the legs between cells
(:mod:`swarmplan.flight.guide`; the searches over it: ``_guide_kernel.dijkstra``)."""

from __future__ import annotations

import dataclasses

import numpy as np


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
