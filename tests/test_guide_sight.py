"""The guide's line-of-sight check (swarmplan.flight.guide.StaticGuide.blocked) passes over lines
that cannot land a sample in a cell near a surface and measures a sample's distances only near
a body's bounding box: on random lines among boxes, cylinders, capsules and spheres, over flat
ground and over terrain (and with a mesh among the bodies), its answers equal those of
measuring every sample of every line; the bounding boxes hold the bodies (no distance below the
box's), and the gap table is the distance between cell boxes."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.flight import _guide_kernel as K
from swarmplan.flight import guide as G
from swarmplan.flight.kinematics import AgentParams

OBSTACLES = [
    {"id": "box", "shape": "box", "size": [10, 10, 30], "position": [30, 30, 15], "rotation": [0, 0, 30]},
    {"id": "pillar", "shape": "cylinder", "radius": 3.0, "height": 25.0, "position": [70, 60, 12.5]},
    {"id": "ball", "shape": "sphere", "radius": 5.0, "position": [60, 25, 30]},
    {
        "id": "beam",
        "shape": "capsule",
        "radius": 2.0,
        "height": 20.0,
        "position": [40, 75, 20],
        "rotation": [40, 30, 0],
    },
    {
        "id": "log",
        "shape": "cylinder",
        "radius": 2.5,
        "height": 15.0,
        "position": [80, 20, 10],
        "rotation": [0, 70, 20],
    },
]
PEAKS = {"peaks": [{"center": [20, 80], "height": 12.0, "spread": [10, 10]}]}


def _guide(terrain: bool, agents: int) -> G.StaticGuide:
    raw = base_world(
        obstacles=OBSTACLES,
        agents=[
            # a block of agents 2.1 m apart (clear of each other's bodies) by a corner of the box
            {
                "id": f"a{k}",
                "start": [3.0 + 2.1 * (k // 40), 3.0 + 2.1 * (k % 40), 40.0 + 2.1 * (k // 200)],
                "goal": [97.0 - 2.1 * (k // 40), 97.0 - 2.1 * (k % 40), 40.0 + 2.1 * (k // 200)],
            }
            for k in range(agents)
        ],
    )
    if terrain:
        raw["terrain"] = PEAKS
    world = make_world(raw)
    return G.make_guide(world, AgentParams.from_world(world))


@pytest.mark.parametrize(("terrain", "agents"), [(False, 1), (True, 1), (False, 200)])
def test_passing_over_lines_changes_no_answer(terrain: bool, agents: int) -> None:
    guide = _guide(terrain, agents)  # 200 agents: a coarser grid
    assert guide._lipschitz is not terrain  # over terrain no sample is decided by its cell alone
    rng = np.random.default_rng(7 + agents)
    lo, hi = np.array([-5.0, -5.0, 0.0]), np.array([105.0, 105.0, 55.0])
    passed = far = 0
    for trial in range(30):
        n = 300
        start = rng.uniform(lo, hi, (n, 3))
        end = start + rng.normal(size=(n, 3)) * rng.choice([2.0, 10.0, 40.0])
        reach = rng.choice([np.inf, 5.0, 20.0], n) if trial % 2 else np.inf
        fast = guide.blocked(start, end, reach)
        slow = _every_sample(guide, *_cut(start, end, reach))
        np.testing.assert_array_equal(fast, slow)
        passed += int(_passed_over(guide, *_cut(start, end, reach)).sum())
        far += int((~slow).sum())
    assert 0 < passed <= far


def _cut(start: np.ndarray, end: np.ndarray, reach: np.ndarray | float) -> tuple[np.ndarray, ...]:
    length = np.linalg.norm(end - start, axis=1)
    cut = np.minimum(length, reach)
    return start, start + (end - start) * (cut / np.maximum(length, 1e-12))[:, None], cut


def _every_sample(guide: G.StaticGuide, start: np.ndarray, end: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Whether a sample of each line comes within SQUEEZE: every sample measured to every body."""
    samples = int(min(max(np.ceil(length.max() / (0.5 * float(guide.cell.min()))), 1), 4000))
    t = np.linspace(0.0, 1.0, samples + 1)
    p = (start[:, None, :] + t[None, :, None] * (end - start)[:, None, :]).reshape(-1, 3)
    exact = p[:, 2] - guide.world.terrain_height(p[:, :2]) - guide.floor
    exact = np.minimum(exact, guide._batch.distance(p).min(axis=1)) - guide.radius
    return (exact < guide.squeeze).reshape(len(start), -1).any(axis=1)


def _passed_over(guide: G.StaticGuide, start: np.ndarray, end: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The lines the gap table passes over (start cell's gap beyond the length, ends high enough)."""
    reach = length * (1.0 + 1e-9) + 1e-6
    kz = np.floor((np.column_stack([start[:, 2], end[:, 2]]) - guide.lo[2]) / guide.cell[2])
    kz = np.clip(kz, 0, guide.shape[2] - 1).min(axis=1)
    return (guide._gap[guide.cell_of(start)] > reach) & (kz >= guide._low)


def test_gap_is_the_distance_between_cell_boxes() -> None:
    guide = _guide(False, 1)
    near = (guide.clear < guide.half_diagonal + guide.squeeze) & (guide.ijk[:, 2] >= guide._low)
    rng = np.random.default_rng(3)
    for c in rng.integers(0, guide.n_cells, 40):
        d = np.maximum(np.abs(guide.ijk[near] - guide.ijk[c]) - 1, 0) * guide.cell
        np.testing.assert_allclose(guide._gap[c], np.sqrt((d**2).sum(axis=1)).min(), rtol=1e-12)


def test_the_compiled_gap_table_is_numpys_shift_by_shift() -> None:
    for terrain, agents in ((False, 1), (True, 64)):
        guide = _guide(terrain, agents)
        near = (guide.clear < guide.half_diagonal + guide.squeeze) & (guide.ijk[:, 2] >= guide._low)
        sq = np.where(near.reshape(tuple(int(v) for v in guide.shape)), 0.0, np.inf)
        for axis in range(3):
            src = np.moveaxis(sq, axis, 0)
            out = src.copy()
            for s in range(1, int(guide.shape[axis])):
                term = (max(s - 1, 0) * guide.cell[axis]) ** 2
                np.minimum(out[s:], src[:-s] + term, out=out[s:])
                np.minimum(out[:-s], src[s:] + term, out=out[:-s])
            sq = np.moveaxis(out, 0, axis)
        expect = np.sqrt(sq).ravel()
        assert np.array_equal(guide._gap.view(np.int64), expect.view(np.int64))
        assert guide._gap_max == expect.max() and 0 < (guide._gap > 0).sum() < guide.n_cells


def test_bounding_boxes_bound_the_distances() -> None:
    guide = _guide(False, 1)
    rng = np.random.default_rng(5)
    p = rng.uniform([-10, -10, -5], [110, 110, 60], (20000, 3))
    gap = np.maximum(np.abs(p[:, None, :] - guide._batch.position[None]) - guide._box_half[None], 0.0)
    below = np.sqrt((gap * gap).sum(axis=2))
    d = guide._batch.distance(p)
    assert (d[below > 0] >= below[below > 0] - 1e-9).all()  # inside a box: any distance
    assert (np.abs(d - below) < 0.5).any(axis=0).all()  # and not loosely: some points come close


def test_the_compiled_reach_table_is_numpys() -> None:
    guide = _guide(False, 1)
    lo = guide.lo + guide.ijk * guide.cell
    hi = lo + guide.cell
    b = guide._batch
    for k in range(len(guide.bodies)):
        c, e = b.position[k], guide._box_half[k]
        gap = np.maximum(np.maximum(lo - (c + e), (c - e) - hi), 0.0)
        expect = np.sqrt((gap * gap).sum(axis=1)) < guide.radius + guide.squeeze + 1e-6
        np.testing.assert_array_equal(guide._reach[:, k], expect)
        assert expect.any() and not expect.all()  # cells round the body, and cells away from it


def test_pairs_measure_the_bits_of_every_body() -> None:
    guide = _guide(False, 1)
    rng = np.random.default_rng(9)
    b = guide._batch
    p = rng.uniform([1, 1, 1], [99, 99, 49], (5000, 3))
    near = b.position[rng.integers(0, len(b), 5000)] + rng.normal(size=(5000, 3)) * rng.choice(
        [0.5, 3.0], (5000, 1)
    )
    p = np.vstack([p, np.clip(near, 1, 49)])  # in the grid, inside and around every body
    guide._reach = np.ones_like(guide._reach)
    got = guide._body_distance(p, guide.cell_of(p))
    np.testing.assert_array_equal(got, b.distance(p).min(axis=1))
    # and body by body, as numpy's formulas give them (spheres too, of every shape)
    for j in range(len(b)):
        one = K.body_distance(
            p, np.zeros(len(p), dtype=np.int64), np.ones((1, 1), dtype=bool), False,
            b.position[j : j + 1], b.rotation[j : j + 1], b.code[j : j + 1], b.prm[j : j + 1],
        )  # fmt: skip
        np.testing.assert_array_equal(one, b.distance(p)[:, j])
    assert (got < 0).any() and (got > 5).any()  # inside bodies and far from them


def test_cell_of_is_the_clipped_floor_of_the_grid_coordinates() -> None:
    guide = _guide(False, 1)
    rng = np.random.default_rng(12)
    size = guide.shape * guide.cell
    p = guide.lo + rng.uniform(-0.2, 1.2, (5000, 3)) * size
    p[:300] = guide.lo + rng.integers(0, guide.shape + 1, (300, 3)) * guide.cell  # on cell faces
    ijk = np.clip(np.floor((p - guide.lo) / guide.cell).astype(np.int64), 0, guide.shape - 1)
    expect = (ijk[:, 0] * guide.shape[1] + ijk[:, 1]) * guide.shape[2] + ijk[:, 2]
    np.testing.assert_array_equal(guide.cell_of(p), expect)
    assert guide.cell_of(guide.centres[[0, 7, guide.n_cells - 1]]).tolist() == [0, 7, guide.n_cells - 1]


def test_a_mesh_among_the_bodies_is_measured_from_its_grid(tmp_path) -> None:
    """With a mesh among the bodies every sample is measured against every body in numpy, the
    mesh from its distance grid: the distances of ``ShapeBatch.distance``, and the answers of
    measuring every sample, on lines inside the grid (where no sample calls for every body)."""
    import trimesh

    trimesh.creation.box(extents=(10.0, 10.0, 20.0)).export(tmp_path / "cube.stl")
    mesh = {"id": "m", "shape": "mesh", "file": str(tmp_path / "cube.stl"), "position": [50, 50, 10]}
    raw = base_world(
        obstacles=[mesh, OBSTACLES[2]], agents=[{"id": "a", "start": [5, 5, 40], "goal": [95, 95, 40]}]
    )
    world = make_world(raw)
    guide = G.make_guide(world, AgentParams.from_world(world))
    rng = np.random.default_rng(2)
    p = rng.uniform([1, 1, 1], [99, 99, 49], (3000, 3))
    d = guide._body_distance(p, guide.cell_of(p))
    np.testing.assert_array_equal(d, guide._batch.distance(p).min(axis=1))
    start = rng.uniform([2, 2, 2], [98, 98, 48], (2000, 3))
    end = np.clip(start + rng.normal(size=(2000, 3)) * 10.0, 2.0, 48.0)
    fast = guide.blocked(start, end)
    np.testing.assert_array_equal(fast, _every_sample(guide, *_cut(start, end, np.inf)))
    assert 0 < fast.sum() < len(fast)
