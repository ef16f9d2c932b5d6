"""FCL swept checks on unit shapes at exact contact thresholds (± epsilon), moving obstacles,
thin walls that a discrete check would tunnel through, meshes, ground, bounds, and the
analytic agent-agent closest approach."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.geometry.collision import CollisionWorld, agent_contacts, segment_segment_min_distance

C = np.array([50.0, 80.0, 25.0])  # where the obstacle under test sits
EPS = 1e-3
X = np.array([1.0, 0, 0])
Y = np.array([0, 1.0, 0])
Z = np.array([0, 0, 1.0])


def world_with(*obstacles, tmp_path=None):
    return make_world(base_world(obstacles=list(obstacles)), base_dir=tmp_path or ".")


def cw(obst: dict, tmp_path=None) -> CollisionWorld:
    return CollisionWorld(world_with(obst, tmp_path=tmp_path))


def sweep(c: CollisionWorld, a, b, r=1.0):
    return c.sweep_static(C + np.asarray(a, float), C + np.asarray(b, float), r)


# ----------------------------------------------------------------------------- static primitives


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_sphere_pass_by_threshold(eps, hit):
    c = cw({"id": "s", "shape": "sphere", "radius": 1.0, "position": C.tolist()})
    # Passing sideways: closest approach of the centre line is 2 + eps; contact at 2 (1 + 1).
    got = sweep(c, (-10, 2 + eps, 0), (10, 2 + eps, 0))
    assert got == ("s" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_box_face_threshold(eps, hit):
    c = cw({"id": "b", "shape": "box", "size": [2, 2, 2], "position": C.tolist()})
    got = sweep(c, (-10, 2 + eps, 0.3), (10, 2 + eps, 0.3))
    assert got == ("b" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_box_vertical_edge_threshold(eps, hit):
    # Line x + y = k passes the edge at (1, 1) at distance (k - 2)/sqrt2: contact below k = 2 + sqrt2.
    c = cw({"id": "b", "shape": "box", "size": [2, 2, 2], "position": C.tolist()})
    k = 2 + math.sqrt(2) + eps * math.sqrt(2)
    a = np.array([k + 10, -10, 0.0])
    b = np.array([k - 10, 10, 0.0])
    assert sweep(c, a, b) == ("b" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_box_corner_threshold(eps, hit):
    # Approach the corner (1,1,1) along the diagonal, stopping at distance 1 + eps from it.
    c = cw({"id": "b", "shape": "box", "size": [2, 2, 2], "position": C.tolist()})
    u = np.ones(3) / math.sqrt(3)
    end = np.ones(3) + (1 + eps) * u
    assert sweep(c, end + 10 * u, end) == ("b" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_rotated_box_threshold(eps, hit):
    # A unit cube turned 45 degrees about z: its vertical edge sits on +x at sqrt2.
    c = cw({"id": "b", "shape": "box", "size": [2, 2, 2], "position": C.tolist(), "rotation": [0, 0, 45]})
    x = math.sqrt(2) + 1 + eps
    assert sweep(c, (x, -10, 0), (x, 10, 0)) == ("b" if hit else None)
    # Its y extent is sqrt2 as well: a sweep along x just beyond it is clear.
    assert sweep(c, (-10, math.sqrt(2) + 1 + 0.05, 0), (10, math.sqrt(2) + 1 + 0.05, 0)) is None


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_cylinder_top_threshold(eps, hit):
    c = cw({"id": "c", "shape": "cylinder", "radius": 1.0, "height": 4.0, "position": C.tolist()})
    z = 2 + 1 + eps  # top face at 2, sweep radius 1
    assert sweep(c, (-10, 0.2, z), (10, 0.2, z)) == ("c" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_cylinder_side_threshold(eps, hit):
    c = cw({"id": "c", "shape": "cylinder", "radius": 1.0, "height": 4.0, "position": C.tolist()})
    assert sweep(c, (2 + eps, -10, 0.5), (2 + eps, 10, 0.5)) == ("c" if hit else None)


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_capsule_cap_threshold(eps, hit):
    # Straight section 2 (ends at z = +-1), radius 1: passing over the cap centre at height 3.
    c = cw({"id": "p", "shape": "capsule", "radius": 1.0, "height": 2.0, "position": C.tolist()})
    z = 1 + 1 + 1 + eps
    assert sweep(c, (-10, 0, z), (10, 0, z)) == ("p" if hit else None)


def test_capsule_is_not_a_cylinder():
    # Beside the rim of the equivalent cylinder (|xy| = 1, z = 1) but clear of the rounded cap.
    c = cw({"id": "p", "shape": "capsule", "radius": 1.0, "height": 2.0, "position": C.tolist()})
    d = np.array([1.0, 0, 1.0]) / math.sqrt(2)
    p = np.array([0, 0, 1.0]) + (1 + 0.3 + 0.2) * d  # 0.2 m beyond contact with radius 0.3
    assert c.sweep_static(C + p, C + p, 0.3) is None
    p = np.array([0, 0, 1.0]) + (1 + 0.3 - 0.05) * d
    assert c.sweep_static(C + p, C + p, 0.3) == "p"


@pytest.mark.parametrize("length", [0.5, 2.0, 5.0, 10.0])
def test_long_step_ending_inside_contact_is_a_hit(length):
    """Straight into the +x face of a cube, ending 0.5 m inside contact: a hit for any step length.

    The contact lies at the far end of the swept capsule, ``length / 2`` from its middle, so
    this also checks that the broad phase sees the capsule's real extent.
    """
    c = cw({"id": "b", "shape": "box", "size": [2, 2, 2], "position": C.tolist()})
    assert sweep(c, (1.5 + length, 0, 0), (1.5, 0, 0), r=1.0) == "b"
    # A wider body, same path: still a hit.
    assert sweep(c, (2.2 + length, 0, 0), (2.2, 0, 0), r=1.75) == "b"


def test_stationary_sphere_query():
    c = cw({"id": "s", "shape": "sphere", "radius": 1.0, "position": C.tolist()})
    assert c.sweep_static(C + 1.99 * X, C + 1.99 * X, 1.0) == "s"
    assert c.sweep_static(C + 2.01 * X, C + 2.01 * X, 1.0) is None


def test_thin_wall_cannot_be_tunnelled():
    """A 5 cm wall between two step end points, both far clear of it, is still a hit."""
    c = cw({"id": "wall", "shape": "box", "size": [0.05, 10, 10], "position": C.tolist()})
    assert sweep(c, (-4, 0, 0), (4, 0, 0), r=0.1) == "wall"
    # The end points alone are clear of it.
    assert sweep(c, (-4, 0, 0), (-4, 0, 0), r=0.1) is None
    assert sweep(c, (4, 0, 0), (4, 0, 0), r=0.1) is None
    # Beside the wall's edge (y half 5): clear at 5 + r + eps, hit at 5 + r - eps.
    assert sweep(c, (-4, 5.1 + EPS, 0), (4, 5.1 + EPS, 0), r=0.1) is None
    assert sweep(c, (-4, 5.1 - EPS, 0), (4, 5.1 - EPS, 0), r=0.1) == "wall"


def test_names_the_body_hit_among_several():
    w = world_with(
        {"id": "s1", "shape": "sphere", "radius": 1.0, "position": (C + [-20, 0, 0]).tolist()},
        {"id": "s2", "shape": "sphere", "radius": 1.0, "position": C.tolist()},
        {"id": "b3", "shape": "box", "size": [2, 2, 2], "position": (C + [20, 0, 0]).tolist()},
    )
    c = CollisionWorld(w)
    assert c.sweep_static(C + [-5, -5, 0], C + [5, 5, 0], 0.5) == "s2"
    assert c.sweep_static(C + [20, -5, 0], C + [20, 5, 0], 0.5) == "b3"
    assert c.sweep_static(C + [-20, 0, 5], C + [-20, 0, 1.4], 0.5) == "s1"
    assert c.sweep_static(C + [-10, 0, 5], C + [10, 0, 5], 0.5) is None


# ----------------------------------------------------------------------------- meshes


@pytest.fixture
def box_mesh_file(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(2.0, 2.0, 2.0)).export(tmp_path / "cube.stl")
    return tmp_path


@pytest.mark.parametrize("eps, hit", [(-0.01, True), (0.01, False)])
def test_mesh_face_threshold(box_mesh_file, eps, hit):
    c = cw(
        {"id": "m", "shape": "mesh", "file": "cube.stl", "position": C.tolist()},
        tmp_path=box_mesh_file,
    )
    assert sweep(c, (-10, 2 + eps, 0.3), (10, 2 + eps, 0.3)) == ("m" if hit else None)


def test_mesh_thin_crossing_and_inside(box_mesh_file):
    c = cw(
        {"id": "m", "shape": "mesh", "file": "cube.stl", "position": C.tolist(), "scale": [0.025, 5, 5]},
        tmp_path=box_mesh_file,
    )
    # A 5 cm mesh wall crossed in one step.
    assert sweep(c, (-3, 0, 0), (3, 0, 0), r=0.1) == "m"
    assert sweep(c, (-3, 0, 0), (-0.2, 0, 0), r=0.1) is None


# ----------------------------------------------------------------------------- moving obstacles


def moving_world(velocity=(20, 0, 0), start=(-10, 0, 0), radius=1.0):
    return CollisionWorld(
        world_with(
            {
                "id": "mv",
                "shape": "sphere",
                "radius": radius,
                "position": (C + np.asarray(start, float)).tolist(),
                "motion": {"type": "linear", "velocity": list(velocity)},
            }
        )
    )


@pytest.mark.parametrize("eps, hit", [(-EPS, True), (EPS, False)])
def test_moving_sphere_sweeps_past_a_hovering_agent(eps, hit):
    c = moving_world()
    q0, q1 = (C + [-10, 0, 0])[None], (C + [10, 0, 0])[None]
    p = C + (2 + eps) * Y  # hovering beside the obstacle's path
    got = c.sweep_moving(p, p, 1.0, q0, q1)
    assert got == ("mv" if hit else None)
    # Only the step's end points would never see it.
    assert c.sweep_moving(p, p, 1.0, q1, q1) is None


def test_moving_obstacle_relative_motion():
    c = moving_world()
    q0, q1 = (C + [-10, 0, 0])[None], (C + [10, 0, 0])[None]
    # Flying alongside at the same velocity, 1.5 m apart centre to centre: overlapping, a hit.
    assert c.sweep_moving(C + [-10, 1.5, 0], C + [10, 1.5, 0], 1.0, q0, q1) == "mv"
    # Same velocity, 2.5 m apart: never closer than 2.5, clear.
    assert c.sweep_moving(C + [-10, 2.5, 0], C + [10, 2.5, 0], 1.0, q0, q1) is None
    # Heading for the obstacle's path, but still 5 m short of it when the obstacle passes.
    assert c.sweep_moving(C + [0, -10, 0], C + [0, -5, 0], 1.0, q0, q1) is None
    # Head-on: both cross the same point at mid-step.
    assert c.sweep_moving(C + [10, 0, 0], C + [-10, 0, 0], 1.0, q0, q1) == "mv"


def test_first_hit_orders_bounds_ground_static_moving():
    w = world_with(
        {"id": "s", "shape": "sphere", "radius": 1.0, "position": C.tolist()},
        {
            "id": "mv",
            "shape": "sphere",
            "radius": 1.0,
            "position": (C + [0, -10, 0]).tolist(),
            "motion": {"type": "linear", "velocity": [0, 0, 0]},
        },
    )
    c = CollisionWorld(w)
    q = (C + [0, -10, 0])[None]
    r = 1.0
    assert c.first_hit(C + [-5, 0, 0], C + [5, 0, 0], r, q, q) == "s"
    assert c.first_hit(C + [-5, -10, 0], C + [5, -10, 0], r, q, q) == "mv"
    assert c.first_hit(C + [-5, 5, 0], C + [5, 5, 0], r, q, q) is None
    # Ground: the sphere's bottom dips below z = 0 during the step.
    assert c.first_hit(np.array([20.0, 20, 5]), np.array([22.0, 20, 0.99]), r, q, q) == "ground"
    assert c.first_hit(np.array([20.0, 20, 5]), np.array([22.0, 20, 1.01]), r, q, q) is None
    # Bounds: the centre leaves the flight volume.
    assert c.first_hit(np.array([99.0, 50, 20]), np.array([100.5, 50, 20]), r, q, q) == "bounds"


def test_terrain_is_swept_not_sampled_at_end_points():
    raw = base_world(
        terrain={"peaks": [{"center": [50, 20], "height": 15, "spread": [3, 3]}], "clearance": 1}
    )
    c = CollisionWorld(make_world(raw))
    # A narrow 15 m peak between two end points at 10 m: the straight step goes through it.
    assert c.sweep_terrain(np.array([40.0, 20, 10]), np.array([60.0, 20, 10]), 1.0) == "terrain"
    assert c.sweep_terrain(np.array([40.0, 20, 17]), np.array([60.0, 20, 17]), 1.0) is None


# ----------------------------------------------------------------------------- agents


def test_segment_segment_min_distance_closed_form():
    p0, p1 = np.array([[0.0, 0, 0]]), np.array([[2.0, 0, 0]])
    q0, q1 = np.array([[2.0, 1, 0]]), np.array([[0.0, 1, 0]])
    # Swap places passing 1 m apart at mid-step.
    assert segment_segment_min_distance(p0, p1, q0, q1)[0] == pytest.approx(1.0)
    # Parallel, same velocity: constant separation.
    assert segment_segment_min_distance(p0, p1, p0 + [0, 3, 0], p1 + [0, 3, 0])[0] == pytest.approx(3.0)
    # Diverging from the start: the minimum is at s = 0.
    assert segment_segment_min_distance(p0, -p1, q0, q1 + [4, 0, 0])[0] == pytest.approx(math.hypot(2, 1))
    # Converging but not yet met at s = 1: the minimum is at the end.
    d = segment_segment_min_distance(
        np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), q0 + [8, 0, 0], q0 + [6, 0, 0]
    )
    assert d[0] == pytest.approx(math.hypot(7, 1))


def test_agent_contacts_catch_a_swap_within_one_step():
    p0 = np.array([[0.0, 0, 10], [10, 0.5, 10], [50, 50, 10]])
    p1 = np.array([[10.0, 0, 10], [0, 0.5, 10], [50, 50, 10]])
    radii = np.array([1.0, 1.0, 1.0])
    active = np.array([True, True, True])
    # End points are 10 m apart, yet they pass 0.5 m apart mid-step.
    assert agent_contacts(p0, p1, radii, active) == [(0, 1)]
    # Exact threshold on the radii sum: 2 m apart is not contact, 1.999 is.
    p0b, p1b = p0.copy(), p1.copy()
    p0b[1, 1] = p1b[1, 1] = 2.0 + EPS
    assert agent_contacts(p0b, p1b, radii, active) == []
    p0b[1, 1] = p1b[1, 1] = 2.0 - EPS
    assert agent_contacts(p0b, p1b, radii, active) == [(0, 1)]
    # The margin inflates the bodies.
    p0b[1, 1] = p1b[1, 1] = 2.1
    assert agent_contacts(p0b, p1b, radii, active, margin=0.2) == [(0, 1)]
    # Two inactive (arrived) agents never collide with each other, but still count as bodies.
    assert agent_contacts(p0, p1, radii, np.array([False, False, True])) == []
    assert agent_contacts(p0, p1, radii, np.array([True, False, False])) == [(0, 1)]
