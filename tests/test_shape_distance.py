"""The shapes' one distance: the compiled ``_shape_kernel`` against exact values on unit shapes,
its numpy twin (``shapes.SDF``, ``shapes.DISTANCE``) bit for bit, and every caller (the field,
the swept checks, the escapes' segment costs, the guide, replay's audit, FCL's geometry) held
to it, shape by shape over the table ``bodies.SHAPES``."""

from __future__ import annotations

import math

import fcl
import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.flight import _guide_kernel, _guide_numpy
from swarmplan.geometry import _shape_kernel as K
from swarmplan.geometry import bodies, shapes, swept_kernels
from swarmplan.geometry.batch import ShapeBatch
from swarmplan.geometry.collision import fcl_geometry, shape_table
from swarmplan.planner import _segment_kernel
from swarmplan.replay.geometry import primitive_distance

S2, S3 = math.sqrt(2.0), math.sqrt(3.0)

UNIT: dict[str, tuple[dict, list[tuple[tuple[float, float, float], float]]]] = {
    "sphere": (
        {"radius": 1.0},
        [((2, 0, 0), 1.0), ((3, 4, 0), 4.0), ((0, -1, 0), 0.0), ((0, 0, 0.5), -0.5), ((0, 0, 0), -1.0)],
    ),
    "box": (
        {"size": [2, 2, 2]},
        [((2, 0, 0), 1.0), ((2, 2, 0), S2), ((-2, 2, 2), S3), ((0.5, 0, 0), -0.5), ((0, 0, 0), -1.0)],
    ),
    "cylinder": (
        {"radius": 1.0, "height": 2.0},
        [((2, 0, 0), 1.0), ((0, 0, 3), 2.0), ((2, 0, -2), S2), ((0, 0.5, 0), -0.5), ((0, 0, 0.9), -0.1)],
    ),
    "capsule": (
        {"radius": 1.0, "height": 2.0},
        [((2, 0, 0), 1.0), ((0, 0, 3), 1.0), ((0, 3, 1), 2.0), ((0, 0, -1.5), -0.5), ((0, 0, 0), -1.0)],
    ),
    "ellipsoid": (
        {"semi_axes": [1, 2, 3]},
        # Outside exact; inside exact on the smallest axis (the bound's depth is the truth there).
        [((3, 0, 0), 2.0), ((0, -5, 0), 3.0), ((0, 0, 4.5), 1.5), ((0.5, 0, 0), -0.5), ((0, 0, 0), -1.0)],
    ),
}
"""Per shape: its world-format parameters and (point, exact signed distance) pairs."""

ANALYTIC = [s for s in bodies.SHAPES if s.code >= 0]


def test_every_analytic_shape_has_unit_cases() -> None:
    assert sorted(UNIT) == sorted(s.name for s in ANALYTIC)


def _prm(name: str) -> np.ndarray:
    return np.array(bodies.shape(name).params(UNIT[name][0]))


@pytest.mark.parametrize("shape", ANALYTIC, ids=lambda s: s.name)
def test_unit_shapes_exact(shape: bodies.Shape) -> None:
    prm = _prm(shape.name)
    for p, want in UNIT[shape.name][1]:
        x, y, z = (float(v) for v in p)
        got = [
            K.sdf(shape.code, x, y, z, *prm),
            K.sdf_grad(shape.code, x, y, z, *prm)[0],
            float(shapes.DISTANCE[shape.code](np.array([p], float), prm)[0]),
            float(shapes.SDF[shape.code](np.array([p], float), prm)[0][0]),
        ]
        assert got[0] == pytest.approx(want, abs=1e-12), (shape.name, p, got)
        assert len({v.hex() for v in got}) == 1, (shape.name, p, got)


def _points(seed: int, n: int = 400) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.normal(0, 2, (n, 3)) * rng.choice([1e-3, 0.5, 1.0, 40.0], (n, 1))
    p[rng.random((n, 3)) < 0.05] = 0.0
    p[rng.random((n, 3)) < 0.05] = -0.0
    return p


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("shape", ANALYTIC, ids=lambda s: s.name)
def test_twin_equals_kernel_bit_for_bit(shape: bodies.Shape, seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    prm = rng.uniform(0.05, 4.0, 3)
    p = _points(seed)
    want_d = shapes.DISTANCE[shape.code](p, prm)
    want_sd, want_g = shapes.SDF[shape.code](p, prm)
    got_d = np.array([K.sdf(shape.code, *q, *prm) for q in p])
    got = np.array([K.sdf_grad(shape.code, *q, *prm) for q in p])
    assert got_d.tobytes() == want_d.tobytes()
    assert got[:, 0].tobytes() == want_sd.tobytes() == want_d.tobytes()
    assert np.ascontiguousarray(got[:, 1:]).tobytes() == np.ascontiguousarray(want_g).tobytes()


def _world(shape: str, rotations: tuple[tuple[float, float, float], ...]):  # noqa: ANN202
    params = UNIT[shape][0]
    obstacles = [
        {"id": f"o{k}", "shape": shape, "position": [30 + 20 * k, 70, 25], "rotation": list(rot), **params}
        for k, rot in enumerate(rotations)
    ]
    return make_world(base_world(obstacles=obstacles))


@pytest.mark.parametrize("shape", ANALYTIC, ids=lambda s: s.name)
def test_every_caller_measures_the_table_distance(shape: bodies.Shape) -> None:
    """Each caller's distance of random points to a body of each shape, unrotated (the same
    bits as the twin) and rotated (the callers turn points with their own products: 1e-12)."""
    world = _world(shape.name, ((0, 0, 0), (20, -35, 70)))
    table = bodies.body_table(world.obstacles)
    assert list(table.code) == [shape.code] * 2
    rng = np.random.default_rng(shape.code)
    pts = table.position[0] + rng.normal(0, 2.5, (300, 3))
    pts = np.concatenate([pts, table.position[1] + rng.normal(0, 2.5, (300, 3))])
    local = [(pts - table.position[j]) @ table.rotation[j] for j in range(2)]
    twin = np.stack([shapes.DISTANCE[shape.code](local[j], table.prm[j]) for j in range(2)], axis=1)

    def same(got: np.ndarray, j: int) -> None:
        if j == 0:
            assert got.tobytes() == twin[:, 0].tobytes()
        else:
            np.testing.assert_allclose(got, twin[:, 1], rtol=0, atol=1e-12)

    # The field: numpy and compiled, with gradients and without.
    for compiled in (False, True):
        batch = ShapeBatch(world.obstacles, compiled=compiled)
        for d in (batch.query(pts)[0], batch.distance(pts)):
            same(d[:, 0], 0)
            same(d[:, 1], 1)
    # The swept checks: the distance outside the body (0 inside).
    code, rot, prm = shape_table(list(world.obstacles))
    assert (code == table.code).all() and (rot == table.rotation).all() and (prm == table.prm).all()
    for j in range(2):
        got = np.array([swept_kernels._point_distance(*q, shape.code, *table.prm[j]) for q in local[j]])
        assert got.tobytes() == np.maximum(twin[:, j], 0.0).tobytes()
    # The escapes' segment costs.
    for j in range(2):
        rel = pts - table.position[j]
        args = (table.code, table.rotation, table.identity, table.prm, j)
        same(np.array([_segment_kernel._body_distance(*args, *r) for r in rel]), j)
    # The guide: the nearest body, compiled and numpy.
    reach = np.ones((1, 2), dtype=np.bool_)
    cells = np.zeros(len(pts), dtype=np.int64)
    prims = (table.position, table.rotation, table.code, table.prm)
    kernels = (_guide_kernel.body_distance, _guide_numpy.body_distance)
    guide = [f(pts, cells, reach, True, *prims) for f in kernels]
    assert guide[0].tobytes() == guide[1].tobytes()
    np.testing.assert_allclose(guide[0], twin.min(axis=1), rtol=0, atol=1e-12)
    # Replay's audit reads the log's obstacles.
    for j, obst in enumerate(world.resolved["obstacles"]):
        assert primitive_distance(local[j], obst).tobytes() == twin[:, j].tobytes()


@pytest.mark.parametrize("shape", ANALYTIC, ids=lambda s: s.name)
def test_fcl_geometry_is_the_table_shape(shape: bodies.Shape) -> None:
    """FCL's distance from small spheres outside the body to the table's FCL geometry is the
    table's distance (FCL decides contacts: both must describe one body)."""
    world = _world(shape.name, ((10, 20, 30),))
    o = world.obstacles[0]
    table = bodies.body_table(world.obstacles)
    body = fcl.CollisionObject(fcl_geometry(o), fcl.Transform(o.rotation, o.position))
    probe_r = 1e-3
    probe = fcl.CollisionObject(fcl.Sphere(probe_r), fcl.Transform())
    rng = np.random.default_rng(7)
    dirs = rng.normal(size=(40, 3))
    pts = o.position + 3.0 * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    for p in pts:
        want = float(shapes.distance_of(shape.code, (p - o.position) @ table.rotation[0], table.prm[0]))
        assert want > 0.1
        probe.setTranslation(p)
        got = fcl.distance(probe, body, fcl.DistanceRequest(), fcl.DistanceResult()) + probe_r
        assert got == pytest.approx(want, abs=1e-4), (shape.name, p)


def test_bounding_radius_holds_the_surface() -> None:
    """Every shape's bound (``bodies.Shape.bound``) holds its drawn surface and is reached."""
    for s in ANALYTIC:
        v = np.asarray(s.surface(UNIT[s.name][0]).vertices)
        bound = s.bound(UNIT[s.name][0])
        assert np.linalg.norm(v, axis=1).max() <= bound + 1e-9
        assert np.linalg.norm(v, axis=1).max() >= 0.9 * bound


def test_ellipsoid_inside_never_shows_less_depth() -> None:
    """Inside an ellipsoid the distance is minus a bound of the depth: never above the true
    signed distance (here against a dense sampling of its surface, which overstates the depth
    by at most the longest edge between its samples)."""
    import trimesh

    axes = np.array([1.0, 2.0, 3.0])
    code = bodies.shape("ellipsoid").code
    sphere = trimesh.creation.icosphere(subdivisions=6)
    surface = sphere.vertices * axes
    gap = np.linalg.norm(
        surface[sphere.edges_unique[:, 0]] - surface[sphere.edges_unique[:, 1]], axis=1
    ).max()
    rng = np.random.default_rng(11)
    p = rng.uniform(-1, 1, (400, 3)) * axes
    p = p[np.linalg.norm(p / axes, axis=1) < 1]
    depth = np.array([np.linalg.norm(surface - q, axis=1).min() for q in p])
    d = shapes.distance_of(code, p, axes)
    assert (d < 0).all()
    assert gap < 0.1
    assert (-d >= depth - gap).all()
    assert (-d <= axes.min()).all()
