"""The static guide's tables kept between runs (:mod:`swarmplan.runtime.disk_cache`).

A :class:`~swarmplan.flight.guide.StaticGuide` costs its world a grid (the cells' clearance,
the reversed graph, the line-of-sight bounds) and, at the first reset, the ways of the agents
whose line is blocked: work that depends on the world's geometry and the agents' starts and
goals alone, and that needs the compiled kernels (numba's load, ~0.45 s per process, is most of
it in a small world). Both are stored after they are computed and read back when a later guide
is built for the same inputs, array for array, so a guide read back holds the very bits a
computed one holds and every run goes on identically (tests/test_guide_cache.py).

This module keys and stores named arrays; the guide says which arrays make its tables
(``StaticGuide.grid_tables`` / ``ways_tables``) and takes them back itself.

- **The grid** is keyed by what it is computed from: the world's box, its number of agents (the
  grid's resolution), its terrain, the bodies at rest (all their fields), the largest agent
  radius, the lowest altitude and the guide's constants.
- **The ways found at the first reset** are keyed by the grid's key and the agents' starts,
  goals and which agents may be guided. They are read back only into a guide that has found no
  way yet, since each way found re-prices the legs of the ways after it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from swarmplan.runtime import disk_cache

if TYPE_CHECKING:
    from swarmplan.world.model import Obstacle, World


def grid_key(
    constants: dict[str, float], world: World, bodies: tuple[Obstacle, ...], radius: float, floor: float
) -> str:
    """The key of a guide's grid over ``world`` round ``bodies`` for agents of largest ``radius``
    kept above ``floor``, with the guide's ``constants`` (see the module docstring)."""
    return disk_cache.digest(
        "guide grid",
        constants,
        world.bounds_min,
        world.bounds_max,
        len(world.agents),
        world.peaks,
        bodies,
        radius,
        floor,
    )


def load_grid(key: str, n_cells: int) -> dict[str, np.ndarray] | None:
    """The grid tables stored under ``key`` for a grid of ``n_cells`` cells, or None."""
    a = disk_cache.load("guide-grid", key)
    if a is None or a["clear"].shape != (n_cells,):
        return None
    return a


def store_grid(key: str, tables: dict[str, np.ndarray]) -> None:
    """Store a guide's grid ``tables`` (right after they are computed) under ``key``."""
    disk_cache.save("guide-grid", key, tables)


def ways_key(grid: str, pos: np.ndarray, goal: np.ndarray, can_stop: np.ndarray) -> str:
    """The key of the ways a fresh guide with grid key ``grid`` finds at a reset to ``pos``,
    ``goal`` (n, 3) with ``can_stop`` (who may be guided)."""
    return disk_cache.digest("guide ways", grid, np.asarray(pos, float), np.asarray(goal, float), can_stop)


def changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rows where ``a`` and ``b`` differ in any bit (-0.0 against 0.0 included)."""
    x = np.ascontiguousarray(a).view(np.uint8).reshape(len(a), -1)
    y = np.ascontiguousarray(b).view(np.uint8).reshape(len(b), -1)
    return np.flatnonzero((x != y).any(axis=1))


def legs_into(indptr: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The rows of a CSR graph's arrays (``indptr``) that hold the legs into ``cells``."""
    lo, count = indptr[cells].astype(np.int64), np.diff(indptr)[cells].astype(np.int64)
    return np.repeat(lo - np.cumsum(count) + count, count) + np.arange(int(count.sum()))


def store_ways(key: str, tables: dict[str, np.ndarray]) -> None:
    """Store what a fresh guide's reset changed (``StaticGuide.ways_tables``) under ``key``."""
    disk_cache.save("guide-ways", key, tables)


def load_ways(key: str, agents: int, n_cells: int, indptr: np.ndarray) -> dict[str, np.ndarray] | None:
    """The reset stored under ``key`` for a guide of ``agents`` agents over ``n_cells`` cells whose
    reversed graph has ``indptr``, checked whole (every array's shape against the others'), with
    ``legs``: the graph's rows of its ``leg_dir``; or None."""
    a = disk_cache.load("guide-ways", key)
    if a is None or a["guided"].shape != (agents,) or a["has_dir"].shape != (n_cells,):
        return None
    rows, capacity = len(a["source"]), int(a["capacity"])
    a["legs"] = legs_into(indptr, np.flatnonzero(a["has_dir"]))
    if (
        a["next"].shape != (rows, n_cells)
        or a["dist"].shape != (rows, n_cells)
        or capacity < rows
        or len(a["legs"]) != len(a["leg_dir"])
        or len(a["priced"]) != len(a["prices"])
        or len(a["flow_cells"]) != len(a["flow"])
        or len(a["goal_cells"]) != len(a["goal_rows"])
    ):
        return None
    return a
