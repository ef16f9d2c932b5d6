"""Geodesic guidance around static obstacles: the way to the goal when the straight line is blocked.

The potential field pulls each agent straight at its goal. Behind a static body with the goal
straight beyond it (a flat wall with one gap, a pillar dead ahead) the pull and the body's push
cancel: a local minimum, the classic failure of APF (Koren & Borenstein 1991). A navigation
function has no such minima (Rimon & Koditschek 1992); its discrete form, the distance to the
goal over a grid of the free space, is what grid planners descend (Barraquand & Latombe 1991).

:class:`StaticGuide` keeps one voxel grid over the flight volume (``MAX_CELLS`` cells up to 64
agents) with the clearance of every cell centre to the static obstacles, the ground and the flight
volume's other faces, less the largest ``checked_radius`` (body and safety margin). Per goal cell it
computes the shortest way from every cell to the goal (Dijkstra over the 26 neighbours, compiled:
``_guide_kernel``): free cells only enter free cells (a cell inside the inflated obstacles only
leads out), and a leg costs its length times ``1 + NEAR (1 - c / C0)`` near surfaces (clearance c
below C0), so the way keeps to the middle of a gap; and ``RIGHT`` more when the nearest surface lies
to the right of the leg's direction, so that in a passage two opposing flows keep to their own
right-hand halves instead of meeting head-on (the right-hand rule the field applies between agents).
Each new way then loads the cells near surfaces it runs through (``ONCOMING``: negotiated
congestion), so opposing flows take separate lanes through a passage (a doorway's tall slot:
different heights). Ways in the same direction are not spread (``SAME`` = 0): spread, they
reach down to the ground's repulsion and hold two agents at a doorway's corners.

Each step an agent whose straight line to its goal runs through a static obstacle or within the
squeeze of one (``field_law.squeeze``, beyond its radius; checked every ``RECHECK`` steps, a
fifth of the agents each step) is *guided*: its point of attraction is the cell ``HOPS`` legs
ahead on its way (or the goal itself once within reach), and its static repulsion is scaled by
``REPULSION``. Every other agent flies at its goal as before: without static obstacles nothing
is built and nothing changes. An agent following a segment or a global route keeps it, and
fixed wings (which cannot fly a way that hugs corners) are never guided: they fly clear lines,
and at the farthest point of their ways in sight, by ``swarmplan.flight.sight``.
The searches, the line-of-sight samples and the points on the ways run compiled
(``_guide_kernel``), each giving the numbers its numpy or scipy formulation gives (the same
ways, the same decisions); below swarm size, while numba is not loaded, the per-step calls run
their numpy twins (``_guide_numpy``: the same answers), so a small world's first steps need no
numba to load.
Stuck detection measures a guided agent's progress along its way, and the escape planner plans
no escape for an agent the guide leads (unless a moving obstacle is near; the guide sees static
ones only): what holds it is other agents.
The grid's tables and the ways found at the first reset are kept on disk and read back, bit for
bit, by the next guide of the same geometry and starts (:mod:`swarmplan.flight.guide_cache`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.flight import _guide_numpy, guide_cache, guide_graph
from swarmplan.flight.field_law import squeeze
from swarmplan.flight.guide_graph import AROUND, Graph, legs, past_way_end, source_cell, ways_floor
from swarmplan.flight.kinematics import checked_radius
from swarmplan.geometry.batch import ShapeBatch, rotate_rows_of
from swarmplan.geometry.shapes import DISTANCE
from swarmplan.runtime.compiled import kernel_module, use_numpy_twin
from swarmplan.world.motion import resting_bodies

if TYPE_CHECKING:
    from types import ModuleType

    from swarmplan.flight.kinematics import AgentParams
    from swarmplan.world.model import Obstacle, World

MAX_CELLS = 40_000  # cells of the grid up to 64 agents (~6 ms per goal for a search)
NEAR = 2.0  # extra cost per metre at a surface (fading out at C0)
RIGHT = 2.0  # extra cost per metre near a surface on the leg's right-hand side
SAME = 0.0  # the same per way already through it in the same direction (see the docstring)
ONCOMING = 3.0  # extra cost per metre through a cell near surfaces per way through it the other way
HOPS = 2  # legs ahead on the way: the point of attraction
REPULSION = 0.15  # scale of a guided agent's static repulsion (half a segment's)
AHEAD = 2.0  # influence distances of a line an unguided agent checks in flight
RECHECK = 5  # steps between two line-of-sight checks of an agent
TRACE_STEPS = 64  # steps of the march along a leg that may run through a body
TRACE_TOUCH = 1e-3  # of the cell: the clearance at which that march has met a body
_CHUNK = 4096  # cell centres per distance query (memory of the (points, obstacles, 3) gradients)
_GRID_ARRAYS = ("clear", "_body_clear", "_gap", "_reach")  # a grid's tables besides its graph


def _constants() -> dict[str, float]:
    """This module's constants (tests may change them: a changed constant is another key)."""
    return {k: v for k, v in globals().items() if k.isupper() and isinstance(v, int | float)}


class StaticGuide:
    """The grid and the ways to the goals of one world (see the module's description)."""

    def __init__(self, world: World, params: AgentParams, bodies: tuple[Obstacle, ...] | None = None):
        self.world = world
        self.bodies = world.static_obstacles if bodies is None else bodies
        # The cells' clearance by the compiled query (numpy's bits): the guide's start-up cost.
        self._batch = ShapeBatch(self.bodies, compiled=True)
        self.radius = float(np.max(checked_radius(params.radius)))  # no gap the safety filter refuses
        self.floor = ways_floor(world, params)
        # Fixed wings are not guided: a way that hugs corners is not theirs to fly (Dubins escapes).
        self.can_stop = ~np.asarray(params.fixed_wing, dtype=bool)
        self.ahead = AHEAD * float(world.planner_config.apf.influence)
        self.squeeze = squeeze(world.planner_config.apf.influence, params.fixed_wing, params.radius)
        lo, hi = np.asarray(world.bounds_min, dtype=float), np.asarray(world.bounds_max, dtype=float)
        size = np.maximum(hi - lo, 1e-6)
        # A way per goal: with many agents the grid is coarser (the searches cost in proportion).
        cells = MAX_CELLS * min(1.0, math.sqrt(64.0 / max(len(world.agents), 1)))
        # No cell finer than the smallest body that flies through it (a small world's grid).
        h = max((float(np.prod(size)) / cells) ** (1.0 / 3.0), float(np.min(params.radius)))
        self.shape = np.maximum(np.ceil(size / h).astype(np.int64), 1)
        self.cell = size / self.shape
        self._sample_step = 0.5 * float(self.cell.min())  # ``blocked``'s spacing of samples
        self.lo = lo
        nx, ny, nz = (int(v) for v in self.shape)
        self.n_cells = nx * ny * nz
        ii, jj, kk = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
        self.ijk = np.column_stack([ii.ravel(), jj.ravel(), kk.ravel()])
        self.centres = lo + (self.ijk + 0.5) * self.cell
        # The clearance a point may lose against its cell's centre (the distance is 1-Lipschitz).
        self.half_diagonal = 0.5 * float(np.linalg.norm(self.cell))
        self._flow = np.zeros((self.n_cells, 3))  # directions of the ways through each cell
        self._row_of = np.full(self.n_cells, -1, dtype=np.int64)  # goal cell -> row of the tables below
        self._next = np.empty((0, self.n_cells), dtype=np.int32)
        self._dist = np.empty((0, self.n_cells), dtype=np.float32)
        self._source = np.empty(0, dtype=np.int64)
        self.guided = np.zeros(len(world.agents), dtype=bool)
        self._t: dict[int, np.ndarray] = {}  # the samples' parameters along a line, by their count
        # The clearance is 1-Lipschitz everywhere (flat ground, exact distances to the bodies).
        self._lipschitz = not world.peaks and not self._batch.meshes
        # The grid's box less a margin: a sample beyond it is measured against every body.
        self._inner = (self.lo + 1e-6, self.lo + self.shape * self.cell - 1e-6)
        # The grid's tables: an earlier guide's of the same geometry (the same bits), else computed.
        key = {**_constants(), "squeeze": self.squeeze}
        self._grid_key = guide_cache.grid_key(key, world, self.bodies, self.radius, self.floor)
        tables = guide_cache.load_grid(self._grid_key, self.n_cells)
        if tables is None:
            self._compute_grid()
            guide_cache.store_grid(self._grid_key, self.grid_tables())
        else:
            self._adopt_grid_tables(tables)

    def grid_tables(self) -> dict[str, np.ndarray]:
        """The grid's tables as named arrays (what :mod:`~swarmplan.flight.guide_cache` stores)."""
        g, box = self._reverse, self._box_half
        return {
            **{name: getattr(self, name) for name in _GRID_ARRAYS},
            **{"indptr": g.indptr, "indices": g.indices, "data": g.data, "mask": g.grid[0]},
            **{"low": np.array(self._low), "gap_max": np.array(self._gap_max)},
            "has_box_half": np.array(box is not None),
            "box_half": np.zeros((0, 3)) if box is None else box,
        }

    def _adopt_grid_tables(self, a: dict[str, np.ndarray]) -> None:
        """Take the grid's tables from :meth:`grid_tables` of an earlier guide of the same inputs."""
        for name in _GRID_ARRAYS:
            setattr(self, name, a[name])
        self._low, self._gap_max = int(a["low"]), float(a["gap_max"])
        self._box_half = a["box_half"] if bool(a["has_box_half"]) else None
        self._proximity()
        self._adopt_graph(a["indptr"], a["indices"], a["data"], a["mask"])

    def _compute_grid(self) -> None:
        """The cells' clearance, the reversed graph and the line-of-sight tables."""
        self.clear, normal, self._body_clear = self._clearance(self.centres)
        prox = self._proximity()
        # The reversed graph in CSR form (row v: the legs into v, by their start cell, ascending):
        # searches run from the goal over reversed legs. Per offset not vertical the cells'
        # normals on the leg's right-hand side (numpy's product over all cells: the bits it
        # gives the legs' end cells); the graph itself in one compiled pass.
        offsets, delta, length, row, rights = legs(self.shape, self.cell)
        side = np.empty((len(rights), self.n_cells))
        for k, r in enumerate(rights):
            np.matmul(normal, r, out=side[k])
        cells = (self.ijk, self.shape, self.centres, self.free, self.near, self._body_clear)
        cut = guide_graph.crossing_legs(cells, self.radius, (offsets, delta, length), self._traced_hits)
        kernels = kernel_module("swarmplan.flight._guide_kernel")
        indptr, start, data, mask = kernels.reverse_graph(
            self.free, prox, side, (offsets, delta, length, row), self.shape, (NEAR, RIGHT), cut
        )
        self._adopt_graph(indptr, start, data, mask)
        self._sight_bounds()
        self._reach_bodies()

    def _traced_hits(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``guide_graph.traced_hits`` against the bodies: whether each segment meets one."""
        return guide_graph.traced_hits(
            a, b, self._batch.distance, TRACE_TOUCH * float(self.cell.min()), TRACE_STEPS
        )

    def _proximity(self) -> np.ndarray:
        """Each cell's nearness to a surface (1 at the surface, falling to 0 at a clearance of two
        cells or 4 m, whichever is more), and the cells' ``free`` and ``near`` flags from it; the
        surfaces here (``room``) take in the flight volume's faces (``guide_graph.face_room``)."""
        box = (self.lo, self.world.bounds_max)
        self.room = guide_graph.face_room(self.clear, self.centres, box, self.radius)
        self.free = self.room > 0.0
        c0 = max(2.0 * float(self.cell.max()), 4.0)
        prox = np.clip(1.0 - self.room / c0, 0.0, 1.0)
        # A cell with no proximity (free) has legs that cost their lengths (``1 + 0 * x`` is 1,
        # and the loads re-price only cells near surfaces): it has no row.
        self.near = prox > 0.0
        return prox

    def _adopt_graph(self, indptr: np.ndarray, start: np.ndarray, data: np.ndarray, mask: np.ndarray) -> None:
        """Take the reversed graph's arrays (``reverse_graph``'s, computed or read back)."""
        _, delta, length, _, _ = legs(self.shape, self.cell)
        self._reverse = Graph(indptr, start, data, (mask, self.near, delta, length))
        self._base = data.copy()
        # Unit directions of the legs into cells near surfaces (the only ones a way re-prices),
        # found at a cell's first re-pricing (only those rows are ever read).
        self._leg_dir = np.empty((len(data), 3))
        self._has_dir = np.zeros(self.n_cells, dtype=bool)

    # ------------------------------------------------------------------ geometry

    def _sight_bounds(self) -> None:
        """Tables that let :meth:`blocked` pass over a line no sample of which can land in a
        cell near a surface (``self.clear`` below ``half_diagonal + squeeze``, the first test a
        sample must fail to count): ``_low`` is the lowest layer of cells (z index) above every
        such cell near the ground, and ``_gap[c]`` the distance from cell c's box to the nearest
        box of a cell near a surface in the layers from ``_low`` up (inf when there is none)."""
        limit = self.half_diagonal + self.squeeze
        c = self.centres
        ground = (c[:, 2] - self.world.terrain_height(c[:, :2]) - self.floor) - self.radius < limit
        self._low = int(self.ijk[ground, 2].max()) + 1 if ground.any() else 0
        near = ((self.clear < limit) & (self.ijk[:, 2] >= self._low)).reshape(
            tuple(int(v) for v in self.shape)
        )
        self._gap, self._gap_max = guide_graph.cell_gaps(near, self.cell, self.shape)

    def _clearance(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Clearance (surface distance less the largest checked radius) of ``pts`` to the static
        obstacles and the ground (less the lowest altitude the field keeps agents above), the
        outward normal of the nearest of them, and the clearance to the obstacles alone."""
        w = self.world
        clear = pts[:, 2] - w.terrain_height(pts[:, :2]) - self.floor
        gh = w.terrain_gradient(pts[:, :2])
        normal = np.column_stack([-gh[:, 0], -gh[:, 1], np.ones(len(pts))])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        body = np.full(len(pts), np.inf)
        if self.bodies:
            batch = self._batch
            for a in range(0, len(pts), _CHUNK):
                d, g = batch.query(pts[a : a + _CHUNK])
                j = np.argmin(d, axis=1)
                rows = np.arange(len(j))
                dj = d[rows, j]
                body[a : a + _CHUNK] = dj
                closer = dj < clear[a : a + _CHUNK]
                clear[a : a + _CHUNK][closer] = dj[closer]
                normal[a : a + _CHUNK][closer] = g[rows, j][closer]
        return clear - self.radius, normal, body - self.radius

    def _kernels(self) -> ModuleType:
        """The per-step kernels: their numpy twins (the same answers) below swarm size while
        numba is not in the process, else the compiled ones."""
        if use_numpy_twin(len(self.world.agents)):
            return _guide_numpy
        return kernel_module("swarmplan.flight._guide_kernel")

    def cell_of(self, pts: np.ndarray) -> np.ndarray:
        """Index of the cell holding each of ``pts`` (points outside: the nearest cell)."""
        pts = np.ascontiguousarray(pts, dtype=float).reshape(-1, 3)
        return self._kernels().cells_of(pts, self.lo, self.cell, self.shape)

    def blocked(self, start: np.ndarray, end: np.ndarray, reach: np.ndarray | float = np.inf) -> np.ndarray:
        """Per row: whether the straight line ``start`` -> ``end`` (n, 3) runs through a static
        obstacle or the ground inflated by the largest checked radius plus ``squeeze`` (exact
        distances where the grid cannot tell): also a line through a narrow gap, in front of
        which the full repulsion of its two edges outweighs the pull (a local minimum).

        The samples ``start + t (end - start)`` (t in [0, 1], as many per row as the longest
        line needs) are measured exactly only where the grid cannot tell (the compiled
        ``sight_samples``). A line passes unmeasured when no sample of it can land in a cell
        near a surface: its samples have heights monotone in t (rounding is monotone), so
        between those of its two ends, whose layers are at least ``_low``: no sample is in a
        cell near the ground. The cell of a sample holds the sample's nearest point in the
        grid's box (the index is clipped), which is no farther from the start's nearest point
        than the sample from the start (projection onto a box does not stretch distances): at
        most the line's length. So that cell's box is within the length of the start's cell's
        box, and ``_gap`` there beyond the length (with a margin for rounding) leaves no cell
        near a body within reach."""
        start = np.ascontiguousarray(np.atleast_2d(start), dtype=float)
        end = np.atleast_2d(np.asarray(end, dtype=float))
        n = len(start)
        out = np.zeros(n, dtype=bool)
        if n == 0:
            return out
        length = np.linalg.norm(end - start, axis=1)
        cut = np.minimum(length, reach)  # only the first ``reach`` m of each line
        end = start + (end - start) * (cut / np.maximum(length, 1e-12))[:, None]
        length = cut
        x = float(length.max()) / self._sample_step
        samples = 4000 if x > 4000 else max(math.ceil(x), 1)  # of all rows: kept as is
        t = self._t.get(samples)
        if t is None:
            t = self._t[samples] = np.linspace(0.0, 1.0, samples + 1)
        kernels = self._kernels()
        grid = (self.lo, self.cell, self.shape, self.centres, self.clear, self._body_clear)
        levels = (self.half_diagonal + self.squeeze, self.squeeze, self.floor, self.radius)
        row, p, cells, out = kernels.sight_samples(
            start, end, length, t, grid, levels, self._gap, self._gap_max, self._low, self._lipschitz
        )
        if not len(row):
            return out
        if self._lipschitz:  # flat ground, primitive bodies: all in one compiled pass
            b = self._batch
            bodies = (self._reach, b.position, b.rotation, b.code, b.prm)
            kernels.flat_hits(p, row, cells, out, self._inner, bodies, levels[1:])  # squeeze, floor, radius
            return out
        exact = p[:, 2] - self.world.terrain_height(p[:, :2]) - self.floor
        if self.bodies:
            exact = np.minimum(exact, self._body_distance(p, cells))
        exact -= self.radius
        out[row[exact < self.squeeze]] = True
        return out

    def _reach_bodies(self) -> None:
        """``_reach[c, b]``: whether a point of cell c's box lies within the largest checked radius
        plus ``squeeze`` (and a margin for rounding) of body b's bounding box (in the world's
        axes). A body's exact distance is at least that to its bounding box, so a sample in the
        grid measures only the bodies its cell reaches: the others cannot bring it under
        ``squeeze``. With a mesh among the bodies (distances from a grid) every cell reaches all."""
        b = self._batch
        self._box_half = None
        if not self.bodies or b.meshes:
            self._reach = np.ones((self.n_cells, len(self.bodies)), dtype=bool)
            return
        local = np.column_stack([b.prm[:, 0], b.prm[:, 0], b.prm[:, 0]])
        local[b.code == 1] = b.prm[b.code == 1]  # box: its half sizes
        local[b.code >= 2, 2] = b.prm[b.code >= 2, 1]  # cylinder, capsule: half height
        local[b.code == 3, 2] += b.prm[b.code == 3, 0]  # capsule: and its caps
        # local = (p - centre) @ R, so |p - centre| <= |R| @ local half-extents per world axis.
        self._box_half = np.einsum("mjk,mk->mj", np.abs(b.rotation), local) * (1.0 + 1e-9) + 1e-9
        # The distance between the boxes below the radius plus ``squeeze``, compiled.
        self._reach = kernel_module("swarmplan.flight._guide_kernel").reach_table(
            self.lo,
            self.cell,
            self.shape,
            b.position - self._box_half,
            b.position + self._box_half,
            self.radius + self.squeeze + 1e-6,
        )

    def _body_distance(self, p: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """The distance from each of the samples ``p`` in ``cells`` to the nearest body its cell
        reaches (inf when none does), each computed as ``ShapeBatch.distance`` computes it (the
        same operations on the same numbers, element by element: the same bits): below
        ``squeeze`` plus the radius exactly where the nearest of all bodies is. A sample outside
        the grid (its cell's box does not hold it) is measured against every body."""
        b = self._batch
        every = bool(((p < self._inner[0]) | (p > self._inner[1])).any())
        if not b.meshes:
            prims = (b.position, b.rotation, b.code, b.prm)
            return self._kernels().body_distance(p, cells, self._reach, every, *prims)
        if every:
            return b.distance(p).min(axis=1)
        pt, body = np.nonzero(self._reach[cells])
        out = np.full(len(p), np.inf)
        if not len(pt):
            return out
        c = b.position[body]
        local = rotate_rows_of(*(p[pt, k] - c[:, k] for k in range(3)), b.rotation[body])
        d = np.empty(len(pt))
        for code in b.groups:
            sel = np.flatnonzero(b.code[body] == code)
            if len(sel):
                d[sel] = DISTANCE[code](local[sel], b.prm[body[sel]])
        mesh = np.flatnonzero(b.code[body] < 0)  # and the meshes from their grids, as ``distance`` does
        d[mesh] = b.pair_distance(p[pt[mesh]], body[mesh])
        first = np.flatnonzero(np.diff(pt, prepend=-1))  # pairs come row by row
        out[pt[first]] = np.minimum.reduceat(d, first)
        return out

    # ------------------------------------------------------------------ ways to the goals

    def _rows_for(self, goal_cells: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """Table rows of the ways to ``goal_cells`` (of the points ``goals``, n x 3) from
        ``starts`` (n, 3), computing the missing ones in order: each new way (from its agent's
        position) then loads the cells near surfaces it runs through (negotiated congestion, as
        routers of wires spread nets over a chip's channels: McMurchie & Ebeling 1995): a later
        way pays ``SAME`` per way already there and ``ONCOMING`` per way there in the opposite
        direction, so the ways spread over a passage's width and height and opposing flows take
        separate lanes."""
        goal_cells = np.asarray(goal_cells, dtype=np.int64)
        missing = self._row_of[goal_cells] < 0
        if missing.any():  # each new goal cell once, in the order of its first row
            cells, starts = goal_cells[missing], np.asarray(starts)[missing]
            goals = np.asarray(goals, dtype=float).reshape(-1, 3)[missing]
            first = np.sort(np.unique(cells, return_index=True)[1])
            self._search(cells[first], starts[first], goals[first])
        return self._row_of[goal_cells]

    def _search(self, goal_cells: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> None:
        """Find the ways to ``goal_cells`` (new ones, in order; their goals ``goals``), each then
        loading the way from its start (see :meth:`_rows_for`)."""
        dijkstra = kernel_module("swarmplan.flight._guide_kernel").dijkstra
        g = self._reverse
        for c, p, goal in zip(goal_cells.tolist(), starts, goals, strict=True):
            source = self._source_of(c, goal)
            dist, pred = dijkstra(g.indptr, g.data, g.grid, source)
            row = len(self._source)
            if row == len(self._next):  # room for a way per agent, then twice as many ways
                grow = max(8, len(self.guided), 2 * row)
                self._next = np.vstack([self._next, np.empty((grow - row, self.n_cells), dtype=np.int32)])
                self._dist = np.vstack([self._dist, np.empty((grow - row, self.n_cells), dtype=np.float32)])
            self._next[row] = np.where(pred < 0, -1, pred)
            self._dist[row] = dist
            self._row_of[c] = row
            self._source = np.append(self._source, source)
            self._load(self._way(row, int(self.cell_of(p[None])[0])))

    def _way(self, row: int, cell: int) -> list[int]:
        """The cells of the way of table ``row`` from ``cell`` to its goal."""
        way = [cell]
        if not np.isfinite(self._dist[row, cell]):
            return way
        for _ in range(self.n_cells):
            nxt = int(self._next[row, way[-1]])
            if nxt < 0:
                break
            way.append(nxt)
        return way

    def _load(self, way: list[int]) -> None:
        """Add a way's directions to the cells near surfaces along it and around them, and
        re-price the legs into those cells."""
        if len(way) < 2:
            return
        a, b = np.array(way[:-1]), np.array(way[1:])
        d = self.centres[b] - self.centres[a]
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        nb = (self.ijk[b][:, None, :] + AROUND[None]).reshape(-1, 3)
        ok = ((nb >= 0) & (nb < self.shape)).all(axis=1)
        cells = (nb[:, 0] * self.shape[1] + nb[:, 1]) * self.shape[2] + nb[:, 2]
        dirs = np.repeat(d, 27, axis=0)
        ok &= self.near[np.where(ok, cells, 0)]
        if not ok.any():
            return
        np.add.at(self._flow, cells[ok], dirs[ok])
        g = self._reverse
        touched = np.unique(cells[ok])
        fresh = touched[~self._has_dir[touched]]
        if len(fresh):
            self._has_dir[fresh] = True
            lo, count = g.indptr[fresh], np.diff(g.indptr)[fresh]
            legs = np.repeat(lo - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
            e = self.centres[np.repeat(fresh, count)] - self.centres[g.indices[legs]]
            self._leg_dir[legs] = e / np.linalg.norm(e, axis=1, keepdims=True)
        # The legs into each touched cell re-priced with the cell's flow, cell by cell: ``e @ f``
        # per cell is a BLAS product, whose rounding one product over all legs would not repeat.
        for v in touched.tolist():
            lo, hi = g.indptr[v], g.indptr[v + 1]
            f = self._flow[v]
            same = SAME * float(np.linalg.norm(f)) if SAME else 0.0
            g.data[lo:hi] = self._base[lo:hi] * (
                1.0 + same + ONCOMING * np.maximum(-(self._leg_dir[lo:hi] @ f), 0.0)
            )

    def _source_of(self, cell: int, goal: np.ndarray) -> int:
        """The search's source for the ``goal`` (3,) in ``cell`` (``guide_graph.source_cell``)."""
        grid = (self.ijk, self.centres, self.shape)
        return source_cell(self.free, self.room, grid, cell, (goal, self._traced_hits))

    def reset(self, pos: np.ndarray | None = None, goal: np.ndarray | None = None) -> None:
        """Forget which agents are guided (the ways to goals already found stay: they depend on
        the world only); with the agents' positions and goals (N, 3), guide those whose line is
        blocked from here and find their ways now, before flight (in the agents' order)."""
        self.guided[:] = False
        if pos is None or goal is None:
            return
        # A guide with no way yet finds the ways an earlier one found from the same starts.
        key = (
            guide_cache.ways_key(self._grid_key, pos, goal, self.can_stop) if not len(self._source) else None
        )
        if key is not None:
            tables = guide_cache.load_ways(key, len(self.guided), self.n_cells, self._reverse.indptr)
            if tables is not None:
                self._adopt_ways_tables(tables)
                return
        rows = np.flatnonzero(self.can_stop[: len(pos)])
        if len(rows):
            self.guided[rows] = self.blocked(pos[rows], goal[rows])
            rows = rows[self.guided[rows]]
            self._rows_for(self.cell_of(goal[rows]), pos[rows], goal[rows])
        if key is not None:
            guide_cache.store_ways(key, self.ways_tables())

    def ways_tables(self) -> dict[str, np.ndarray]:
        """What a fresh guide's reset changed (the ways found, the legs they re-priced, the loads
        and which agents it guides) as named arrays: only the parts that differ from a fresh
        guide's, so they come to a few MB at most."""
        g, rows = self._reverse, len(self._source)
        priced = guide_cache.changed(g.data, self._base)
        flow = guide_cache.changed(self._flow, np.zeros_like(self._flow))
        legs = guide_cache.legs_into(g.indptr, np.flatnonzero(self._has_dir))
        goal_cells = np.flatnonzero(self._row_of >= 0)
        return {
            **{"guided": self.guided, "priced": priced, "prices": g.data[priced]},
            **{"flow_cells": flow, "flow": self._flow[flow], "has_dir": self._has_dir},
            **{"leg_dir": self._leg_dir[legs], "goal_cells": goal_cells},
            "goal_rows": self._row_of[goal_cells],
            **{"next": self._next[:rows], "dist": self._dist[:rows], "capacity": np.array(len(self._next))},
            "source": self._source,
        }

    def _adopt_ways_tables(self, a: dict[str, np.ndarray]) -> None:
        """Take the ways of :meth:`ways_tables` of an earlier fresh guide (checked whole by
        ``guide_cache.load_ways``) into this fresh one."""
        rows, n = len(a["source"]), self.n_cells
        self.guided[:] = a["guided"]
        self._reverse.data[a["priced"]] = a["prices"]
        self._flow[a["flow_cells"]] = a["flow"]
        self._has_dir[:] = a["has_dir"]
        self._leg_dir[a["legs"]] = a["leg_dir"]
        self._row_of[a["goal_cells"]] = a["goal_rows"]
        self._next = np.empty((int(a["capacity"]), n), dtype=np.int32)
        self._dist = np.empty((int(a["capacity"]), n), dtype=np.float32)
        self._next[:rows], self._dist[:rows] = a["next"], a["dist"]
        self._source = a["source"]

    def targets(
        self,
        step: int,
        idx: np.ndarray,
        pos: np.ndarray,
        goal: np.ndarray,
        target: np.ndarray,
        scale: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Points of attraction of agents ``idx`` at ``pos`` (n, 3) and the scale of their static
        repulsion: ``target`` and ``scale`` where the target is not the goal (a segment or route),
        else for a guided agent the point ``HOPS`` legs ahead on the way and its static
        repulsion scaled by ``REPULSION`` (the way keeps its clearance on the grid; at full
        strength the two edges of a narrow gap push back harder than the pull, a local minimum
        in front of the gap, and at 0.3 agents held beside a doorway's edges).
        Agents whose turn it is (``step``) have their line of sight checked."""
        same = target == goal
        to_goal = same[:, 0] & same[:, 1] & same[:, 2]
        due = to_goal & ((idx + step) % RECHECK == 0) & self.can_stop[idx]
        if due.any():
            # An agent not guided yet looks only as far ahead as the static repulsion reaches
            # (the local minimum forms there; farther, the crowd may still move it off the
            # line), one guided keeps its way while the whole line is blocked.
            who = idx[due]
            reach = np.where(self.guided[who], np.inf, self.ahead)
            self.guided[who] = self.blocked(pos[due], goal[due], reach)
        rows = np.flatnonzero(to_goal & self.guided[idx])
        if not len(rows):
            return target, scale
        out = target.copy()
        scale = scale.copy()
        scale[rows] = np.minimum(scale[rows], REPULSION)
        p, g = pos[rows], goal[rows]
        table = self._rows_for(goal_cells := self.cell_of(g), p, g)
        grid, ways = (self.lo, self.cell, self.shape, self.centres), (self._next, self._dist, self._source)
        out[rows] = self._kernels().way_points(p, g, table, grid, ways, HOPS)
        home = past_way_end(p, g, self._source[table], goal_cells, (self.ijk, self.centres))
        # By its way's end with the goal in sight (``guide_graph.by_way_end``): at the goal.
        at = (self.ijk, self.centres)
        by_end = guide_graph.by_way_end(p, g, self.cell_of(p), self._source[table], goal_cells, at)
        there = np.flatnonzero(~home & by_end)
        if len(there):
            home[there] = ~self._traced_hits(p[there], g[there])
        out[rows[home]] = g[home]
        return out, scale

    def leads(self, i: int, pos: np.ndarray, goal: np.ndarray) -> bool:
        """Whether the guide leads agent ``i`` at ``pos`` to ``goal`` (3,): it is guided and a way
        exists from its cell."""
        if not self.guided[i]:
            return False
        return bool(np.isfinite(self.way_length(pos[None], goal[None])[0]))

    def way_point(self, pos: np.ndarray, goal: np.ndarray, ahead: float) -> np.ndarray:
        """The point of the way from ``pos`` to ``goal`` (3,) about ``ahead`` m along it (the
        cell centre where it first gets that far), or the goal when the way is shorter."""
        row = int(self._rows_for(self.cell_of(goal[None]), pos[None], goal[None])[0])
        way = self._way(row, int(self.cell_of(pos[None])[0]))
        if len(way) < 2 or way[-1] != self._source[row]:
            return np.asarray(goal, dtype=float).copy()
        pts = np.vstack([pos, self.centres[way[1:]]])
        run = np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))
        k = int(np.searchsorted(run, ahead))
        return np.asarray(goal, dtype=float).copy() if k >= len(run) - 1 else pts[k + 1]

    def way_length(self, pos: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Cost of the way from ``pos`` to ``goal`` (n, 3) on the grid: its length, more near
        surfaces (the legs' cost; inf where there is no way)."""
        table = self._rows_for(self.cell_of(goal), pos, goal)
        cell = self.cell_of(pos)
        return self._dist[table, cell].astype(float) + np.linalg.norm(self.centres[cell] - pos, axis=1)


def make_guide(world: World, params: AgentParams, t: float = 0.0) -> StaticGuide | None:
    """The guide of ``world`` round the obstacles at rest for good at ``t``, or None when there
    are none (nothing to go round) or the world turns it off (``planner.apf.guide: false``)."""
    if not world.planner_config.apf.guide:
        return None
    bodies = resting_bodies(world, t)
    if not bodies:
        return None
    if math.prod(float(v) for v in np.asarray(world.bounds_max) - np.asarray(world.bounds_min)) <= 0:
        return None
    return StaticGuide(world, params, bodies)
