"""Every shipped world's log passes ``replay --strict``: the summary the simulator writes agrees
with the metrics replay recomputes independently from the recorded states. The papers' worlds
(``worlds/papers``) get the same audit and turn-limit check on the log of their own run, in
tests/scenarios/test_papers.py.

Plus the cause of the mesh_hangar disagreement, pinned on exact geometry: the mesh distance grid
is only a lower bound beyond its extent, so the clearance metric must query the mesh exactly.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from swarmplan.geometry.shapes import ObstacleField
from swarmplan.world import load_world

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "worlds").rglob("*.yaml"))
WORLDS = [p for p in SHIPPED if p.parent.name != "papers"]
# Every shipped world runs to its end in a few seconds; a cap keeps a future slow world cheap here.
MAX_TIME = "120"


def test_every_shipped_world_is_listed() -> None:
    names = {p.relative_to(ROOT / "worlds").as_posix() for p in WORLDS}
    assert {"mesh_hangar.yaml", "quickstart.yaml", "traps/u_pocket.yaml"} <= names
    papers = {p.relative_to(ROOT / "worlds").as_posix() for p in SHIPPED} - names
    assert "papers/iba_battlefield.yaml" in papers and all(n.startswith("papers/") for n in papers)


@pytest.mark.parametrize("world", WORLDS, ids=[p.relative_to(ROOT / "worlds").as_posix() for p in WORLDS])
def test_replay_strict_agrees_on_shipped_world(world: Path, tmp_path: Path) -> None:
    from swarmplan.cli.replay import main as replay_main
    from swarmplan.cli.run import main as run_main

    log = tmp_path / "run.mcap"
    rc = run_main([str(world), "--out", str(log), "--max-time", MAX_TIME, "--quiet"])
    assert rc in (0, 1) and log.is_file()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = replay_main([str(log), "--strict"])
    assert rc == 0, out.getvalue()
    assert "agreement with /summary: OK" in out.getvalue()
    # Every agent flew within its model's turn limit: a fixed wing's curvature within 1.05 / R_min,
    # a multirotor's lateral acceleration within 1.05 max_accel (stops and reversals counted apart).
    from swarmplan.replay import load

    broken = [a["id"] for a in load(log).summary["agents"] if a.get("curvature_violation")]
    assert broken == [], f"turn limit broken by {broken}"


def test_min_distance_is_exact_beyond_the_mesh_grid() -> None:
    """Points above the hangar's roof, outside its distance grid: the grid gives only a lower
    bound there (metres low off the axes); ``min_distance`` equals trimesh's exact distance."""
    import trimesh

    world = load_world(ROOT / "worlds" / "mesh_hangar.yaml")
    hangar = next(o for o in world.obstacles if o.shape == "mesh")
    field = ObstacleField([hangar])
    grid = field.mesh_grids[0]
    rng = np.random.default_rng(0)
    local = np.column_stack(
        [
            rng.uniform(grid.mesh_lo[0] - 10, grid.mesh_hi[0] + 10, 200),
            rng.uniform(grid.mesh_lo[1] - 10, grid.mesh_hi[1] + 10, 200),
            rng.uniform(grid.hi[2] + 1, grid.hi[2] + 15, 200),
        ]
    )
    points = local @ hangar.rotation.T + hangar.position
    mesh = trimesh.Trimesh(hangar.vertices, hangar.faces, process=False)
    exact = -trimesh.proximity.signed_distance(mesh, local)
    grid_d = field.query(points)[0][:, 0]
    assert (exact - grid_d).max() > 2.0  # the grid's lower bound really is loose here
    assert np.allclose(field.min_distance(points), exact, atol=1e-9)


def test_min_distance_mixes_primitives_and_meshes_exactly() -> None:
    """With a sphere beside the mesh the minimum is the nearer of the two exact distances, and a
    mesh skipped by the bounding-box bound is one that cannot be nearest."""
    import trimesh

    world = load_world(ROOT / "worlds" / "mesh_hangar.yaml")
    obstacles = [o for o in world.obstacles if o.motion is None]
    field = ObstacleField(obstacles)
    rng = np.random.default_rng(1)
    points = rng.uniform([0, 0, 0], [240, 200, 70], (300, 3))
    d = field.query(points)[0]
    want = d.copy()
    for j, o in enumerate(obstacles):
        if o.shape == "mesh":
            mesh = trimesh.Trimesh(o.vertices, o.faces, process=False)
            want[:, j] = -trimesh.proximity.signed_distance(mesh, (points - o.position) @ o.rotation)
    assert np.allclose(field.min_distance(points, d=d), want.min(axis=1), atol=1e-9)
    assert np.all(np.isinf(ObstacleField([]).min_distance(points)))


def test_point_triangle_distance_matches_trimesh() -> None:
    import trimesh

    from swarmplan.geometry.shapes import point_triangle_distance

    rng = np.random.default_rng(2)
    tri = rng.normal(size=(60, 3, 3))
    tri[0, 2] = tri[0, 0] + 2.0 * (tri[0, 1] - tri[0, 0])  # a degenerate (flat) triangle too
    pts = rng.normal(size=(50, 3)) * 3.0
    cp = trimesh.triangles.closest_point(np.tile(tri, (len(pts), 1, 1)), np.repeat(pts, len(tri), axis=0))
    want = np.linalg.norm(cp - np.repeat(pts, len(tri), axis=0), axis=1).reshape(len(pts), len(tri))
    got = point_triangle_distance(pts, tri)
    assert np.allclose(got[:, 1:], want[:, 1:], atol=1e-12)
    assert np.all(got[:, 0] >= want[:, 0].min() - 1e-9) and np.all(np.isfinite(got))


def test_mesh_exact_is_signed_inside_and_out() -> None:
    """Around and inside the hangar (local frame), ``MeshGrid.exact`` equals trimesh's signed distance."""
    import trimesh

    world = load_world(ROOT / "worlds" / "mesh_hangar.yaml")
    hangar = next(o for o in world.obstacles if o.shape == "mesh")
    grid = ObstacleField([hangar]).mesh_grids[0]
    rng = np.random.default_rng(3)
    local = rng.uniform(grid.mesh_lo - 15, grid.mesh_hi + 15, (600, 3))
    want = -trimesh.proximity.signed_distance(
        trimesh.Trimesh(hangar.vertices, hangar.faces, process=False), local
    )
    assert (want < 0).sum() > 50  # inside points are tested
    got = np.concatenate([grid.exact(local[k : k + 30]) for k in range(0, len(local), 30)])
    assert np.allclose(got, want, atol=1e-9)
