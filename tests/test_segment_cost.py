"""SegmentCost's compiled kernel (culled per leg, sphere-traced along it) equals the brute
force: every sample against every intent and body, in numpy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmplan.planner.segment_cost import Flyer, Intent, SegmentCost, SegmentEncoding
from swarmplan.world import parse_world


def _world():
    return parse_world(
        {
            "name": "t",
            "bounds": {"min": [0, 0, 0], "max": [200, 200, 60]},
            "agent_defaults": {"radius": 1.0},
            "agents": [{"id": "a", "start": [10, 10, 20], "goal": [190, 190, 20]}],
        }
    )


def _random_intents(rng: np.random.Generator, count: int, t0: float) -> list[Intent]:
    """Stationary agents, straight and multi-leg routes, all inside the 100 m box the candidates fly in."""
    out = []
    for _ in range(count):
        m = int(rng.integers(1, 6))
        pts = rng.uniform([40, 40, 10], [140, 140, 40], (m, 3))
        times = t0 + np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 6.0, m - 1))])
        out.append(Intent(times, pts, float(rng.uniform(0.5, 1.5)), rng.uniform(1, 6, 3)))
    # A jump: two knots at one time (no speed bound, so no tracing past it).
    pts = rng.uniform([40, 40, 10], [140, 140, 40], (3, 3))
    out.append(Intent(t0 + np.array([0.0, 2.0, 2.0]), pts, 1.0, np.array([3.0, 3.0, 2.0])))
    return out


def _population(rng: np.random.Generator, n: int, k: int = 3):
    enc = SegmentEncoding(np.array([50.0, 50, 20]), np.array([130.0, 120, 30]), k, width=40, height=20)
    X = rng.uniform(enc.lower, enc.upper, (n, enc.dim))
    return enc.decode(X)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("crowd", [40, 4])
def test_culled_agent_term_equals_brute_force_on_random_populations(seed, crowd):
    """Crowded (every candidate meets somebody) and sparse (tracing skips most samples)."""
    rng = np.random.default_rng(seed)
    t0 = float(rng.uniform(0, 50))
    cost = SegmentCost(
        _world(),
        Flyer(radius=1.0, speed=float(rng.uniform(3, 12)), turn_radius=5.0, max_climb=0.8, min_altitude=3.0),
        t0=t0,
        intents=_random_intents(rng, crowd, t0 - float(rng.uniform(0, 3))),
    )
    P = _population(rng, 30)
    pts, ds, s = cost.sample(P)
    ref = cost.agent_penalty_reference(pts, ds, s)
    # Both branches are exercised: candidates that meet somebody, and (sparse) some that do not.
    assert (ref > 0).sum() >= (10 if crowd > 10 else 1)
    assert crowd > 10 or (ref == 0).sum() >= 1
    np.testing.assert_allclose(cost.terms(P)["agents"], ref, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("inside", [True, False])
def test_culling_keeps_an_agent_just_within_reach(inside):
    """An agent that stays just inside (outside) the reach of one sample must (must not) cost:
    a cull that drops intents a little too early fails the first case."""
    sep = np.array([3.0, 3.0, 2.0])
    r, radius = 1.0, 1.0
    reach = 1.2 * float((sep + r + radius).max())  # 6 m, along x or y
    start, end = np.array([0.0, 0.0, 20.0]), np.array([40.0, 0.0, 20.0])
    P = np.stack([start, end])[None]
    gap = reach - 1e-3 if inside else reach + 1e-3
    # A stationary agent beside the midpoint of the straight leg and a moving one that meets
    # the candidate's sample only at the time the candidate passes by.
    # Samples at 0.5 m spacing sit at x = 0.25 + 0.5 k, so x = 20.25 and 30.25 are samples.
    still = Intent(np.array([0.0]), np.array([[20.25, gap, 20.0]]), radius, sep)
    speed = 8.0
    t_pass = 30.25 / speed
    mover = Intent(
        np.array([t_pass - 2.0, t_pass, t_pass + 2.0]),
        np.array([[30.25, -gap - 16.0, 20.0], [30.25, -gap, 20.0], [30.25, -gap - 16.0, 20.0]]),
        radius,
        sep,
    )
    for it in (still, mover):
        cost = SegmentCost(
            _world(),
            Flyer(radius=r, speed=speed, turn_radius=5.0, max_climb=0.8, min_altitude=3.0),
            intents=[it],
        )
        cost.spacing = 0.5
        pts, ds, s = cost.sample(P)
        ref = cost.agent_penalty_reference(pts, ds, s)
        fast = cost.terms(P)["agents"]
        assert (ref[0] > 0) == inside
        np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=0)


def test_culling_drops_only_far_agents():
    """Agents far in space, or near the path only at other times, cost nothing; one crossing
    the path when the candidate is there costs the collision weight."""
    sep = np.array([3.0, 3.0, 2.0])
    speed = 10.0
    P = np.array([[[0.0, 0.0, 20.0], [100.0, 0.0, 20.0]]])
    far = Intent(np.array([0.0]), np.array([[50.0, 80.0, 20.0]]), 1.0, sep)
    # Cross the line at x = 50 at t = 0 (early) or t = 10 (late) while the candidate gets there at t = 5 s.
    early = Intent(np.array([-5.0, 5.0]), np.array([[50.0, -50.0, 20.0], [50.0, 50.0, 20.0]]), 1.0, sep)
    late = Intent(np.array([5.0, 15.0]), np.array([[50.0, -50.0, 20.0], [50.0, 50.0, 20.0]]), 1.0, sep)
    crossing = Intent(np.array([0.0, 10.0]), np.array([[50.0, -50.0, 20.0], [50.0, 50.0, 20.0]]), 1.0, sep)
    for it, positive in ((far, False), (early, False), (crossing, True), (late, False)):
        cost = SegmentCost(
            _world(),
            Flyer(radius=1.0, speed=speed, turn_radius=5.0, max_climb=0.8, min_altitude=3.0),
            intents=[it],
        )
        pts, ds, s = cost.sample(P)
        ref = cost.agent_penalty_reference(pts, ds, s)
        np.testing.assert_allclose(cost.terms(P)["agents"], ref, rtol=1e-12, atol=0)
        assert (ref[0] > 0) == positive


def _cluttered_world(rng: np.random.Generator):
    obstacles = []
    for k in range(16):
        shape = ("sphere", "box", "cylinder", "capsule")[k % 4]
        o = {"id": f"o{k}", "shape": shape, "position": rng.uniform([40, 40, 5], [140, 140, 40]).tolist()}
        if shape == "box":
            o["size"] = rng.uniform(2, 12, 3).tolist()
            o["rotation"] = [0, 0, float(rng.uniform(0, 90))]
        else:
            o["radius"] = float(rng.uniform(1, 6))
        if shape in ("cylinder", "capsule"):
            o["height"] = float(rng.uniform(4, 30))
        if k >= 8:
            o["motion"] = {"type": "linear", "velocity": rng.normal(0, 3, 3).tolist()}
        obstacles.append(o)
    return parse_world(
        {
            "name": "t",
            "bounds": {"min": [0, 0, 0], "max": [200, 200, 60]},
            "agent_defaults": {"radius": 1.0, "min_altitude": 3},
            "obstacles": obstacles,
            "agents": [{"id": "a", "start": [10, 10, 20], "goal": [190, 190, 20]}],
        }
    )


@pytest.mark.parametrize("seed", range(4))
def test_culled_obstacle_terms_equal_brute_force(seed):
    """Static and moving terms (culled, batched by shape) equal every point against every body."""
    from swarmplan.geometry.shapes import ObstacleField
    from swarmplan.world.motion import poses_at

    rng = np.random.default_rng(seed)
    world = _cluttered_world(rng)
    cost = SegmentCost(
        world,
        Flyer(radius=1.0, speed=6.0, turn_radius=5.0, max_climb=0.8, min_altitude=3.0),
        t0=2.0,
        margin=2.0,
    )
    P = _population(rng, 30)
    pts, ds, s = cost.sample(P)
    flat = pts.reshape(-1, 3)
    d = ObstacleField(cost.static).query(flat)[0].min(axis=1).reshape(pts.shape[:2])
    req = cost._required(s)
    static = cost.w.clearance * (np.maximum(req - d, 0) * ds).sum(1) + cost.w.collision * (
        (d < cost.r) * ds
    ).sum(1)
    assert (static > 0).sum() >= 5
    np.testing.assert_allclose(cost.static_penalty(pts, ds, s), static, rtol=1e-12, atol=1e-9)
    terms = cost.terms(P)
    np.testing.assert_allclose(terms["static"], static, rtol=1e-12, atol=1e-9)
    # Moving bodies at their predicted centres on the 0.2 s grid, every point against every body.
    k = np.round((s / cost.speed) / 0.2).astype(int).reshape(-1)
    moving = np.zeros(len(P))
    for o in cost.moving:
        dj = np.empty(len(flat))
        for kk in np.unique(k):
            at = k == kk
            dj[at] = ObstacleField([o]).query(flat[at], poses_at([o], cost.t0 + kk * 0.2)[0])[0][:, 0]
        dj = dj.reshape(pts.shape[:2])
        moving += cost.w.moving * (np.maximum(cost.required - dj, 0) * ds).sum(1)
        moving += cost.w.collision * ((dj < cost.r) * ds).sum(1)
    assert (moving > 0).sum() >= 1
    np.testing.assert_allclose(cost.moving_penalty(pts, ds, s), moving, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(terms["moving"], moving, rtol=1e-12, atol=1e-9)
    vd = ObstacleField(cost.static).query(P[:, 1:-1].reshape(-1, 3))[0].min(axis=1).reshape(len(P), -1)
    cost.vertex_clearance = 3.0
    vertex = cost.w.vertex * np.maximum(3.0 - (vd - cost.r), 0).sum(1)
    assert (vertex > 0).sum() >= 1
    np.testing.assert_allclose(cost.vertex_penalty(P), vertex, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cost.terms(P)["vertices"], vertex, rtol=1e-12, atol=1e-12)


def _brute_force_obstacles(cost: SegmentCost, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Static and moving terms with every sample against every body (no culling, no tracing),
    and whether each candidate has a sample inside the agent's radius of something."""
    from swarmplan.geometry.shapes import ObstacleField
    from swarmplan.world.motion import poses_at

    pts, ds, s = cost.sample(P)
    flat = pts.reshape(-1, 3)
    d = ObstacleField(cost.static).query(flat)[0].min(axis=1).reshape(pts.shape[:2])
    req = cost._required(s)
    static = cost.w.clearance * (np.maximum(req - d, 0) * ds).sum(1) + cost.w.collision * (
        (d < cost.r) * ds
    ).sum(1)
    hit = (d < cost.r).any(axis=1)
    k = np.round((s / cost.speed) / 0.2).astype(int).reshape(-1)
    moving = np.zeros(len(P))
    for o in cost.moving:
        dj = np.empty(len(flat))
        for kk in np.unique(k):
            at = k == kk
            dj[at] = ObstacleField([o]).query(flat[at], poses_at([o], cost.t0 + kk * 0.2)[0])[0][:, 0]
        dj = dj.reshape(pts.shape[:2])
        moving += cost.w.moving * (np.maximum(cost.required - dj, 0) * ds).sum(1)
        moving += cost.w.collision * ((dj < cost.r) * ds).sum(1)
        hit |= (dj < cost.r).any(axis=1)
    return static, moving, hit


def _thin_world(rng: np.random.Generator):
    """Many small bodies (thinner than the sample spacing is long) strewn over the
    candidates' box, some rotated, some moving fast: where tracing could skip a hit."""
    obstacles = []
    for k in range(60):
        shape = ("sphere", "box", "cylinder", "capsule")[k % 4]
        o = {"id": f"o{k}", "shape": shape, "position": rng.uniform([45, 45, 10], [135, 125, 40]).tolist()}
        if shape == "box":
            o["size"] = rng.uniform(0.05, 1.0, 3).tolist()
            o["rotation"] = rng.uniform(0, 90, 3).tolist()
        else:
            o["radius"] = float(rng.uniform(0.02, 0.4))
        if shape in ("cylinder", "capsule"):
            o["height"] = float(rng.uniform(0.1, 20))
            o["rotation"] = [float(rng.uniform(0, 90)), 0, 0]
        if k % 5 == 0:
            o["motion"] = {"type": "linear", "velocity": rng.normal(0, 6, 3).tolist()}
        obstacles.append(o)
    return parse_world(
        {
            "name": "thin",
            "bounds": {"min": [0, 0, 0], "max": [200, 200, 60]},
            "agent_defaults": {"radius": 0.3, "min_altitude": 3},
            "obstacles": obstacles,
            "agents": [{"id": "a", "start": [10, 10, 20], "goal": [190, 190, 20]}],
        }
    )


@pytest.mark.parametrize("seed", range(6))
def test_tracing_never_skips_a_sample_the_brute_force_counts(seed):
    """Thin bodies between samples' reach and a small agent: the kernel's skipped samples must
    all be ones that add nothing, so its terms equal every-sample-against-every-body, and
    every candidate the brute force finds in collision costs the collision weight."""
    rng = np.random.default_rng(100 + seed)
    world = _thin_world(rng)
    cost = SegmentCost(
        world,
        Flyer(radius=0.3, speed=float(rng.uniform(3, 12)), turn_radius=5.0, max_climb=0.8, min_altitude=3.0),
        t0=float(rng.uniform(0, 5)),
        margin=float(rng.uniform(0.1, 1.5)),
        start_clearance=float(rng.uniform(0, 2)),
    )
    P = _population(rng, 40)
    static, moving, hit = _brute_force_obstacles(cost, P)
    assert hit.sum() >= 3 and (~hit).sum() >= 1
    terms = cost.terms(P)
    np.testing.assert_allclose(terms["static"], static, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(terms["moving"], moving, rtol=1e-12, atol=1e-9)
    assert np.all(terms["static"][hit] + terms["moving"][hit] > 0)


def test_floor_bounds_turning_and_length_equal_numpy():
    """The kernel's per-polyline terms equal the numpy ones, for populations partly outside
    the bounds and below the floor, with a heading (multirotor and fixed wing)."""
    rng = np.random.default_rng(7)
    for fixed_wing in (False, True):
        cost = SegmentCost(
            _world(),
            Flyer(
                radius=1.0,
                speed=7.0,
                turn_radius=12.0,
                max_climb=0.4,
                min_altitude=8.0,
                fixed_wing=fixed_wing,
            ),
            heading=np.array([1.0, -0.3, 0.1]),
        )
        enc = SegmentEncoding(np.array([20.0, 170, 14]), np.array([120.0, 185, 50]), 4, width=30, height=10)
        P = enc.decode(rng.uniform(enc.lower, enc.upper, (50, enc.dim)))
        P[3, 2] = P[3, 1]  # a zero-length leg
        pts, ds, _ = cost.sample(P)
        ref = cost.floor_bounds_penalty(pts, ds)
        assert (ref > 0).sum() >= 10 and (ref == 0).sum() >= 1
        terms = cost.terms(P)
        np.testing.assert_allclose(terms["floor_bounds"], ref, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(terms["turning"], cost.turning(P), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(terms["length"], cost.length(P), rtol=1e-14, atol=0)
        total = sum(
            terms[k]
            for k in (
                "length",
                "turning",
                "static",
                "vertices",
                "floor_bounds",
                "threats",
                "moving",
                "agents",
            )
        )
        np.testing.assert_allclose(cost(P), total, rtol=1e-14, atol=0)


def test_meshes_terrain_and_threats_take_the_numpy_terms():
    """What the kernel does not measure (a mesh's distance grid, terrain peaks, threats) comes
    from the numpy terms: the whole cost equals the reference terms."""
    import yaml

    worlds = Path(__file__).resolve().parents[1] / "worlds"
    raw = yaml.safe_load((worlds / "mesh_hangar.yaml").read_text())
    raw["terrain"] = {"peaks": [{"center": [120, 100], "height": 6, "spread": [30, 30]}]}
    raw["threats"] = [{"kind": "radar", "position": [110, 80, 15], "r_min": 5, "r_max": 25}]
    world = parse_world(raw, base_dir=worlds)
    rng = np.random.default_rng(3)
    cost = SegmentCost(
        world, Flyer(radius=1.0, speed=6.0, turn_radius=5.0, max_climb=0.8, min_altitude=3.0), t0=1.0
    )
    cost.vertex_clearance = 2.0
    enc = SegmentEncoding(np.array([60.0, 60, 12]), np.array([180.0, 140, 20]), 4, width=50, height=15)
    P = enc.decode(rng.uniform(enc.lower, enc.upper, (30, enc.dim)))
    ref = cost.terms_reference(P)
    assert (ref["static"] > 0).sum() >= 3 and (ref["floor_bounds"] > 0).sum() >= 1
    terms = cost.terms(P)
    for name, value in ref.items():
        np.testing.assert_allclose(terms[name], value, rtol=1e-12, atol=1e-9, err_msg=name)


def test_decode_is_the_frame_formula():
    """The compiled decoder equals ``base + offsets @ frame``, clipped, between start and end."""
    rng = np.random.default_rng(1)
    lo, hi = np.array([0.0, 0, 5]), np.array([150.0, 150, 45])
    enc = SegmentEncoding(
        np.array([50.0, 50, 20]), np.array([130.0, 120, 30]), 3, width=60, height=30, lo=lo, hi=hi
    )
    X = rng.uniform(enc.lower, enc.upper, (25, enc.dim))
    P = enc.decode(X)
    wp = np.clip(enc.base[None] + X.reshape(25, 3, 3) @ enc.frame, lo, hi)
    np.testing.assert_allclose(P[:, 1:-1], wp, rtol=0, atol=1e-12)
    assert np.all(P[:, 0] == enc.start) and np.all(P[:, -1] == enc.end)
    assert (wp == hi).any() or (wp == lo).any()  # some waypoints were clipped
