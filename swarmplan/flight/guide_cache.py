"""The static guide's tables kept between runs (:mod:`swarmplan.runtime.disk_cache`).

A :class:`~swarmplan.flight.guide.StaticGuide` costs its world a grid (the cells' clearance,
the reversed graph, the line-of-sight bounds) and, at the first reset, the ways of the agents
whose line is blocked: work that depends on the world's geometry and the agents' starts and
goals alone, and that needs the compiled kernels (numba's load, ~0.45 s per process, is most of
it in a small world). Both are stored after they are computed and read back when a later guide
is built for the same inputs, array for array, so a guide read back holds the very bits a
computed one holds and every run goes on identically (tests/test_guide_cache.py).

- **The grid** is keyed by what it is computed from: the world's box, its number of agents (the
  grid's resolution), its terrain, the bodies at rest (all their fields), the largest agent
  radius, the lowest altitude and the guide's constants.
- **The ways found at the first reset** are keyed by the grid's key and the agents' starts,
  goals and which agents may be guided. They are read back only into a guide that has found no
  way yet, since each way found re-prices the legs of the ways after it.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.runtime import disk_cache

if TYPE_CHECKING:
    from swarmplan.flight.guide import StaticGuide

_GRID_ARRAYS = ("clear", "_body_clear", "_gap", "_reach")
_GRAPH_ARRAYS = ("indptr", "indices", "data")


def _constants() -> dict[str, float]:
    """The guide module's constants (tests may change them: a changed constant is another key)."""
    module = sys.modules["swarmplan.flight.guide"]
    return {k: v for k, v in vars(module).items() if k.isupper() and isinstance(v, int | float)}


def grid_key(guide: StaticGuide) -> str:
    """The key of ``guide``'s grid (see the module docstring)."""
    w = guide.world
    return disk_cache.digest(
        "guide grid",
        _constants(),
        w.bounds_min,
        w.bounds_max,
        len(w.agents),
        w.peaks,
        guide.bodies,
        guide.radius,
        guide.floor,
    )


def load_grid(guide: StaticGuide, key: str) -> bool:
    """Set ``guide``'s grid tables from the entry under ``key``; whether there was one."""
    a = disk_cache.load("guide-grid", key)
    if a is None or a["clear"].shape != (guide.n_cells,):
        return False
    for name in _GRID_ARRAYS:
        setattr(guide, name, a[name])
    guide._low, guide._gap_max = int(a["low"]), float(a["gap_max"])
    guide._box_half = a["box_half"] if bool(a["has_box_half"]) else None
    guide._proximity()
    guide._adopt_graph(*(a[name] for name in _GRAPH_ARRAYS), a["mask"])
    return True


def store_grid(guide: StaticGuide, key: str) -> None:
    """Store ``guide``'s grid tables (right after they are computed) under ``key``."""
    g = guide._reverse
    disk_cache.save(
        "guide-grid",
        key,
        {
            **{name: getattr(guide, name) for name in _GRID_ARRAYS},
            "indptr": g.indptr,
            "indices": g.indices,
            "data": g.data,
            "mask": g.grid[0],
            "low": np.array(guide._low),
            "gap_max": np.array(guide._gap_max),
            "has_box_half": np.array(guide._box_half is not None),
            "box_half": np.zeros((0, 3)) if guide._box_half is None else guide._box_half,
        },
    )


def ways_key(grid: str, pos: np.ndarray, goal: np.ndarray, can_stop: np.ndarray) -> str:
    """The key of the ways a fresh guide with grid key ``grid`` finds at a reset to ``pos``,
    ``goal`` (n, 3) with ``can_stop`` (who may be guided)."""
    return disk_cache.digest("guide ways", grid, np.asarray(pos, float), np.asarray(goal, float), can_stop)


def _changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rows where ``a`` and ``b`` differ in any bit (-0.0 against 0.0 included)."""
    x = np.ascontiguousarray(a).view(np.uint8).reshape(len(a), -1)
    y = np.ascontiguousarray(b).view(np.uint8).reshape(len(b), -1)
    return np.flatnonzero((x != y).any(axis=1))


def _legs_of(guide: StaticGuide, cells: np.ndarray) -> np.ndarray:
    """The stored legs into ``cells`` (their rows of the graph's arrays)."""
    g = guide._reverse
    lo, count = g.indptr[cells].astype(np.int64), np.diff(g.indptr)[cells].astype(np.int64)
    return np.repeat(lo - np.cumsum(count) + count, count) + np.arange(int(count.sum()))


def store_ways(guide: StaticGuide, key: str) -> None:
    """Store what a fresh ``guide``'s reset changed (the ways found, the legs they re-priced,
    the loads and which agents it guides) under ``key``: only the parts that differ from a fresh
    guide's, so an entry is a few MB at most."""
    g = guide._reverse
    priced = _changed(g.data, guide._base)
    flow = _changed(guide._flow, np.zeros_like(guide._flow))
    legs = _legs_of(guide, np.flatnonzero(guide._has_dir))
    rows = len(guide._source)
    goal_cells = np.flatnonzero(guide._row_of >= 0)
    disk_cache.save(
        "guide-ways",
        key,
        {
            "guided": guide.guided,
            "priced": priced,
            "prices": g.data[priced],
            "flow_cells": flow,
            "flow": guide._flow[flow],
            "has_dir": guide._has_dir,
            "leg_dir": guide._leg_dir[legs],
            "goal_cells": goal_cells,
            "goal_rows": guide._row_of[goal_cells],
            "next": guide._next[:rows],
            "dist": guide._dist[:rows],
            "capacity": np.array(len(guide._next)),
            "source": guide._source,
        },
    )


def load_ways(guide: StaticGuide, key: str) -> bool:
    """Put the reset stored under ``key`` into the fresh ``guide``; whether there was one."""
    a = disk_cache.load("guide-ways", key)
    if a is None or a["guided"].shape != guide.guided.shape or a["has_dir"].shape != guide._has_dir.shape:
        return False
    n = guide.n_cells
    rows, capacity = len(a["source"]), int(a["capacity"])
    legs = _legs_of(guide, np.flatnonzero(a["has_dir"]))
    # Every part checked before the guide is touched: an entry is taken whole or not at all.
    if (
        a["next"].shape != (rows, n)
        or a["dist"].shape != (rows, n)
        or capacity < rows
        or len(legs) != len(a["leg_dir"])
        or len(a["priced"]) != len(a["prices"])
        or len(a["flow_cells"]) != len(a["flow"])
        or len(a["goal_cells"]) != len(a["goal_rows"])
    ):
        return False
    guide.guided[:] = a["guided"]
    guide._reverse.data[a["priced"]] = a["prices"]
    guide._flow[a["flow_cells"]] = a["flow"]
    guide._has_dir[:] = a["has_dir"]
    guide._leg_dir[legs] = a["leg_dir"]
    guide._row_of[a["goal_cells"]] = a["goal_rows"]
    guide._next = np.empty((capacity, n), dtype=np.int32)
    guide._dist = np.empty((capacity, n), dtype=np.float32)
    guide._next[:rows], guide._dist[:rows] = a["next"], a["dist"]
    guide._source = a["source"]
    return True
