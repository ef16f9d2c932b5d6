"""Escape planning with moving obstacles at their predicted poses (swarmplan.planner.movers),
and the run's seed reaching the escape optimizer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import base_world, make_world, read_log, without_guide

from swarmplan.cli.run import main as run_main
from swarmplan.io.runner import apply_overrides, simulate
from swarmplan.planner.escape import choose_subgoal, mover_leg_hit
from swarmplan.planner.movers import EscapeClock, moving_clearance, positions_at
from swarmplan.planner.segment_cost import Flyer, SegmentCost
from swarmplan.sim import Simulation
from swarmplan.world import load_world
from swarmplan.world.motion import pose_at

ROOT = Path(__file__).resolve().parents[1]

# A plug (4 x 36 x 40 box) drives south along x = 62 at 8 m/s and parks at y = 40 at t = 4.5 s.
PLUG = {
    "id": "plug",
    "shape": "box",
    "size": [4, 36, 40],
    "position": [62, 76, 15],
    "motion": {"type": "waypoints", "waypoints": [[62, 40, 15]], "speed": 8, "loop": False},
}
MOVERS = [
    PLUG,
    {
        "id": "lin",
        "shape": "sphere",
        "radius": 2.0,
        "position": [10, 10, 20],
        "motion": {"type": "linear", "velocity": [1, 2, 0]},
    },
    {
        "id": "loop",
        "shape": "cylinder",
        "radius": 1.0,
        "height": 4.0,
        "position": [30, 30, 20],
        "motion": {"type": "waypoints", "waypoints": [[60, 30, 20], [60, 60, 20]], "speed": 5, "loop": True},
    },
    {
        "id": "circ",
        "shape": "sphere",
        "radius": 1.5,
        "position": [80, 50, 15],
        "motion": {"type": "circle", "center": [70, 50, 15], "radius": 10, "angular_speed": 0.3},
    },
]


def corridor_sim(t: float, obstacles: list | None = None, velocity=(0.0, 0.0, 0.0)) -> Simulation:
    """One agent at (20, 40, 15) heading for (105, 40, 15), the plug as the only obstacle, at time ``t``."""
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [120, 80, 30]},
        obstacles=[PLUG] if obstacles is None else obstacles,
        agents=[{"id": "a", "start": [20, 40, 15], "goal": [105, 40, 15]}],
    )
    raw["agent_defaults"] = {
        "model": "multirotor",
        "radius": 1.0,
        "speed": {"min": 0, "max": 10, "cruise": 7},
        "max_accel": 4,
    }
    sim = Simulation(make_world(raw))
    sim.reset(seed=0)
    sim.state.t = t
    sim.state.velocity[0] = velocity
    return sim


def test_positions_at_are_the_motion_models_poses():
    world = make_world(base_world(obstacles=MOVERS))
    times = np.array([0.0, 0.3, 2.25, 4.5, 7.7, 13.0, 31.4, 100.0])
    got = positions_at(world.obstacles, times)
    want = np.array([[pose_at(o, t)[0] for o in world.obstacles] for t in times])
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_clock_accelerates_from_rest_to_cruise():
    clock = EscapeClock(t0=10.0, v0=0.0, accel=4.0, cruise=7.0)
    # 6.125 m to reach 7 m/s in 1.75 s, then cruise.
    assert float(clock(0.0)) == 10.0
    assert float(clock(2.0)) == pytest.approx(10.0 + 1.0)  # s = a t^2 / 2
    assert float(clock(6.125)) == pytest.approx(11.75)
    assert float(clock(6.125 + 70.0)) == pytest.approx(21.75)
    at_cruise = EscapeClock(t0=0.0, v0=7.0, accel=4.0, cruise=7.0)
    assert float(at_cruise(35.0)) == pytest.approx(5.0)


def test_moving_clearance_sees_the_plug_where_it_is_predicted():
    sim = corridor_sim(0.0)
    pts = np.array([[55.0, 40.0, 15.0], [55.0, 76.0, 15.0]])
    # Before it moves the plug is at y = 58..94 (face x = 60): beside the second point only.
    c0 = moving_clearance(sim, pts, 1.0, 0.0, 0.0)
    assert c0[1] == pytest.approx(5.0 - 1.0)
    assert c0[0] == pytest.approx(np.hypot(5.0, 40.0 - 58.0) - 1.0)
    # Parked (any window after 4.5 s): in front of the first point.
    c1 = moving_clearance(sim, pts, 1.0, 6.0, 20.0)
    assert c1[0] == pytest.approx(4.0)
    assert c1[1] == pytest.approx(np.hypot(5.0, 76.0 - 58.0) - 1.0)
    # A window spanning its drive counts every pose in it: the worst one.
    c2 = moving_clearance(sim, pts, 1.0, 0.0, 20.0)
    assert c2[0] == pytest.approx(4.0) and c2[1] == pytest.approx(4.0)


def test_subgoal_goes_past_a_parked_mover():
    sim = corridor_sim(10.0)
    need = 3.0
    sub = choose_subgoal(sim, 0, 24.0, need)
    # The plug's far face is x = 64: the sub-goal is past it with the clearance needed.
    assert sub[0] >= 64.0 + 1.0 + need - 1e-6
    np.testing.assert_allclose(sub[1:], [40.0, 15.0])
    # Without any obstacle it would be the horizon.
    free = corridor_sim(10.0, obstacles=[])
    np.testing.assert_allclose(choose_subgoal(free, 0, 24.0, need), [44.0, 40.0, 15.0])


def test_a_stretch_that_grazes_a_wall_does_not_hide_the_blocker_behind_it():
    """parked_mover_corridor seed 1: stuck at (30.9, 53.4) beside the corridor's north wall
    (y = 56..60 for x = 36..60), the ray to the goal passes the wall's corner 2.5 m clear
    (less than ``need`` = 3, more than the 1 m margin), then runs into the parked plug."""
    walls = [
        {"id": "left", "shape": "box", "size": [24, 4, 40], "position": [48, 22, 15]},
        {"id": "right", "shape": "box", "size": [24, 4, 40], "position": [48, 58, 15]},
    ]
    sim = corridor_sim(10.0, obstacles=[*walls, PLUG])
    sim.state.position[0] = [30.9, 53.4, 15.0]
    sub = choose_subgoal(sim, 0, 24.0, 3.0)
    assert sub[0] > 64.0 + 1.0 + 3.0  # past the plug, not 24 m out in front of it
    u = (sim.state.goal[0] - sim.state.position[0]) / np.linalg.norm(
        sim.state.goal[0] - sim.state.position[0]
    )
    np.testing.assert_allclose(np.cross(sub - sim.state.position[0], u), 0.0, atol=1e-9)  # on the ray
    # Only a stretch that comes closer than ``squeeze`` blocks: with squeeze = need the
    # grazing stretch is the first blocker again and the sub-goal is the horizon.
    near = choose_subgoal(sim, 0, 24.0, 3.0, squeeze=3.0)
    assert float(np.linalg.norm(near - sim.state.position[0])) == pytest.approx(24.0)


def test_subgoal_ignores_a_mover_that_is_gone_before_the_agent_gets_there():
    # The plug drives north out of the way (from y = 40 to y = 100 at 20 m/s: gone at 3 s).
    gone = dict(
        PLUG,
        position=[62, 40, 15],
        motion={"type": "waypoints", "waypoints": [[62, 200, 15]], "speed": 20, "loop": False},
    )
    sim = corridor_sim(0.0, obstacles=[gone])
    sub = choose_subgoal(sim, 0, 24.0, 3.0)
    np.testing.assert_allclose(sub, [44.0, 40.0, 15.0])


def test_fcl_validation_sees_movers_at_the_time_the_agent_passes():
    # A leg straight through the plug's parked pose: a hit once it is parked.
    a, b = np.array([20.0, 40.0, 15.0]), np.array([100.0, 40.0, 15.0])
    parked = corridor_sim(10.0, velocity=(7.0, 0.0, 0.0))
    assert mover_leg_hit(parked, 0, a, b, 0.0, 0.3) == "plug"
    # The same leg at t = 0 passes x = 62 at about 6 s: the plug is parked by then.
    assert mover_leg_hit(corridor_sim(0.0, velocity=(7.0, 0.0, 0.0)), 0, a, b, 0.0, 0.3) == "plug"
    # A leg through the plug's start pose (y = 58..94 at x = 60..64) reaches x = 59 at 5.5 s
    # (at 7 m/s from x = 20): the plug has parked at y = 22..58 by then, even 2 s earlier.
    c, d = np.array([20.0, 76.0, 15.0]), np.array([100.0, 76.0, 15.0])
    start = corridor_sim(0.0, velocity=(7.0, 0.0, 0.0))
    assert mover_leg_hit(start, 0, c, d, 0.0, 0.3) is None
    # ... but it is not from x = 56 (at x = 60 in 0.6 s, when the plug is at y = 71..107).
    e = np.array([56.0, 76.0, 15.0])
    assert mover_leg_hit(start, 0, e, d, 0.0, 0.3) == "plug"


def test_segment_cost_scores_movers_at_their_predicted_poses():
    """The cost's moving term looks at the plug where it is when the agent gets there."""
    world = corridor_sim(0.0).world
    flyer = Flyer(radius=1.0, speed=7.0, turn_radius=12.0, max_climb=np.radians(45), min_altitude=3.0)
    through = np.array([[[20.0, 40.0, 15.0], [100.0, 40.0, 15.0]]])
    parked = SegmentCost(world, flyer, t0=10.0)
    assert parked.terms(through)["moving"][0] > parked.w.collision * 4.0  # 4 m inside the plug
    # From t = 0 at 7 m/s the agent reaches x = 60 at 5.7 s: parked by then, the same hit.
    assert SegmentCost(world, flyer, t0=0.0).terms(through)["moving"][0] > parked.w.collision * 4.0
    # Along y = 76 (the plug's start) from x = 40: at x = 60 at 2.9 s, the plug has left (y < 63).
    north = np.array([[[40.0, 76.0, 15.0], [100.0, 76.0, 15.0]]])
    assert SegmentCost(world, flyer, t0=0.0).terms(north)["moving"][0] == 0.0


# ----------------------------------------------------------------------------- seeds


def escape_histories(seed: int, tmp_path: Path) -> list[list[float]]:
    """Convergence histories of the escape optimizer runs of u_pocket (first 12 s) with ``seed``,
    on the bare field (the guide round static obstacles leads the agent out of the pocket)."""
    world = apply_overrides(load_world(ROOT / "worlds" / "traps" / "u_pocket.yaml"), None, 12.0)
    log = tmp_path / f"seed{seed}.mcap"
    simulate(without_guide(world), seed, log)
    runs = [d for _, d in read_log(log).get("/optimizer", []) if d["purpose"] == "escape"]
    return [r["convergence"] for r in runs]


def test_the_seed_reaches_the_escape_optimizer(tmp_path):
    """Before the first escape the potential field is deterministic (no draws), so the first
    escape is planned from the same state under every seed: its optimizer history differs
    only through the seed. Same seed: the same history."""
    first = {}
    for seed in (1, 2, 3):
        runs = escape_histories(seed, tmp_path)
        assert runs, f"seed {seed}: no escape in 12 s"
        first[seed] = runs[0]
    assert first[1] != first[2] and first[2] != first[3] and first[1] != first[3]
    assert escape_histories(1, tmp_path / "again")[0] == first[1]


def test_the_command_line_seed_reaches_the_escape_optimizer(tmp_path):
    """``run --seed N`` (not the world's seed) seeds the escape optimizer: the first escape's
    history differs between seeds 1 and 2 of the shipped U-shaped pocket (on the bare field:
    the guide leads the agent out of the pocket without an escape)."""
    world = ROOT / "worlds" / "traps" / "u_pocket.yaml"
    first = {}
    for seed in (1, 2):
        log = tmp_path / f"cli{seed}.mcap"
        args = ["--seed", str(seed), "--out", str(log), "--max-time", "12", "--no-guide", "--quiet"]
        run_main([str(world), *args])
        runs = [d for _, d in read_log(log).get("/optimizer", []) if d["purpose"] == "escape"]
        assert runs, f"seed {seed}: no escape in 12 s"
        first[seed] = runs[0]
    assert first[1]["convergence"] != first[2]["convergence"]
    assert first[1]["t"] == first[2]["t"]  # planned from the same state: only the draws differ
