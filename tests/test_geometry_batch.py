"""Distances batched by shape type equal the per-shape path; exact values on unit shapes."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import obstacles_of, random_shapes

from swarmplan.geometry.batch import ShapeBatch
from swarmplan.geometry.shapes import ObstacleField


def _obstacles(raw):
    return obstacles_of(raw, start=(-40, -40, 40), goal=(40, 40, 40))


UNIT = [
    {"id": "s", "shape": "sphere", "radius": 1.0, "position": [0, 0, 0]},
    {"id": "b", "shape": "box", "size": [2, 2, 2], "position": [0, 0, 0]},
    {"id": "c", "shape": "cylinder", "radius": 1.0, "height": 2.0, "position": [0, 0, 0]},
    {"id": "k", "shape": "capsule", "radius": 1.0, "height": 2.0, "position": [0, 0, 0]},
]


def test_exact_distances_on_unit_shapes():
    batch = ShapeBatch(_obstacles(UNIT))
    pts = np.array([[3.0, 0, 0], [0, 0, 3.0], [2.0, 2.0, 0], [0.5, 0, 0], [2.0, 0, 2.0]])
    d = batch.distance(pts)
    r2 = np.sqrt(2.0)
    expected = np.array(
        [
            [2.0, 2.0, 2.0, 2.0],  # on the x axis
            [2.0, 2.0, 2.0, 1.0],  # above: the capsule's cap reaches z = 2
            [2 * r2 - 1, r2, 2 * r2 - 1, 2 * r2 - 1],
            [-0.5, -0.5, -0.5, -0.5],  # inside all four
            [2 * r2 - 1, r2, r2, np.sqrt(5.0) - 1],  # beside the top edge (capsule: segment end z = 1)
        ]
    )
    np.testing.assert_allclose(d, expected, atol=1e-15)
    dq, _ = batch.query(pts)
    np.testing.assert_array_equal(dq, d)


@pytest.mark.parametrize("seed", range(3))
def test_batched_equals_per_shape_with_rotations_and_centers(seed):
    rng = np.random.default_rng(seed)
    raw = random_shapes(rng, 12)
    obs = _obstacles(raw)
    pts = rng.uniform(-30, 30, (500, 3))
    field, batch = ObstacleField(obs), ShapeBatch(obs)
    d_ref, g_ref = field.query(pts)
    d, g = batch.query(pts)
    # query feeds the simulator's field: bit for bit (signs of zeros too), or runs diverge.
    np.testing.assert_array_equal(d, d_ref)
    np.testing.assert_array_equal(g, g_ref)
    assert not np.any(np.signbit(g) != np.signbit(g_ref))
    np.testing.assert_allclose(batch.distance(pts), d_ref, rtol=0, atol=1e-12)
    centers = np.array([o.position for o in obs]) + rng.normal(size=(len(obs), 3))
    d_ref, g_ref = field.query(pts, centers)
    d, g = batch.query(pts, centers)
    np.testing.assert_array_equal(d, d_ref)
    np.testing.assert_array_equal(g, g_ref)


def test_distance_to_a_subset_keeps_its_order():
    obs = _obstacles(UNIT + [{"id": "s2", "shape": "sphere", "radius": 2.0, "position": [5, 0, 0]}])
    batch = ShapeBatch(obs)
    pts = np.random.default_rng(3).uniform(-6, 6, (50, 3))
    full = batch.distance(pts)
    for subset in ([4, 0], [2], [3, 1, 4]):
        np.testing.assert_array_equal(batch.distance(pts, subset=np.array(subset)), full[:, subset])


@pytest.mark.parametrize("seed", range(2))
def test_pair_distance_equals_the_matrix_entries(seed):
    rng = np.random.default_rng(seed)
    raw = []
    for k in range(10):
        shape = ("sphere", "box", "cylinder", "capsule")[k % 4]
        o = {"id": f"o{k}", "shape": shape, "position": rng.uniform(-20, 20, 3).tolist()}
        if shape == "box":
            o["size"] = rng.uniform(1, 8, 3).tolist()
            o["rotation"] = rng.uniform(-90, 90, 3).tolist()
        else:
            o["radius"] = float(rng.uniform(0.5, 4))
        if shape in ("cylinder", "capsule"):
            o["height"] = float(rng.uniform(1, 10))
        raw.append(o)
    batch = ShapeBatch(_obstacles(raw))
    pts = rng.uniform(-30, 30, (300, 3))
    bodies = rng.integers(0, len(raw), 300)
    full = batch.distance(pts)
    np.testing.assert_allclose(
        batch.pair_distance(pts, bodies), full[np.arange(300), bodies], rtol=0, atol=1e-12
    )


def test_mesh_world_query_and_exact_min_distance_equal_obstacle_field():
    """The simulator's distances come from ShapeBatch: on the hangar world (a mesh among
    primitives, moved centers too) ``query`` and the exact ``min_distance`` of the clearance
    metric equal ObstacleField's, including above the roof where the mesh grid is a loose bound."""
    from pathlib import Path

    from swarmplan.world import load_world

    world = load_world(Path(__file__).resolve().parents[1] / "worlds" / "mesh_hangar.yaml")
    obs = world.obstacles
    assert any(o.shape == "mesh" for o in obs) and any(o.shape != "mesh" for o in obs)
    field, batch = ObstacleField(obs), ShapeBatch(obs)
    rng = np.random.default_rng(4)
    pts = rng.uniform([0, 0, 0], [240, 200, 90], (300, 3))
    centers = np.array([o.position for o in obs]) + rng.normal(size=(len(obs), 3))
    for c in (None, centers):
        d_ref, g_ref = field.query(pts, c)
        d, g = batch.query(pts, c)
        np.testing.assert_array_equal(d, d_ref)
        np.testing.assert_array_equal(g, g_ref)
        want = field.min_distance(pts, c, d_ref)
        np.testing.assert_allclose(batch.min_distance(pts, c, d), want, rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch.min_distance(pts, c), want, rtol=0, atol=1e-12)
    assert np.all(np.isinf(ShapeBatch([]).min_distance(pts)))
