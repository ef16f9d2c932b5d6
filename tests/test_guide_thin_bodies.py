"""The guide round bodies thinner than its cells (swarmplan.flight.guide): no leg of a way runs
through a thin wall, and the search for a goal tucked under a thin slab starts where the goal is
in sight. (Worlds of ``bench reach`` that failed on these fly in tests/reach_regressions.)"""

from __future__ import annotations

import numpy as np
from helpers import base_world, make_world

from swarmplan.flight import guide as G
from swarmplan.flight import guide_graph
from swarmplan.flight.kinematics import AgentParams

# A field 400 x 200 x 100 m (cells of 5.8 m along x, centres at 200.0 and 205.8 m) with a wall
# 1 m thick across it at x = 203, between those centres, from y = 40 to 160 and up to the
# bounds' top: only its two ends lead round it.
THIN_WALL = [{"id": "wall", "shape": "box", "size": [1, 120, 100], "position": [203, 100, 50]}]
# A slab 2 m thick, 100 x 100 m, its underside 40 m up, through the middle of a layer of cells
# (5.56 m high: 38.9 to 44.4 m).
THIN_SLAB = [{"id": "slab", "shape": "box", "size": [100, 100, 2], "position": [200, 100, 41]}]


def _guide(obstacles, start, goal):
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [400, 200, 100]},
        obstacles=obstacles,
        agents=[{"id": "a", "start": list(start), "goal": list(goal)}],
    )
    raw["agent_defaults"] = {**raw["agent_defaults"], "radius": 0.5, "separation": [1, 1, 1]}
    world = make_world(raw)
    return G.make_guide(world, AgentParams.from_world(world))


def _crosses_wall(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment a -> b passes through the wall's box (x 202.5..203.5, y 40..160)."""
    t = np.linspace(0.0, 1.0, 2001)[:, None]
    p = a + t * (b - a)
    inside = (np.abs(p[:, 0] - 203.0) <= 0.5) & (np.abs(p[:, 1] - 100.0) <= 60.0) & (p[:, 2] <= 100.0)
    return bool(inside.any())


def test_no_leg_of_a_way_runs_through_a_wall_thinner_than_a_cell():
    start, goal = np.array([100.0, 100.0, 30.0]), np.array([205.5, 100.0, 30.0])
    guide = _guide(THIN_WALL, start, goal)
    assert guide.cell.min() > 4.0  # the wall is a sixth of a cell thick
    row = int(guide._rows_for(guide.cell_of(goal[None]), start[None], goal[None])[0])
    way = guide._way(row, int(guide.cell_of(start[None])[0]))
    assert way[-1] == guide._source[row]
    pts = np.vstack([start, guide.centres[way[1:]], goal])
    assert not any(_crosses_wall(pts[k], pts[k + 1]) for k in range(len(pts) - 1))
    # round one of the wall's ends: the way is at least the detour's length
    detour = np.hypot(103.0, 60.0) + np.hypot(2.5, 60.0)
    assert np.linalg.norm(np.diff(pts, axis=0), axis=1).sum() > detour - 2.0 * guide.cell.max()


def test_legs_through_the_wall_are_cut_and_legs_beside_it_kept():
    guide = _guide(THIN_WALL, (100.0, 100.0, 30.0), (300.0, 100.0, 30.0))
    offsets, delta, length, _, _ = G.legs(guide.shape, guide.cell)
    cells = (guide.ijk, guide.shape, guide.centres, guide.free, guide.near, guide._body_clear)
    cut = guide_graph.crossing_legs(cells, guide.radius, (offsets, delta, length), guide._traced_hits)
    v, q = np.nonzero((cut[:, None] >> np.arange(len(offsets), dtype=np.uint32)) & 1)
    assert len(v)
    u = v - delta[q]
    # every leg cut runs through the wall, and every free leg across its plane within its
    # extent (between two free cells whose centres straddle x = 203 at y 50..150) is cut
    assert all(_crosses_wall(guide.centres[a], guide.centres[b]) for a, b in zip(u, v, strict=True))
    c = guide.centres
    cut_set = set(zip(u.tolist(), v.tolist(), strict=True))
    for k in range(len(offsets)):
        into = np.flatnonzero(guide.free & guide.near)
        src = guide.ijk[into] - offsets[k]
        ok = ((src >= 0) & (src < guide.shape)).all(axis=1)
        vv = into[ok]
        uu = vv - delta[k]
        across = guide.free[uu] & ((c[uu, 0] - 203.0) * (c[vv, 0] - 203.0) < 0.0)
        mid = 0.5 * (c[uu] + c[vv])
        across &= (np.abs(mid[:, 1] - 100.0) < 50.0) & (mid[:, 2] < 90.0)
        assert all((a, b) in cut_set for a, b in zip(uu[across].tolist(), vv[across].tolist(), strict=True))


def test_a_goal_under_a_thin_slab_is_searched_from_where_it_is_in_sight():
    """The goal, 0.3 m under the slab, lies in a cell whose centre is in the slab (not free); free
    cells lie both above the slab (the most clearance) and under it: the search starts under it,
    where the goal is in sight."""
    goal = np.array([200.0, 100.0, 39.2])
    guide = _guide(THIN_SLAB, (200.0, 100.0, 80.0), goal)
    cell = int(guide.cell_of(goal[None])[0])
    assert not guide.free[cell] and 40.0 < guide.centres[cell][2] < 42.0
    source = guide._source_of(cell, goal)
    assert guide.free[source]
    assert guide.centres[source][2] < 40.0  # under the slab's underside
    assert not guide._traced_hits(guide.centres[source][None], goal[None])[0]


def test_a_goal_just_above_a_thin_plate_is_sought_from_above_it():
    """A 5^3 grid of unit cells; a plate 0.2 thick at z 2.0..2.2 and the goal 0.2 above it, in
    the cell (2, 2, 2). The plate inflated by the largest body takes the layers z = 2 and 3;
    the free cells next to the goal's (z = 1) see it only through the plate: the source is the
    free cell nearest the goal that sees it, two cells up, not a neighbour under the plate."""
    shape = np.array([5, 5, 5])
    ijk = np.stack(np.meshgrid(*(np.arange(5),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = ijk.astype(float)
    free = (ijk[:, 2] <= 1) | (ijk[:, 2] == 4)
    clear = np.where(free, 1.0, -1.0) + 0.01 * ijk[:, 0]  # the most clearance at x = 4
    goal = np.array([2.0, 2.0, 2.4])

    def hits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        lo, hi = np.minimum(a[:, 2], b[:, 2]), np.maximum(a[:, 2], b[:, 2])
        return (lo <= 2.2) & (hi >= 2.0)

    cell = (2 * 5 + 2) * 5 + 2
    source = guide_graph.source_cell(free, clear, (ijk, centres, shape), cell, (goal, hits))
    assert ijk[source].tolist() == [2, 2, 4]
    # Without the sight test, the free neighbour with the most clearance (under the plate).
    blind = guide_graph.source_cell(free, clear, (ijk, centres, shape), cell)
    assert ijk[blind][2] == 1 and ijk[blind][0] == 3


def test_a_leg_from_its_ways_end_with_the_goal_in_sight_an_agent_flies_at_the_goal():
    """Under the slab, the goal 0.3 m below its underside: an agent one leg from the way's end
    (its source cell) that sees the goal is drawn at the goal itself, though the way from its
    cell goes round; one farther off under the slab, also in sight of it, along its way."""
    goal = np.array([200.0, 100.0, 39.2])
    guide = _guide(THIN_SLAB, (200.0, 100.0, 80.0), goal)
    cell = int(guide.cell_of(goal[None])[0])
    source = guide._source_of(cell, goal)
    step = guide.ijk[source] + np.array([1, 1, 0])
    near = guide.lo + (step + 0.5) * guide.cell  # a cell one leg from the source's, beside it
    far = guide.lo + (guide.ijk[source] + np.array([4, 0, 0]) + 0.5) * guide.cell
    for p in (near, far):
        assert guide.free[int(guide.cell_of(p[None])[0])]
        assert not guide._traced_hits(p[None], goal[None])[0]
    # Ways of other agents out through the source past the near cell load the leg back in (the
    # negotiated congestion): the way from the near cell goes round, the agent at the goal.
    near_cell = int(guide.cell_of(near[None])[0])
    for _ in range(30):
        guide._load([source, near_cell])
    row = int(guide._rows_for(np.array([cell]), near[None], goal[None])[0])
    assert len(guide._way(row, near_cell)) > 2
    pos = np.vstack([near, far])
    goals = np.vstack([goal, goal])
    guide.guided[:] = True
    idx = np.zeros(2, dtype=np.int64)
    target, scale = guide.targets(1, idx, pos, goals, goals.copy(), np.ones(2))
    assert np.array_equal(target[0], goal)
    assert not np.array_equal(target[1], goal)


def test_an_agent_nearer_its_goal_than_its_ways_end_with_the_goal_in_sight_flies_at_it():
    """A goal 0.2 m above the ground (its cell and the cells beside it inside the ground inflated
    by the body): an agent in a cell by the goal's, more than a leg from the way's end but nearer
    the goal than that end's centre, flies at the goal (its way led it out and back in)."""
    goal = np.array([8.93, 6.49, 0.186])
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [9.8, 9.7, 4.1]},
        obstacles=[{"id": "box", "shape": "box", "size": [0.7, 1.5, 3.5], "position": [4.2, 3.0, 1.75]}],
        agents=[{"id": "a", "start": [2.3, 5.0, 2.5], "goal": goal.tolist()}],
    )
    raw["agent_defaults"] = {**raw["agent_defaults"], "radius": 0.09, "separation": [0.2, 0.2, 0.2]}
    raw["agent_defaults"]["min_altitude"] = 0.0
    world = make_world(raw)
    guide = G.make_guide(world, AgentParams.from_world(world))
    cell = int(guide.cell_of(goal[None])[0])
    assert not guide.free[cell]
    source = guide._source_of(cell, goal)
    p = np.array([9.2, 6.3, 0.1])
    at = int(guide.cell_of(p[None])[0])
    assert not guide.free[at] and np.abs(guide.ijk[at] - guide.ijk[source]).max() >= 2
    assert np.linalg.norm(p - goal) < np.linalg.norm(guide.centres[source] - goal)
    assert not guide._traced_hits(p[None], goal[None])[0]
    guide.guided[:] = True
    one = np.zeros(1, dtype=np.int64)
    target, _ = guide.targets(1, one, p[None], goal[None], goal[None].copy(), np.ones(1))
    assert np.array_equal(target[0], goal)
