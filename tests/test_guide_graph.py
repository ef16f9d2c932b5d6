"""The guide's graph (swarmplan.flight.guide) against a plain construction of it: the reversed
graph built in one compiled pass (the rows of the cells near surfaces, the other cells' legs
implied by their offsets) equals, to the bit, the one scipy builds from the list of legs and
transposes, and re-pricing a way's cells gives the legs the costs computed cell by cell from
the cells' centres. The searches run on these arrays, so equal arrays mean equal ways; and the
compiled search finds scipy's distances and predecessors to the bit, on the guide's graph and
on small grids with random costs (ties among equal distances included), reading the legs'
start cells and, away from surfaces, their costs from the offsets."""

from __future__ import annotations

import numpy as np
from helpers import base_world, make_world
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from swarmplan.flight import _guide_kernel as K
from swarmplan.flight import guide as G
from swarmplan.flight import guide_graph
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.batch import ShapeBatch

# A wall with one gap and a pillar: free cells, cells inside the inflated obstacles, cells near
# surfaces on every side.
OBSTACLES = [
    {"id": "south", "shape": "box", "size": [1, 47, 60], "position": [50, 23.5, 25]},
    {"id": "north", "shape": "box", "size": [1, 47, 60], "position": [50, 76.5, 25]},
    {"id": "pillar", "shape": "cylinder", "radius": 2.0, "height": 30.0, "position": [70, 40, 15]},
]


def _guide(agents: int = 1) -> G.StaticGuide:
    agents = [
        {"id": f"a{k}", "start": [30.0, 20.0 + 5 * k, 20.0], "goal": [80.0, 60.0 - 5 * k, 20.0]}
        for k in range(agents)
    ]
    world = make_world(base_world(obstacles=OBSTACLES, agents=agents))
    return G.make_guide(world, AgentParams.from_world(world))


def _reference_graph(guide: G.StaticGuide) -> csr_matrix:
    """The legs listed offset by offset, assembled by scipy and transposed (row v: legs into v)."""
    nx, ny, nz = (int(v) for v in guide.shape)
    clear, normal, _ = guide._clearance(guide.centres)
    # the flight volume's faces but the floor hold a body off as a wall does
    c, lo, hi = guide.centres, guide.world.bounds_min, guide.world.bounds_max
    faces = np.stack([c[:, 0] - lo[0], c[:, 1] - lo[1], hi[0] - c[:, 0], hi[1] - c[:, 1], hi[2] - c[:, 2]])
    room = np.minimum(clear, faces.min(axis=0) - guide.radius)
    prox = np.clip(1.0 - room / max(2.0 * float(guide.cell.max()), 4.0), 0.0, 1.0)
    free = room > 0.0
    flat = np.arange(guide.n_cells).reshape(nx, ny, nz)
    rows, cols, cost = [], [], []
    for o in guide_graph.OFFSETS:
        src = flat[
            max(0, -o[0]) : nx - max(0, o[0]),
            max(0, -o[1]) : ny - max(0, o[1]),
            max(0, -o[2]) : nz - max(0, o[2]),
        ].ravel()
        dst = src + (o[0] * ny + o[1]) * nz + o[2]
        keep = free[dst] | ~free[src]
        src, dst = src[keep], dst[keep]
        step = o * guide.cell
        length = float(np.linalg.norm(step))
        e = step / length
        right = np.array([e[1], -e[0], 0.0])
        nr = float(np.linalg.norm(right))
        side = np.maximum(normal[dst] @ (right / nr), 0.0) if nr > 0.2 else np.zeros(len(dst))
        w = length * (1.0 + prox[dst] * (G.NEAR + G.RIGHT * side))
        rows.append(src)
        cols.append(dst)
        cost.append(np.where(free[dst], w, 10.0 * length))
    g = csr_matrix(
        (np.concatenate(cost), (np.concatenate(rows), np.concatenate(cols))), shape=(guide.n_cells,) * 2
    )
    return g.T.tocsr()


def _expand(indptr, indices, data, grid) -> csr_matrix:
    """The whole graph: the stored rows, and the legs of the other cells from their offsets (their
    start cells the cell less the offset's delta, their costs its length)."""
    mask, read, delta, length = grid
    bits = ((mask[:, None] >> np.arange(len(delta), dtype=np.uint32)) & 1).astype(bool)
    v, q = np.nonzero(bits)  # cell by cell, offset by offset
    cost = length[q].copy()
    cost[read[v]] = data
    stored = np.repeat(np.arange(len(mask)), np.diff(indptr))
    assert np.array_equal(stored, v[read[v]]) and np.array_equal(indices, (v - delta[q])[read[v]])
    full = np.concatenate([[0], np.cumsum(bits.sum(axis=1))]).astype(np.int32)
    return csr_matrix((cost, (v - delta[q]).astype(np.int32), full), shape=(len(mask),) * 2)


def test_the_graph_built_in_place_is_the_one_scipy_assembles():
    guide = _guide()
    ref, got = _reference_graph(guide), guide._reverse
    full = _expand(got.indptr, got.indices, got.data, got.grid)
    assert np.array_equal(full.indptr, ref.indptr)
    assert np.array_equal(full.indices, ref.indices)
    assert np.array_equal(full.data.view(np.int64), ref.data.view(np.int64))
    read = got.grid[1]
    assert read.any() and not read.all() and len(got.data) < len(ref.data)  # rows near surfaces
    # and so the same search: distances and next cells, from a goal behind the wall and from
    # cells all over the grid, scipy's on scipy's graph and the compiled one on the guide's
    cells = [int(guide.cell_of(np.array([[80.0, 60.0, 20.0]]))[0])]
    cells += np.random.default_rng(2).choice(guide.n_cells, 5, replace=False).tolist()
    for source in cells:
        d0, p0 = dijkstra(ref, directed=True, indices=source, return_predecessors=True)
        d1, p1 = K.dijkstra(got.indptr, got.data, got.grid, source)
        assert np.array_equal(d0.view(np.int64), d1.view(np.int64))
        assert np.array_equal(p0, p1)
        assert np.isfinite(d1).sum() > guide.n_cells // 2  # the free space is reached


def test_the_compiled_search_is_scipys_on_random_grids():
    rng = np.random.default_rng(11)
    for trial in range(30):
        shape = rng.integers(2, 8, 3)
        n = int(np.prod(shape))
        offsets, delta, length, row, rights = guide_graph.legs(shape, np.ones(3))  # equal cells: ties
        free = rng.random(n) < 0.8
        prox = np.where(rng.random(n) < 0.5, 0.0, rng.choice([0.25, 0.5, 1.0], n))
        prox[~free] = 1.0
        side = rng.uniform(-1.0, 1.0, (len(rights), n))
        indptr, indices, data, mask = K.reverse_graph(
            free,
            prox,
            side,
            (offsets, delta, length, row),
            shape,
            (G.NEAR, G.RIGHT),
            np.zeros(n, dtype=np.uint32),
        )
        read = prox > 0.0
        # the legs stored (into cells near surfaces): costs from a few values (many ways of equal length,
        # where only the order of the search decides the predecessor) or random ones
        if trial % 2:
            data[:] = rng.choice([0.5, 1.0, 1.5, 2.0, np.sqrt(2.0)], len(data))
        else:
            data[:] = rng.uniform(0.1, 5.0, len(data))
        g = _expand(indptr, indices, data, (mask, read, delta, length))
        for source in rng.choice(n, 3, replace=False).tolist():
            d0, p0 = dijkstra(g, directed=True, indices=source, return_predecessors=True)
            d1, p1 = K.dijkstra(indptr, data, (mask, read, delta, length), source)
            assert np.array_equal(d0.view(np.int64), d1.view(np.int64))
            assert np.array_equal(p0, p1)
    # and on a line of three cells, by hand: legs of length 1, those into the middle cell
    # (near a surface: its row stored) 3 = 1 + 1 * NEAR; the ways to the top cell
    shape = np.array([1, 1, 3])
    offsets, delta, length, row, rights = guide_graph.legs(shape, np.ones(3))
    free, prox = np.ones(3, dtype=bool), np.array([0.0, 1.0, 0.0])
    indptr, indices, data, mask = K.reverse_graph(
        free,
        prox,
        np.zeros((len(rights), 3)),
        (offsets, delta, length, row),
        shape,
        (G.NEAR, G.RIGHT),
        np.zeros(3, dtype=np.uint32),
    )
    assert indptr.tolist() == [0, 0, 2, 2] and indices.tolist() == [0, 2] and data.tolist() == [3.0, 3.0]
    d, p = K.dijkstra(indptr, data, (mask, prox > 0.0, delta, length), 2)
    assert d.tolist() == [4.0, 1.0, 0.0] and p.tolist() == [1, 2, K.NO_WAY]


def test_re_pricing_gives_each_leg_the_cost_computed_cell_by_cell():
    guide = _guide(agents=4)
    pos = np.array([[30.0, 20.0 + 5 * k, 20.0] for k in range(4)])
    goal = np.array([[80.0, 60.0 - 5 * k, 20.0] for k in range(4)])
    guide.reset(pos, goal)
    flow = guide._flow
    loaded = np.flatnonzero(np.abs(flow).sum(axis=1) > 0)
    assert len(loaded) > 0  # the ways pass the gap: cells near its edges carry them
    g = guide._reverse
    expect = guide._base.copy()
    for v in loaded.tolist():
        lo, hi = g.indptr[v], g.indptr[v + 1]
        e = guide.centres[v] - guide.centres[g.indices[lo:hi]]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        f = flow[v]
        expect[lo:hi] = guide._base[lo:hi] * (
            1.0 + G.SAME * float(np.linalg.norm(f)) + G.ONCOMING * np.maximum(-(e @ f), 0.0)
        )
    assert np.array_equal(g.data.view(np.int64), expect.view(np.int64))
    assert (g.data != guide._base).any()  # the loads did re-price legs


def test_the_cells_clearance_from_the_compiled_query_is_numpys():
    guide = _guide()
    assert guide._batch.compiled
    clear, normal, _ = guide._clearance(guide.centres)
    guide._batch = ShapeBatch(guide.bodies)  # numpy's query
    ref_clear, ref_normal, _ = guide._clearance(guide.centres)
    assert np.array_equal(clear.view(np.int64), ref_clear.view(np.int64))
    assert np.array_equal(normal.view(np.int64), ref_normal.view(np.int64))
    assert (clear < 0).any() and (clear > 5).any()  # inside the wall and the pillar, and far out


def test_the_points_of_attraction_follow_the_tables():
    """The compiled way points against the tables read in numpy: the cell two legs on from
    the agent's cell, or the goal at the way's end or where no way leads from the cell."""
    guide = _guide(agents=4)
    pos = np.array([[30.0, 20.0 + 5 * k, 20.0] for k in range(4)])
    goal = np.array([[80.0, 60.0 - 5 * k, 20.0] for k in range(4)])
    guide.reset(pos, goal)
    rng = np.random.default_rng(4)
    p = rng.uniform(guide.lo - 5.0, guide.lo + guide.shape * guide.cell + 5.0, (400, 3))
    p[:10] = goal[0] + rng.normal(size=(10, 3))  # at the end of a way
    g = goal[rng.integers(0, 4, 400)]
    table = guide._rows_for(guide.cell_of(g), p, g)
    cell = guide.cell_of(p)
    lost = ~np.isfinite(guide._dist[table, cell])
    for _ in range(G.HOPS):
        nxt = guide._next[table, cell]
        cell = np.where(nxt >= 0, nxt, cell)
    home = (cell == guide._source[table]) | lost
    expect = np.where(home[:, None], g, guide.centres[cell])
    grid = (guide.lo, guide.cell, guide.shape, guide.centres)
    got = K.way_points(p, g, table, grid, (guide._next, guide._dist, guide._source), G.HOPS)
    assert np.array_equal(got, expect)
    assert 0 < home.sum() < len(p)  # goals reached and cells on the way


def test_a_way_keeps_its_body_off_the_faces_of_the_flight_volume():
    """A pole 0.3 m from the face x = 0 of a small room, floor to ceiling, between a 0.15 m
    agent's start and goal: the gap leaves its centre room (the bounds hold the centre) but not
    its body (the field holds the body off a face as off a wall). The way goes round the pole's
    far side, every cell of it a body's room from the faces."""
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [4, 4, 3]},
        sim={"dt": 0.05, "max_time": 20, "goal_tolerance": 0.1},
        obstacles=[
            {"id": "pole", "shape": "cylinder", "radius": 0.08, "height": 3.0, "position": [0.38, 2.0, 1.5]}
        ],
        agents=[{"id": "a", "start": [0.3, 1.0, 1.5], "goal": [0.3, 3.0, 1.5]}],
    )
    raw["agent_defaults"] = {
        **raw["agent_defaults"],
        "radius": 0.15,
        "speed": {"min": 0, "max": 1.0, "cruise": 0.8},
        "max_accel": 2.0,
        "separation": [0.3, 0.3, 0.3],
        "min_altitude": 0.3,
    }
    world = make_world(raw)
    guide = G.make_guide(world, AgentParams.from_world(world))
    start, goal = np.array([0.3, 1.0, 1.5]), np.array([0.3, 3.0, 1.5])
    row = int(guide._rows_for(guide.cell_of(goal[None]), start[None], goal[None])[0])
    way = guide.centres[guide._way(row, int(guide.cell_of(start[None])[0]))[1:-1]]
    assert len(way) > 2
    assert (way[:, 0] >= guide.radius).all(), way  # never its body over the face x = 0
    assert (way[np.abs(way[:, 1] - 2.0) < 0.1][:, 0] > 0.46).all()  # past the pole on its far side
