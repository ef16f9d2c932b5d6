"""Escape planning: the segment cost on exact geometry, FCL validation and retries, determinism."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from helpers import base_world, make_world, without_guide

from swarmplan.core import Mode, PlannedSegment
from swarmplan.planner import RefinementPlanner
from swarmplan.planner.escape import EscapePlanner, choose_subgoal
from swarmplan.planner.segment_cost import Flyer, SegmentCost, SegmentEncoding
from swarmplan.sim import Simulation
from swarmplan.world import WorldError

TRAPS = Path(__file__).resolve().parents[1] / "worlds" / "traps"
SPHERE = {"id": "ball", "shape": "sphere", "radius": 5.0, "position": [50, 50, 25]}


def cost_for(world, **kw) -> SegmentCost:
    """A cost for a 1 m multirotor at 8 m/s; ``kw``: the flyer's fields or the cost's settings."""
    flyer = Flyer(radius=1.0, speed=8.0, turn_radius=16.0, max_climb=np.radians(45), min_altitude=5.0)
    fields = {k: kw.pop(k) for k in list(kw) if k in Flyer.__dataclass_fields__}
    return SegmentCost(world, replace(flyer, **fields), **kw)


def test_straight_free_segment_costs_exactly_its_length():
    world = make_world(base_world(obstacles=[SPHERE]))
    cost = cost_for(world)
    P = np.array([[[10.0, 10.0, 20.0], [20.0, 15.0, 20.0], [30.0, 20.0, 20.0], [40.0, 25.0, 20.0]]])
    length = float(np.linalg.norm(P[0, -1] - P[0, 0]))
    terms = cost.terms(P)
    assert terms["length"][0] == pytest.approx(length, rel=1e-12)
    for k, v in terms.items():
        if k != "length":
            assert v[0] == 0.0, k
    assert cost(P)[0] == pytest.approx(length, rel=1e-12)


def test_segment_through_a_sphere_is_penalized_by_the_length_inside():
    world = make_world(base_world(obstacles=[SPHERE]))
    cost = cost_for(world)
    through = np.array([[[30.0, 50.0, 25.0], [70.0, 50.0, 25.0]]])
    beside = through + np.array([0.0, 20.0, 0.0])
    c_through, c_beside = cost(through)[0], cost(beside)[0]
    assert c_beside == pytest.approx(40.0)
    # Inside the sphere for 10 m (closer than the radius for 12 m): at least the collision weight.
    assert c_through > 40.0 + cost.w.collision * 11.0
    # Vectorized: one call scores both, identically.
    np.testing.assert_allclose(cost(np.concatenate([through, beside])), [c_through, c_beside])


def test_turning_penalizes_corners_tighter_than_the_turn_radius():
    world = make_world(base_world())
    cost = cost_for(world, turn_radius=20.0)
    wide = np.array([[[10.0, 10, 20], [50.0, 10, 20], [50.0, 50, 20]]])  # legs 40 m, fillet tangent 20
    tight = np.array([[[10.0, 10, 20], [20.0, 10, 20], [20.0, 20, 20]]])  # legs 10 m
    t_wide = cost.turning(wide)[0]
    t_tight = cost.turning(tight)[0]
    assert t_wide == pytest.approx(cost.w.turn * np.pi / 2)
    assert t_tight == pytest.approx(cost.w.turn * np.pi / 2 + cost.w.turn_radius * (20.0 - 5.0))


def test_encoding_zero_offsets_is_the_straight_line_and_roundtrips():
    enc = SegmentEncoding(np.array([0.0, 0, 10]), np.array([40.0, 0, 10]), 3, width=10, height=5)
    P = enc.decode(np.zeros((1, enc.dim)))[0]
    np.testing.assert_allclose(P[:, 0], [0, 10, 20, 30, 40])
    x = np.array([1.0, 2.0, -1.0, 0.0, -3.0, 2.0, 0.5, 0.5, 0.5])
    np.testing.assert_allclose(enc.encode(enc.decode(x[None])[0, 1:-1]), x)


def test_moving_obstacle_is_avoided_at_its_predicted_position():
    mover = dict(SPHERE, id="m", position=[50, 10, 25], motion={"type": "linear", "velocity": [0, 8, 0]})
    world = make_world(base_world(obstacles=[mover]))
    cost = cost_for(world, speed=8.0, t0=0.0)
    # The agent reaches x = 50 after 5 s at 8 m/s, when the mover has come to y = 50.
    P = np.array([[[10.0, 50.0, 25.0], [90.0, 50.0, 25.0]]])
    assert cost.terms(P)["moving"][0] > 0
    later = cost_for(world, speed=8.0, t0=20.0)  # long gone by then
    assert later.terms(P)["moving"][0] == 0.0


def _pocket_sim(optimizer="de"):
    from swarmplan.world import load_world

    world = without_guide(load_world(TRAPS / "u_pocket.yaml"))  # the guide would lead it out
    planner = RefinementPlanner(world, optimizer)
    sim = Simulation(world, planner=planner)
    sim.reset(seed=3)
    sim.state.position[0] = np.array([54.0, 40.0, 15.0])  # deep in the pocket
    sim.state.velocity[0] = np.zeros(3)
    return sim, planner


def test_subgoal_lies_past_the_blocking_wall():
    sim, _ = _pocket_sim()
    g = choose_subgoal(sim, 0, 10.0, 3.0)
    assert g[0] > 64.0 + 3.0  # beyond the back wall (x 60..64) with the clearance asked for
    np.testing.assert_allclose(g[1:], [40.0, 15.0])


def test_escape_out_of_the_pocket_is_valid_and_recorded():
    sim, planner = _pocket_sim()
    out = planner.on_stuck(sim, 0)
    assert isinstance(out, PlannedSegment) and out.mode == "escape"
    poly = np.vstack([sim.state.position[0], out.waypoints])
    assert planner.escape.segment_hit(sim, 0, poly, 1.0) is None
    assert sim.metrics.optimizer_runs[0] >= 1
    assert len(sim.metrics.escape_ms[0]) == sim.metrics.optimizer_runs[0]


def test_fcl_rejection_triggers_a_retry_with_a_larger_horizon_and_budget(monkeypatch):
    sim, planner = _pocket_sim()
    calls = []
    real_hit = EscapePlanner.segment_hit
    real_opt = EscapePlanner.optimize_segment

    def fake_hit(self, sim, i, poly, c0):
        calls.append("hit")
        return "back" if calls.count("hit") == 1 else real_hit(self, sim, i, poly, c0)

    widths = []

    def spy_opt(self, sim, i, end, purpose, width, budget_factor=1.0, *a, **k):
        widths.append((width, budget_factor))
        return real_opt(self, sim, i, end, purpose, width, budget_factor, *a, **k)

    monkeypatch.setattr(EscapePlanner, "segment_hit", fake_hit)
    monkeypatch.setattr(EscapePlanner, "optimize_segment", spy_opt)
    out = planner.on_stuck(sim, 0)
    assert isinstance(out, PlannedSegment)
    assert len(widths) >= 2
    assert widths[1][0] > widths[0][0] and widths[1][1] > widths[0][1]
    assert sim.metrics.optimizer_runs[0] == len(widths)


def test_every_attempt_rejected_holds_then_searches_wider(monkeypatch):
    sim, planner = _pocket_sim()
    monkeypatch.setattr(EscapePlanner, "segment_hit", lambda *a: "back")
    widths = []
    real_opt = EscapePlanner.optimize_segment

    def spy_opt(self, sim, i, end, purpose, width, budget_factor=1.0, *a, **k):
        widths.append((width, budget_factor))
        return real_opt(self, sim, i, end, purpose, width, budget_factor, *a, **k)

    monkeypatch.setattr(EscapePlanner, "optimize_segment", spy_opt)
    rounds = planner.escape.cfg["rounds"]
    attempts = 1 + planner.escape.cfg["retries"]
    # Each round but the last defers (the agent holds on under APF and is asked again) ...
    for r in range(1, rounds):
        assert planner.on_stuck(sim, 0) is None
        kind, detail = [(e.kind, e.detail) for e in sim.records.events][-1]
        assert kind == "escape_deferred" and detail["round"] == r and detail["attempts"] == attempts
        assert detail["held_by"]["by"] in ("ground", "bounds", "body", "agent", "none")
    # ... and the last does not give up: the multirotor hovers where it is, and says why.
    out = planner.on_stuck(sim, 0)
    assert isinstance(out, PlannedSegment) and out.mode == Mode.ESCAPE
    np.testing.assert_allclose(out.waypoints, [sim.state.position[0]])
    kind, detail = [(e.kind, e.detail) for e in sim.records.events][-1]
    assert kind == "hold" and detail["possible"] and detail["round"] == 1
    assert f"in {rounds} rounds" in detail["reason"]
    assert sim.metrics.optimizer_runs[0] == rounds * attempts
    # Asked again after holding, it searches wider (horizon and budget times growth).
    before = len(widths)
    assert planner.on_stuck(sim, 0) is None
    growth = planner.escape.cfg["growth"]
    assert widths[before][1] == pytest.approx(growth * widths[0][1])


def test_a_fixed_wing_with_no_room_anywhere_flies_on_and_plans_again(monkeypatch):
    sim, planner = _pocket_sim()
    monkeypatch.setattr(EscapePlanner, "segment_hit", lambda *a: "back")
    sim.params.fixed_wing[0] = True  # every loiter circle and every way to free volume is 'blocked'
    for _ in range(planner.escape.cfg["rounds"] - 1):
        assert planner.on_stuck(sim, 0) is None
    assert planner.on_stuck(sim, 0) is None  # never 'failed': on under the field
    kind, detail = [(e.kind, e.detail) for e in sim.records.events][-1]
    assert kind == "hold" and detail["possible"] is False


def test_a_fixed_wing_with_no_loiter_circle_flies_to_the_clearest_free_point(monkeypatch):
    from swarmplan.planner.escape import static_clearance
    from swarmplan.planner.hold import FREE_CLIMBS, FREE_HEADINGS, LOITER_FACTORS

    sim, planner = _pocket_sim()
    sim.params.fixed_wing[0] = True
    sim.params.min_turn_radius[0] = 5.0  # its points (24 m off) are within the 120 x 80 x 30 m volume
    reach = 2.0 * LOITER_FACTORS[-1] * float(sim.params.min_turn_radius[0])

    def only_free_volume_open(self, sim, i, poly, start_clearance):
        # Escapes and loiter circles are 'blocked'; ways to a point a loiter's diameter off are free.
        return None if np.isclose(np.linalg.norm(poly[-1] - poly[0]), reach, rtol=1e-9) else "back"

    monkeypatch.setattr(EscapePlanner, "segment_hit", lambda *a: "back")
    for _ in range(planner.escape.cfg["rounds"] - 1):
        assert planner.on_stuck(sim, 0) is None
    from swarmplan.planner.escape import EscapeOutcome

    monkeypatch.setattr(EscapePlanner, "plan", lambda *a, **k: EscapeOutcome(None, 1, []))  # no escape
    monkeypatch.setattr(EscapePlanner, "segment_hit", only_free_volume_open)
    out = planner.on_stuck(sim, 0)
    assert isinstance(out, PlannedSegment) and out.mode == Mode.ESCAPE
    kind, detail = [(e.kind, e.detail) for e in sim.records.events][-1]
    assert kind == "hold" and detail["possible"] and detail["free_volume"]
    # Its end is the clearest of the candidate points: no other is clearer.
    p = sim.state.position[0]
    np.testing.assert_allclose(np.linalg.norm(out.waypoints[-1] - p), reach, rtol=1e-9)
    psi = np.arange(FREE_HEADINGS) * 2 * np.pi / FREE_HEADINGS
    g = np.array(FREE_CLIMBS)[:, None] * float(sim.params.max_climb[0])
    up = np.broadcast_to(np.sin(g), (len(g), len(psi)))
    u = np.stack([np.cos(g) * np.cos(psi), np.cos(g) * np.sin(psi), up], -1)
    r = float(sim.params.radius[0])
    best = static_clearance(sim, (p + reach * u).reshape(-1, 3), r).max()
    assert static_clearance(sim, out.waypoints[-1], r)[0] == pytest.approx(best)


def test_same_seed_same_run():
    from swarmplan.world import load_world

    world = without_guide(load_world(TRAPS / "goal_beside_obstacle.yaml"))  # with it: no escape

    def run(seed):
        sim = Simulation(world, planner=RefinementPlanner(world, "pso"))
        sim.reset(seed=seed)
        traj = []
        while True:
            r = sim.step()
            traj.append(sim.state.position.copy())
            if r.terminated or r.truncated:
                return np.array(traj), sim.summary()

    a, sa = run(5)
    b, sb = run(5)
    np.testing.assert_array_equal(a, b)
    assert sa["success"] and sa["agents"][0]["escapes"] >= 1
    for key in ("arrived", "collisions", "steps"):
        assert sa[key] == sb[key]


def test_unknown_escape_setting_is_an_error_of_the_world_file():
    with pytest.raises(WorldError, match="did you mean 'horizon'") as exc:
        make_world(base_world(planner={"escape": {"horizn": 5, "retries": -1}}))
    assert [p.split(":")[0] for p in exc.value.problems] == [
        "planner.escape.horizn",
        "planner.escape.retries",
    ]


def test_culling_leaves_the_static_and_moving_terms_exactly_unchanged():
    """The terms skip bodies (and points) out of reach; on random polylines among boxes,
    cylinders, spheres and movers they must equal the brute-force sums over every body."""
    from swarmplan.geometry.shapes import ObstacleField, distance_and_gradient
    from swarmplan.world.motion import poses_at

    obstacles = [
        {"id": "b1", "shape": "box", "size": [8, 4, 30], "position": [30, 40, 15], "rotation": [0, 0, 30]},
        {"id": "c1", "shape": "cylinder", "radius": 4, "height": 30, "position": [60, 60, 15]},
        SPHERE,
        {"id": "far", "shape": "box", "size": [2, 2, 2], "position": [95, 5, 45]},
        dict(
            SPHERE,
            id="m1",
            radius=3.0,
            position=[20, 80, 20],
            motion={"type": "linear", "velocity": [2, -3, 0]},
        ),
        dict(
            SPHERE,
            id="m2",
            radius=2.0,
            position=[70, 30, 20],
            motion={"type": "circle", "center": [60, 30, 20], "radius": 10, "angular_speed": 0.3},
        ),
    ]
    world = make_world(base_world(obstacles=obstacles))
    cost = cost_for(world, margin=3.0, t0=1.0)
    rng = np.random.default_rng(0)
    P = rng.uniform([5, 5, 6], [95, 95, 44], size=(40, 5, 3))
    pts, ds, s = cost.sample(P)
    n, S, _ = pts.shape
    # Brute force: every static body at every point ...
    d = ObstacleField(cost.static).query(pts.reshape(-1, 3))[0].min(axis=1).reshape(n, S)
    req = cost._required(s)
    static = cost.w.clearance * (np.maximum(req - d, 0) * ds).sum(1) + cost.w.collision * (
        (d < cost.r) * ds
    ).sum(1)
    # ... and every mover where the agent would meet it (same 0.2 s time grid as the term).
    k = np.round((s / cost.speed) / 0.2).astype(int).reshape(-1)
    moving = np.zeros(n)
    for o in cost.moving:
        centers = np.array([poses_at([o], cost.t0 + kk * 0.2)[0][0] for kk in k])
        dm = distance_and_gradient(o, pts.reshape(-1, 3) - centers + o.position)[0].reshape(n, S)
        moving += cost.w.moving * (np.maximum(cost.required - dm, 0) * ds).sum(1)
        moving += cost.w.collision * ((dm < cost.r) * ds).sum(1)
    assert np.any(static > 0) and np.any(static == 0) and np.any(moving > 0)
    np.testing.assert_allclose(cost.static_penalty(pts, ds, s), static, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cost.moving_penalty(pts, ds, s), moving, rtol=0, atol=1e-9)
