"""Arrays kept on disk between runs (swarmplan.runtime.disk_cache): the static guide's tables
(swarmplan.flight.guide_cache) and the mesh distance grids (swarmplan.geometry.shapes.MeshGrid).
A guide read back holds, array for array and bit for bit, what a computed one holds, after its
build and after its first reset, and a run goes on identically; a mesh grid read back is the
computed one; a change of any input or constant is another entry; a damaged, foreign or
unwritable entry costs only the speed-up."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarmplan.bench.sim import swarm_world
from swarmplan.flight import guide as G
from swarmplan.flight.guide_graph import Graph
from swarmplan.flight.kinematics import AgentParams
from swarmplan.runtime import disk_cache
from swarmplan.world import parse_world

WORLD = swarm_world(16, 4, 8)


@pytest.fixture
def folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(disk_cache.ENV, str(tmp_path))
    return tmp_path


def _guide(world=None) -> G.StaticGuide:
    world = world or parse_world(WORLD)
    guide = G.make_guide(world, AgentParams.from_world(world))
    pos = np.array([a.start for a in world.agents])
    goal = np.array([a.goal for a in world.agents])
    guide.reset(pos, goal)
    return guide


def _state(guide: G.StaticGuide) -> dict[str, np.ndarray]:
    """Every array the guide holds (the graph's too), as raw bytes; leg directions only where
    they were ever written (the other rows are uninitialised and never read)."""
    out = {}
    for name, value in vars(guide).items():
        if isinstance(value, np.ndarray):
            out[name] = value
        elif isinstance(value, Graph):
            for field in dataclasses.fields(value):
                part = getattr(value, field.name)
                for k, a in enumerate(part if isinstance(part, tuple) else (part,)):
                    out[f"graph.{field.name}.{k}"] = a
        elif isinstance(value, int | float | bool | None):
            out[name] = np.array(value)
    g = guide._reverse
    has = np.flatnonzero(guide._has_dir)
    legs = np.concatenate([np.arange(g.indptr[c], g.indptr[c + 1]) for c in has]) if len(has) else []
    out["_leg_dir"] = guide._leg_dir[np.asarray(legs, dtype=np.int64)]
    rows = len(guide._source)
    out["_next"], out["_dist"] = guide._next[:rows], guide._dist[:rows]
    out["capacity"] = np.array(len(guide._next))
    return out


def _assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for name in a:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name


def test_a_guide_read_back_holds_the_computed_bits(folder: Path) -> None:
    computed = _guide()
    assert computed.guided.any() and len(computed._source) > 0  # ways were found
    assert sorted(p.name.split("-")[1] for p in folder.glob("*.npz")) == ["grid", "ways"]
    calls = []
    real = G.StaticGuide._compute_grid
    G.StaticGuide._compute_grid = lambda self: calls.append(1) or real(self)  # noqa: E731
    try:
        read = _guide()
    finally:
        G.StaticGuide._compute_grid = real
    assert calls == []  # nothing computed
    _assert_same(_state(computed), _state(read))
    # The types the kernels are called with are the computed ones (no new compilation).
    assert type(read._low) is int and type(read._gap_max) is float


def test_without_the_cache_nothing_is_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(disk_cache.ENV, "")
    assert disk_cache.cache_dir() is None
    guide = _guide()
    assert guide.guided.any() and list(tmp_path.iterdir()) == []


def test_another_world_or_constant_is_another_entry(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first = _guide()
    keys = {first._grid_key}
    moved = parse_world(WORLD)
    body = next(o for o in moved.obstacles if not o.moving)
    shifted = dataclasses.replace(body, position=body.position + np.array([0.0, 0.0, 1e-9]))
    moved = dataclasses.replace(moved, obstacles=tuple(shifted if o is body else o for o in moved.obstacles))
    keys.add(_guide(moved)._grid_key)
    monkeypatch.setattr(G, "NEAR", G.NEAR + 0.5)
    near = _guide()
    keys.add(near._grid_key)
    assert len(keys) == 3
    # the changed constant changes the costs: the read-back guide would have been wrong
    assert not np.array_equal(near._reverse.data, first._reverse.data)


def test_a_damaged_or_foreign_entry_is_computed_again(folder: Path) -> None:
    computed = _state(_guide())
    for path in folder.glob("*.npz"):
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])  # cut short
    _assert_same(computed, _state(_guide()))
    grid = next(folder.glob("guide-grid-*.npz"))
    other = sorted(folder.glob("guide-ways-*.npz"))[0]
    os.replace(other, grid)  # a file under the grid's name holding another key
    _assert_same(computed, _state(_guide()))


def test_an_unwritable_cache_costs_only_the_speed_up(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(disk_cache.ENV, str(blocker / "cache"))
    assert _guide().guided.any()


def test_keys_tell_values_and_types_apart() -> None:
    parts = [1, 1.0, True, "1", np.array([1]), np.array([1.0]), np.array([[1.0]]), (1,), [1, 1], {"a": 1}]
    parts.append(None)
    keys = {disk_cache.digest(p) for p in parts}
    assert len(keys) == len(parts)
    assert disk_cache.digest(np.array([0.0])) != disk_cache.digest(np.array([-0.0]))
    assert disk_cache.digest({"a": 1, "b": 2}) == disk_cache.digest({"b": 2, "a": 1})
    with pytest.raises(TypeError, match="cannot key"):
        disk_cache.digest(object())


def test_the_oldest_entries_go_beyond_the_size_limit(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for k in range(5):
        disk_cache.save("test", f"key{k}", {"x": np.zeros(1000)})
        os.utime(folder / f"test-key{k}.npz", ns=(10**18 + k, 10**18 + k))  # k-th oldest
    assert disk_cache.load("test", "key0")["x"].shape == (1000,)  # used again: now the newest
    size = (folder / "test-key0.npz").stat().st_size
    monkeypatch.setattr(disk_cache, "MAX_BYTES", 3 * size + size // 2)
    disk_cache.save("test", "key5", {"x": np.zeros(1000)})
    left = sorted(p.stem for p in folder.glob("*.npz"))
    assert left == ["test-key0", "test-key4", "test-key5"]
    assert disk_cache.load("test", "key1") is None
    monkeypatch.setattr(disk_cache, "MAX_ENTRY_BYTES", 7999)
    disk_cache.save("test", "big", {"x": np.zeros(1000)})
    assert disk_cache.load("test", "big") is None


def test_a_run_goes_on_the_same_with_the_tables_read_back(folder: Path) -> None:
    """Two fresh interpreters fly the same world 150 steps: the first computes the tables, the
    second reads them back; every step's positions and velocities are the same bits."""
    code = (
        "import hashlib, sys\n"
        "from swarmplan.bench.sim import swarm_world\n"
        "from swarmplan.planner import make_planner\n"
        "from swarmplan.sim import Simulation\n"
        "from swarmplan.world import parse_world\n"
        "w = parse_world(swarm_world(16, 4, 8))\n"
        "s = Simulation(w, planner=make_planner(w))\n"
        "s.reset(seed=0)\n"
        "h = hashlib.sha256()\n"
        "for _ in range(150):\n"
        "    r = s.step(); h.update(r.state.position.tobytes()); h.update(r.state.velocity.tobytes())\n"
        "    h.update(repr([(e.kind, e.agent) for e in r.events]).encode())\n"
        "print(h.hexdigest(), int(s.guide.guided.sum()))\n"
    )
    env = {**os.environ, disk_cache.ENV: str(folder)}
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
            for _ in range(2)]  # fmt: skip
    assert len(list(folder.glob("*.npz"))) == 2
    assert runs[0].stdout == runs[1].stdout
    off = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**env, disk_cache.ENV: ""})  # fmt: skip
    assert off.stdout == runs[0].stdout


def test_a_mesh_grid_read_back_is_the_computed_one(folder: Path) -> None:
    import trimesh

    from swarmplan.geometry.shapes import MeshGrid

    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    computed = MeshGrid(box.vertices, box.faces, cells=16)
    assert len(list(folder.glob("mesh-grid-*.npz"))) == 1
    read = MeshGrid(box.vertices, box.faces, cells=16)
    for name in ("grid", "grad", "lo", "hi", "mesh_lo", "mesh_hi"):
        a, b = getattr(computed, name), getattr(read, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name
    assert (computed.pitch, computed.watertight) == (read.pitch, read.watertight)
    assert type(read.pitch) is float and read.watertight
    p = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.25]])
    np.testing.assert_allclose(read.exact(p), [-0.25, 1.0, 1.0])  # inside, beside, above
    MeshGrid(box.vertices, box.faces, cells=12)  # another resolution: another entry
    assert len(list(folder.glob("mesh-grid-*.npz"))) == 2
