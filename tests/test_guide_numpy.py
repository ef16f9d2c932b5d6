"""The static guide's numpy twins (swarmplan.flight._guide_numpy: the per-step calls of worlds
below swarm size while numba is not loaded) give its kernels' answers exactly: every call the
line-of-sight check makes (samples to measure, their points and cells, the rows found blocked,
the distances) on random lines among the bodies of tests/test_guide_sight.py over flat ground
and terrain (lines through bodies, grazing them, of length 0, leaving the grid), the cells and
points of attraction on random points, and a whole 16-agent run with guided agents; the world's
size and numba's presence choose the implementation, and with the guide's tables on disk a
small guided world steps without numba."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from types import ModuleType, SimpleNamespace

import numpy as np
import pytest
from test_guide_graph import _guide as _graph_guide
from test_guide_sight import _guide

from swarmplan.flight import _guide_numpy as T
from swarmplan.flight import guide as G
from swarmplan.runtime.compiled import COMPILED_FROM, kernel_module

K = kernel_module("swarmplan.flight._guide_kernel")
NAMES = ("cells_of", "way_points", "sight_samples", "flat_hits", "body_distance")


def _same(a: object, b: object) -> None:
    """The same answer: arrays of the same dtype, shape and bits, tuples item by item."""
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
        return
    assert isinstance(a, np.ndarray) and isinstance(b, np.ndarray)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()


def _both(seen: dict[str, int]) -> SimpleNamespace:
    """The per-step calls made through the kernel and the twin alike, their answers (and the
    arrays they write) compared; the twin's returned. ``seen`` counts the calls by name."""

    def call(name: str) -> Callable:
        def run(*args: object) -> object:
            seen[name] = seen.get(name, 0) + 1
            copies = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
            expect = getattr(K, name)(*copies)
            got = getattr(T, name)(*args)
            if name == "flat_hits":  # writes its rows into ``out``
                _same(args[3], copies[3])
            else:
                _same(got, expect)
            return got

        return run

    return SimpleNamespace(**{name: call(name) for name in NAMES})


def _use(guide: G.StaticGuide, kernels: ModuleType | SimpleNamespace) -> G.StaticGuide:
    guide._kernels = lambda: kernels  # this guide's per-step calls, whatever the world's size
    return guide


def _lines(guide: G.StaticGuide, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Random lines, a sixth each through a body, grazing the ball at the distance that
    decides, of length 0, from the grid out of it, level at the height that decides, and short
    or long at random."""
    b = guide._batch
    lo, hi = guide.lo, guide.lo + guide.shape * guide.cell
    start = rng.uniform(lo - 5.0, hi + 5.0, (n, 3))
    end = start + rng.normal(size=(n, 3)) * rng.choice([2.0, 10.0, 40.0], (n, 1))
    k = n // 6
    body = rng.integers(0, len(b), k)  # through a body: from its centre
    start[:k] = b.position[body] + rng.normal(size=(k, 3))
    sphere = np.flatnonzero(b.code == 0)[0]  # grazing the ball at radius + SQUEEZE (+- a hair)
    u = rng.normal(size=(k, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(u, rng.normal(size=(k, 3)))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    shift = rng.choice([-1e-3, -1e-7, 0.0, 1e-7, 1e-3], (k, 1))
    far = b.prm[sphere, 0] + guide.radius + guide.squeeze + shift
    mid = b.position[sphere] + far * u
    start[k : 2 * k], end[k : 2 * k] = mid - 8.0 * v, mid + 8.0 * v
    end[2 * k : 3 * k] = start[2 * k : 3 * k]  # length 0
    start[3 * k : 4 * k] = rng.uniform(lo, hi, (k, 3))  # out of the grid
    end[3 * k : 4 * k] = start[3 * k : 4 * k] + 200.0 * u
    # level, at the height over flat ground that decides (+- a few units in the last place)
    h = guide.floor + guide.radius + guide.squeeze
    start[4 * k : 5 * k] = rng.uniform(lo, hi, (k, 3))
    start[4 * k : 5 * k, 2] = h + rng.integers(-3, 4, k) * np.spacing(h)
    end[4 * k : 5 * k] = start[4 * k : 5 * k] + 30.0 * (u * [1.0, 1.0, 0.0])
    return start, end


@pytest.mark.parametrize(("terrain", "agents"), [(False, 1), (True, 1), (False, 200)])
def test_the_twins_decide_every_line_as_the_kernels_do(
    terrain: bool, agents: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    guide = _guide(terrain, agents)  # 200 agents: a coarser grid (its twin forced here)
    rng = np.random.default_rng(11 + agents + terrain)
    seen: dict[str, int] = {}
    blocked = 0
    for trial in range(12):
        if trial == 6:  # the later calls' lines in many blocks
            monkeypatch.setattr(T, "_SAMPLES", 4096)
        start, end = _lines(guide, rng, 300)
        reach = rng.choice([np.inf, 5.0, 20.0], len(start)) if trial % 2 else np.inf
        twin = _use(guide, _both(seen)).blocked(start, end, reach)
        compiled = _use(guide, K).blocked(start, end, reach)
        np.testing.assert_array_equal(twin, compiled)
        blocked += int(compiled.sum())
        if trial == 0:  # samples outside the grid: every body for every sample of the call
            one = _use(guide, _both(seen)).blocked(start[50:60], end[50:60] + 300.0)
            np.testing.assert_array_equal(one, _use(guide, K).blocked(start[50:60], end[50:60] + 300.0))
    assert 0 < blocked < 12 * 300  # both answers
    assert seen["sight_samples"] == 13
    assert seen.get("flat_hits" if not terrain else "body_distance", 0) > 0  # samples measured


def test_the_twins_measure_every_kind_of_body_as_the_kernel() -> None:
    """Points in, on and around every body, per body and against all (grid cells or not)."""
    guide = _guide(False, 1)
    b = guide._batch
    rng = np.random.default_rng(9)
    p = b.position[rng.integers(0, len(b), 4000)] + rng.normal(size=(4000, 3)) * rng.choice(
        [0.5, 4.0], (4000, 1)
    )
    p = np.vstack([p, rng.uniform(-20.0, 120.0, (1000, 3))])
    cells = guide.cell_of(p)
    args = (guide._reach, b.position, b.rotation, b.code, b.prm)
    for every in (False, True):
        got = T.body_distance(p, cells, args[0], every, *args[1:])
        _same(got, K.body_distance(p, cells, args[0], every, *args[1:]))
        assert np.isinf(got).any() != every and (got < 0).any()
    _same(T.body_distance(p[:0], cells[:0], args[0], True, *args[1:]), np.empty(0))


def test_the_twins_find_the_kernels_cells_and_points_of_attraction() -> None:
    guide = _graph_guide(agents=4)
    pos = np.array([[30.0, 20.0 + 5 * k, 20.0] for k in range(4)])
    goal = np.array([[80.0, 60.0 - 5 * k, 20.0] for k in range(4)])
    guide.reset(pos, goal)
    rng = np.random.default_rng(4)
    size = guide.shape * guide.cell
    p = guide.lo + rng.uniform(-0.2, 1.2, (2000, 3)) * size  # a fifth outside the grid
    p[:200] = guide.lo + rng.integers(-1, guide.shape + 2, (200, 3)) * guide.cell  # on cell faces
    p[200:210] = goal[0] + rng.normal(size=(10, 3))  # at the end of a way
    g = goal[rng.integers(0, 4, len(p))]
    args = (guide.lo, guide.cell, guide.shape)
    cells = T.cells_of(p, *args)
    _same(cells, K.cells_of(p, *args))
    table = guide._rows_for(guide.cell_of(g), p, g)
    grid, ways = (*args, guide.centres), (guide._next, guide._dist, guide._source)
    got = T.way_points(p, g, table, grid, ways, G.HOPS)
    _same(got, K.way_points(p, g, table, grid, ways, G.HOPS))
    home = (got == g).all(axis=1)
    assert 0 < home.sum() < len(p)  # goals (ways' ends, no way) and cells on the way
    assert len(np.unique(cells)) > 100 and (cells == 0).any() and (cells == guide.n_cells - 1).any()


def test_world_size_and_numba_choose_the_implementation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Below swarm size and with numba not in the process the guide's per-step calls run the
    twins; at swarm size, or once numba is loaded, the kernels."""
    from swarmplan.runtime import compiled

    loaded = [False]
    monkeypatch.setattr(compiled, "numba_loaded", lambda: loaded[0])
    calls: list[tuple[str, str]] = []
    for module, kind in ((T, "numpy"), (K, "compiled")):
        for name in NAMES:
            real = getattr(module, name)
            monkeypatch.setattr(module, name, lambda *a, _r=real, _c=(kind, name): calls.append(_c) or _r(*a))
    few, many = _guide(False, COMPILED_FROM - 1), _guide(False, COMPILED_FROM)
    hilly = _guide(True, 2)  # terrain: the distances to the bodies apart
    # through the box; beside the ball, within reach of its surface (samples measured)
    start = np.array([[5.0, 5.0, 20.0], [40.0, 25.0 + 5.0 + few.radius + few.squeeze - 0.2, 30.0]])
    end = np.array([[95.0, 95.0, 20.0], [80.0, 25.0 + 5.0 + few.radius + few.squeeze - 0.2, 30.0]])
    idx, goal = np.arange(2), end.copy()

    def step(guide: G.StaticGuide) -> set[tuple[str, str]]:
        calls.clear()
        guide.reset(start, goal)
        guide.targets(0, idx, start, goal, goal.copy(), np.ones(2))
        assert guide.blocked(start, end).all() and guide.guided[0]
        return set(calls)

    core = {"cells_of", "way_points", "sight_samples"}
    assert step(few) == {("numpy", n) for n in core | {"flat_hits", "body_distance"}}  # the one in the other
    assert step(hilly) == {("numpy", n) for n in core | {"body_distance"}}
    assert step(many) == {("compiled", n) for n in core | {"flat_hits"}}
    loaded[0] = True
    assert step(few) == {("compiled", n) for n in core | {"flat_hits"}}


def test_a_small_swarm_flies_the_same_with_both_guides(monkeypatch: pytest.MonkeyPatch) -> None:
    """The 16-agent world of 4 movers and 8 static bodies, its guide's per-step calls run by the
    kernels and by the twins: the same positions, velocities and events at every step."""
    from swarmplan.bench.sim import swarm_world
    from swarmplan.planner import make_planner
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    world = parse_world(swarm_world(16, 4, 8))
    runs = []
    for twin in (False, True):
        monkeypatch.setattr(G, "use_numpy_twin", lambda n_agents, twin=twin: twin)
        sim = Simulation(world, planner=make_planner(world))
        assert sim.guide is not None and (sim.guide._kernels() is T) == twin
        sim.reset(seed=0)
        steps, guided = [], 0
        for _ in range(150):
            r = sim.step()
            guided += int(sim.guide.guided.sum())
            steps.append(
                (r.state.position.copy(), r.state.velocity.copy(), [(e.kind, e.agent) for e in r.events])
            )
            if r.terminated or r.truncated:
                break
        runs.append((steps, guided))
    (a, guided_a), (b, guided_b) = runs
    assert len(a) == len(b) == 150 and guided_a == guided_b > 0  # agents guided along the way
    for (p0, v0, e0), (p1, v1, e1) in zip(a, b, strict=True):
        _same(p0, p1)
        _same(v0, v1)
        assert e0 == e1
    assert np.abs(a[-1][0] - a[0][0]).max() > 10.0  # the agents went somewhere


def test_a_small_guided_world_steps_without_numba() -> None:
    """With the guide's tables on disk (built here first), a fresh interpreter builds, resets and
    steps the 16-agent world with its guide, agents guided, without importing numba."""
    from swarmplan.bench.sim import swarm_world
    from swarmplan.planner import make_planner
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    world = parse_world(swarm_world(16, 4, 8))
    Simulation(world, planner=make_planner(world)).reset(seed=0)  # the tables stored
    code = (
        "import sys\n"
        "from swarmplan.bench.sim import swarm_world\n"
        "from swarmplan.planner import make_planner\n"
        "from swarmplan.sim import Simulation\n"
        "from swarmplan.world import parse_world\n"
        "w = parse_world(swarm_world(16, 4, 8))\n"
        "s = Simulation(w, planner=make_planner(w))\n"
        "s.reset(seed=0)\n"
        "guided = 0\n"
        "for _ in range(30):\n"
        "    s.step(); guided += int(s.guide.guided.sum())\n"
        "print(guided > 0, sorted(m for m in ('numba', 'llvmlite') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True []"
