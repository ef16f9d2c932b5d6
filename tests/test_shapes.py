"""Analytic signed distances and gradients on unit shapes (hand-computed values), the mesh
distance grid against trimesh's exact distance, and the ObstacleField batch query."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.geometry.rotation import rotation_matrix
from swarmplan.geometry.shapes import MeshGrid, ObstacleField, distance_and_gradient, signed_distance
from swarmplan.world import Obstacle

S2, S3 = math.sqrt(2.0), math.sqrt(3.0)


def obstacle(shape: str, position=(0, 0, 0), rotation=(0, 0, 0), **kw) -> Obstacle:
    if "size" in kw:
        kw["size"] = np.asarray(kw["size"], dtype=float)
    return Obstacle(
        id=shape,
        shape=shape,
        position=np.asarray(position, dtype=float),
        rotation=rotation_matrix(rotation),
        rotation_deg=tuple(float(a) for a in rotation),
        **kw,
    )


def dg(o: Obstacle, p) -> tuple[float, np.ndarray]:
    d, g = distance_and_gradient(o, np.asarray([p], dtype=float))
    return float(d[0]), g[0]


def check(o: Obstacle, p, d_expected: float, g_expected=None) -> None:
    d, g = dg(o, p)
    assert d == pytest.approx(d_expected, abs=1e-12), f"{o.shape} at {p}: distance {d}, expected {d_expected}"
    if g_expected is not None:
        g_expected = np.asarray(g_expected, dtype=float)
        g_expected = g_expected / np.linalg.norm(g_expected)
        np.testing.assert_allclose(g, g_expected, atol=1e-12, err_msg=f"{o.shape} gradient at {p}")


# ----------------------------------------------------------------------------- sphere

SPHERE_CASES = [
    ((2, 0, 0), 1.0, (1, 0, 0)),  # outside on an axis
    ((3, 4, 0), 4.0, (3, 4, 0)),  # outside off-axis: |p| = 5
    ((0, -1, 0), 0.0, (0, -1, 0)),  # on the surface
    ((0, 0, 0.5), -0.5, (0, 0, 1)),  # inside
    ((0, 0.6, -0.8), 0.0, (0, 0.6, -0.8)),
]


@pytest.mark.parametrize("p, d, g", SPHERE_CASES)
def test_sphere_exact(p, d, g):
    check(obstacle("sphere", radius=1.0), p, d, g)


def test_sphere_translated():
    o = obstacle("sphere", position=(10, -5, 3), radius=2.0)
    check(o, (10, -5, 9), 4.0, (0, 0, 1))
    check(o, (10, -4, 3), -1.0, (0, 1, 0))


# ----------------------------------------------------------------------------- box

BOX_CASES = [
    # unit half-extents (size 2)
    ((2, 0, 0), 1.0, (1, 0, 0)),  # face region
    ((0, -3, 0), 2.0, (0, -1, 0)),
    ((2, 2, 0), S2, (1, 1, 0)),  # edge region
    ((-2, 0, -2), S2, (-1, 0, -1)),
    ((2, 2, 2), S3, (1, 1, 1)),  # corner region
    ((-3, 3, -3), 2 * S3, (-1, 1, -1)),
    ((1, 0.3, 0.2), 0.0, (1, 0, 0)),  # on a face
    ((1, 1, 0), 0.0, None),  # on an edge (gradient is a valid choice; not asserted)
    ((0.5, 0, 0), -0.5, (1, 0, 0)),  # inside, nearest face +x
    ((0, 0, -0.9), -0.1, (0, 0, -1)),
    ((0.2, -0.7, 0.1), -0.3, (0, -1, 0)),
]


@pytest.mark.parametrize("p, d, g", BOX_CASES)
def test_box_exact(p, d, g):
    check(obstacle("box", size=(2, 2, 2)), p, d, g)


def test_box_non_cubic():
    o = obstacle("box", size=(2, 4, 6))
    check(o, (0, 0, 0), -1.0, (1, 0, 0))  # nearest face is x (half 1)
    check(o, (0, 0, 5), 2.0, (0, 0, 1))
    check(o, (0, 2.5, 0), 0.5, (0, 1, 0))
    check(o, (4, 5, 0), math.hypot(3, 3), (1, 1, 0))


def test_rotated_box_yaw_90():
    # Long axis (local x, half 2) turned onto world y.
    o = obstacle("box", position=(10, 0, 0), rotation=(0, 0, 90), size=(4, 2, 2))
    check(o, (10, 3, 0), 1.0, (0, 1, 0))
    check(o, (12, 0, 0), 1.0, (1, 0, 0))
    check(o, (10, 0, 2), 1.0, (0, 0, 1))
    check(o, (10, 1.5, 0), -0.5, (0, 1, 0))  # inside, 0.5 from the +y end face
    check(o, (12, 3, 0), S2, (1, 1, 0))  # vertical edge at (11, 2)


def test_rotated_box_yaw_45_edge_on_axis():
    # A unit cube turned 45 degrees about z has a vertical edge on the +x axis at x = sqrt 2.
    o = obstacle("box", rotation=(0, 0, 45), size=(2, 2, 2))
    check(o, (3, 0, 0), 3 - S2, (1, 0, 0))
    check(o, (0, 3, 0), 3 - S2, (0, 1, 0))
    # Face normal is along (1, 1, 0)/sqrt2; the face is at distance 1 from the centre.
    check(o, (2 / S2, 2 / S2, 0), 1.0, (1, 1, 0))


def test_rotated_box_roll_pitch():
    # Pitch 90: local x -> world -z, local z -> world x.
    o = obstacle("box", rotation=(0, 90, 0), size=(6, 2, 2))
    check(o, (0, 0, 5), 2.0, (0, 0, 1))
    check(o, (3, 0, 0), 2.0, (1, 0, 0))
    # Roll 90: local y -> world z.
    o = obstacle("box", rotation=(90, 0, 0), size=(2, 6, 2))
    check(o, (0, 0, 5), 2.0, (0, 0, 1))
    check(o, (0, 3, 0), 2.0, (0, 1, 0))


# ----------------------------------------------------------------------------- cylinder

CYL_CASES = [
    # radius 1, height 4 (half 2), axis z
    ((3, 0, 0), 2.0, (1, 0, 0)),  # side
    ((0, -2, 1), 1.0, (0, -1, 0)),
    ((0, 0, 5), 3.0, (0, 0, 1)),  # above the top face
    ((0.5, 0, -3), 1.0, (0, 0, -1)),  # below the bottom face
    ((4, 0, 6), 5.0, (3, 0, 4)),  # beyond the rim: hypot(3, 4)
    ((0, 1, 0), 0.0, (0, 1, 0)),  # on the side
    ((0.3, 0, 2), 0.0, (0, 0, 1)),  # on the top face
    ((0.5, 0, 0), -0.5, (1, 0, 0)),  # inside, nearest side
    ((0, 0.1, 1.8), -0.2, (0, 0, 1)),  # inside, nearest top
]


@pytest.mark.parametrize("p, d, g", CYL_CASES)
def test_cylinder_exact(p, d, g):
    check(obstacle("cylinder", radius=1.0, height=4.0), p, d, g)


def test_cylinder_tilted():
    # Roll 90: axis along world -y; the flat ends face +-y.
    o = obstacle("cylinder", position=(0, 0, 10), rotation=(90, 0, 0), radius=1.0, height=4.0)
    check(o, (0, 5, 10), 3.0, (0, 1, 0))
    check(o, (0, 0, 13), 2.0, (0, 0, 1))


# ----------------------------------------------------------------------------- capsule

CAP_CASES = [
    # radius 1, straight section 2 (half 1), axis z
    ((3, 0, 0), 2.0, (1, 0, 0)),
    ((0, 3, 0.7), 2.0, (0, 1, 0)),  # beside the straight section
    ((0, 0, 4), 2.0, (0, 0, 1)),  # above: cap centre at z = 1
    ((3, 0, 5), 4.0, (3, 0, 4)),  # diagonal from the cap centre
    ((0, 0, -2), 0.0, (0, 0, -1)),  # tip of the bottom cap
    ((0, 0.5, 0), -0.5, (0, 1, 0)),  # inside
    ((0, 0, 1.5), -0.5, (0, 0, 1)),  # inside the top cap
]


@pytest.mark.parametrize("p, d, g", CAP_CASES)
def test_capsule_exact(p, d, g):
    check(obstacle("capsule", radius=1.0, height=2.0), p, d, g)


def test_capsule_pitched_axis_along_x():
    o = obstacle("capsule", rotation=(0, 90, 0), radius=1.0, height=4.0)
    check(o, (4, 0, 0), 1.0, (1, 0, 0))  # beyond the end at x = 2
    check(o, (0, 0, 3), 2.0, (0, 0, 1))
    check(o, (-1.5, 2, 0), 1.0, (0, 1, 0))


# ----------------------------------------------------------------------------- gradients


def _random_points(rng, n, spread=4.0):
    return rng.uniform(-spread, spread, size=(n, 3))


ALL_SHAPES = [
    obstacle("sphere", radius=1.3),
    obstacle("box", size=(2, 3, 1), rotation=(10, 20, 30)),
    obstacle("cylinder", radius=1.0, height=3.0, rotation=(0, 30, 60)),
    obstacle("capsule", radius=0.7, height=2.0, rotation=(45, 0, 10)),
]


@pytest.mark.parametrize("o", ALL_SHAPES, ids=lambda o: o.shape)
def test_gradient_is_unit_and_matches_finite_differences(o):
    rng = np.random.default_rng(3)
    pts = _random_points(rng, 400)
    d, g = distance_and_gradient(o, pts)
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-9)
    h = 1e-6
    fd = np.stack(
        [(signed_distance(o, pts + h * e) - signed_distance(o, pts - h * e)) / (2 * h) for e in np.eye(3)],
        axis=1,
    )
    # Away from the medial axis / edges the SDF is differentiable and the gradient is exact.
    smooth = np.linalg.norm(fd, axis=1) > 1 - 1e-4
    assert smooth.mean() > 0.8
    np.testing.assert_allclose(g[smooth], fd[smooth], atol=1e-4)
    # Stepping along the gradient changes the distance by the step (outside, 1-Lipschitz, exact).
    out = d > 0.05
    step = 0.01
    d2 = signed_distance(o, pts[out] + step * g[out])
    np.testing.assert_allclose(d2 - d[out], step, atol=1e-9)


@pytest.mark.parametrize("o", ALL_SHAPES, ids=lambda o: o.shape)
def test_matches_fcl_distance_outside(o):
    """An independent reference: FCL's distance from a tiny sphere to the primitive."""
    import fcl

    from swarmplan.geometry.collision import fcl_geometry

    rng = np.random.default_rng(5)
    pts = _random_points(rng, 60, spread=5.0)
    d = signed_distance(o, pts)
    body = fcl.CollisionObject(fcl_geometry(o), fcl.Transform(o.rotation, o.position))
    probe_r = 1e-4
    checked = 0
    for p, dp in zip(pts, d, strict=True):
        if dp < 0.05:
            continue
        probe = fcl.CollisionObject(fcl.Sphere(probe_r), fcl.Transform(np.asarray(p, dtype=float)))
        ref = fcl.distance(body, probe, fcl.DistanceRequest(), fcl.DistanceResult()) + probe_r
        assert dp == pytest.approx(ref, abs=2e-3), f"{o.shape} at {p}: {dp} vs fcl {ref}"
        checked += 1
    assert checked > 20


# ----------------------------------------------------------------------------- mesh grid


@pytest.fixture(scope="module")
def unit_box_mesh():
    import trimesh

    m = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    return np.asarray(m.vertices, dtype=float), np.asarray(m.faces, dtype=np.int64), m


@pytest.fixture(scope="module")
def unit_box_grid(unit_box_mesh):
    v, f, _ = unit_box_mesh
    return MeshGrid(v, f)


def test_mesh_grid_within_one_voxel_of_exact(unit_box_mesh, unit_box_grid):
    import trimesh

    mesh = unit_box_mesh[2]
    grid = unit_box_grid
    rng = np.random.default_rng(11)
    pts = rng.uniform(-0.6, 0.6, size=(2000, 3))  # inside and outside, all within the grid
    d, g = grid.query(pts)
    exact = -trimesh.proximity.signed_distance(mesh, pts)  # trimesh: positive inside
    err = np.abs(d - exact)
    assert err.max() <= grid.pitch, f"max error {err.max():.4f} > one voxel {grid.pitch:.4f}"
    # Signs agree wherever the point is more than a voxel from the surface.
    far = np.abs(exact) > grid.pitch
    assert np.all(np.sign(d[far]) == np.sign(exact[far]))
    # The gradient of the grid is a unit vector pointing roughly along the true normal.
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-6)
    analytic_g = distance_and_gradient(obstacle("box", size=(1, 1, 1)), pts)[1]
    clear = np.abs(exact) > 2 * grid.pitch
    face = (np.sort(np.abs(pts), axis=1)[:, 2] - np.sort(np.abs(pts), axis=1)[:, 1]) > 0.1
    cos = np.sum(g * analytic_g, axis=1)[clear & face]
    assert np.median(cos) > 0.95


def test_mesh_grid_beyond_the_grid_along_the_axes(unit_box_grid):
    grid = unit_box_grid
    pts = np.array([[5.0, 0, 0], [0, -7.5, 0], [3, 3, 3]])
    d, g = grid.query(pts)
    exact = signed_distance(obstacle("box", size=(1, 1, 1)), pts)
    assert np.all(d <= exact + grid.pitch)
    assert np.all(d >= exact - 2 * grid.pitch)
    np.testing.assert_allclose(g[0], [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(g[1], [0, -1, 0], atol=1e-9)


def test_mesh_obstacle_in_world_frame(unit_box_mesh):
    """A placed, rotated mesh obstacle measures like the equivalent analytic box."""
    v, f, _ = unit_box_mesh
    kw = dict(position=(20, -3, 7), rotation=(0, 0, 30))
    mesh_o = obstacle("mesh", vertices=v * np.array([2.0, 1.0, 1.0]), faces=f, **kw)
    box_o = obstacle("box", size=(2, 1, 1), **kw)
    rng = np.random.default_rng(2)
    pts = np.array([20, -3, 7]) + rng.uniform(-1.5, 1.5, size=(500, 3))
    field = ObstacleField([mesh_o])
    d, _ = field.query(pts)
    d = d[:, 0]
    exact = signed_distance(box_o, pts)
    grid = field.mesh_grids[0]
    local = (pts - mesh_o.position) @ mesh_o.rotation
    in_grid = np.all((local >= grid.lo) & (local <= grid.hi), axis=1)
    assert in_grid.sum() > 50
    assert np.abs(d[in_grid] - exact[in_grid]).max() <= grid.pitch
    assert np.all(d[~in_grid] > 0)


def test_mesh_grid_beyond_the_grid_never_overstates_clearance(unit_box_grid):
    grid = unit_box_grid
    # Beyond +x, level with the box's top-front edge region (clamped onto the grid face).
    pts = np.array([[3.0, 0.6, 0.6], [1.5, 0.66, 0.0], [10.0, 0.66, 0.66]])
    d, _ = grid.query(pts)
    exact = signed_distance(obstacle("box", size=(1, 1, 1)), pts)
    assert np.all(d <= exact + grid.pitch), f"grid {d} vs exact {exact} (pitch {grid.pitch:.4f})"
    # ... and stays a useful estimate, not a trivial bound: within a few voxels of the truth.
    assert np.all(d >= exact - 4 * grid.pitch), f"grid {d} vs exact {exact} (pitch {grid.pitch:.4f})"
    # Straight out along an axis the value is exact (distance to the face).
    d_axis, g_axis = grid.query(np.array([[7.0, 0.0, 0.0]]))
    assert d_axis[0] == pytest.approx(6.5, abs=1e-9)
    assert g_axis[0] == pytest.approx([1.0, 0.0, 0.0])


# ----------------------------------------------------------------------------- field


def test_obstacle_field_batches_every_obstacle_and_moves_centres():
    obs = [
        obstacle("sphere", position=(0, 0, 0), radius=1.0),
        obstacle("box", position=(10, 0, 0), size=(2, 2, 2)),
        obstacle("cylinder", position=(0, 10, 0), radius=1.0, height=4.0),
    ]
    field = ObstacleField(obs)
    assert len(field) == 3
    pts = np.array([[3.0, 0, 0], [10, 3, 0], [0, 10, 6]])
    d, g = field.query(pts)
    assert d.shape == (3, 3) and g.shape == (3, 3, 3)
    assert d[0, 0] == pytest.approx(2.0)
    assert d[1, 1] == pytest.approx(2.0)
    assert d[2, 2] == pytest.approx(4.0)
    for j, o in enumerate(obs):
        dj, gj = distance_and_gradient(o, pts)
        np.testing.assert_allclose(d[:, j], dj)
        np.testing.assert_allclose(g[:, j], gj)
    # Moving the sphere onto the first point puts that point at its centre (inside, -radius).
    centers = np.array([[3.0, 0, 0], [10, 0, 0], [0, 10, 0]])
    d2, _ = field.query(pts, centers)
    assert d2[0, 0] == pytest.approx(-1.0)
    np.testing.assert_allclose(d2[:, 1:], d[:, 1:])
