"""The turn-ahead guard's manoeuvres, its choice when none keeps clear, the loiter circle of an
arrived fixed wing, and the waypoint spacing of a fixed wing's mission: exact answers on simple
geometry."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.flight.kinematics import AgentParams
from swarmplan.flight.lookahead import _MANOEUVRES, _rollout_rows, guard_commands, horizon_steps
from swarmplan.runtime.compiled import kernel_module

ROOT = Path(__file__).resolve().parents[1]
R, V, DT, CLIMB = 40.0, 20.0, 0.1, math.radians(15.0)


def fk():  # noqa: ANN201
    return kernel_module("swarmplan.flight._fixed_wing_kernel")


def roll(top: float, turn: float, vel: np.ndarray, kappa=(0.0, 0.0), steps=200, rate=np.inf, start=None):  # noqa: ANN001, ANN201
    """Positions (2 steps, 3) and steps flown of one manoeuvre from ``start`` (the origin)."""
    one = lambda x: np.array([x], dtype=float)  # noqa: E731
    at = np.zeros((1, 3)) if start is None else np.array([start], float)
    out, used = fk().rollouts(
        at, np.array([vel], float), np.array([kappa], float), np.array([[turn]], float),
        np.array([[top]], float), one(2.0), one(R), one(CLIMB), one(rate), steps, DT,
    )  # fmt: skip
    return out[0, 0], int(used[0, 0])


def gammas(path: np.ndarray) -> np.ndarray:
    d = np.diff(path, axis=0)
    return np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))


def diving(g: float = CLIMB) -> np.ndarray:
    return V * np.array([math.cos(g), 0.0, -math.sin(g)])


@pytest.mark.parametrize("rate", [np.inf, math.radians(90.0)])
def test_a_level_turn_pulls_out_of_a_banked_dive_first(rate: float) -> None:
    """Diving at the climb limit in a hard right turn (at its roll rate or at once), the level
    right turn pulls out first: the dive's angle goes by the whole turn budget V dt / R a step
    (0.05 rad) down to level in ceil(15 deg / 0.05 rad) = 6 steps (a few more while the bank
    eases off at a finite roll rate), losing no more height than a pull-out on a circle of R,
    R (1 - cos 15 deg) (1.4 m), and a step's dive."""
    path, used = roll(math.nan, -1.0, diving(), kappa=(-1.0 / R, 0.0), rate=rate)
    g = gammas(np.vstack([np.zeros(3), path[:used]]))  # the angle of each step flown
    level = int(np.argmax(np.abs(g) < 1e-9)) + 1  # steps to level
    assert (level == 6 if rate == np.inf else 6 <= level <= 9) and np.all(np.abs(g[level - 1 :]) < 1e-9)
    assert -path[:used, 2].min() <= R * (1 - math.cos(CLIMB)) + V * DT * math.sin(CLIMB)
    # It flew a step more for each step it began more than a budget off level; then it turns at
    # the limit.
    before = np.concatenate([[-CLIMB], g[:-1]])
    assert used == 200 + int((np.abs(before) > V * DT / R).sum())
    heading = np.unwrap(np.arctan2(np.diff(path[level:used, 1]), np.diff(path[level:used, 0])))
    assert np.allclose(np.diff(heading)[3:], -V * DT / R, rtol=1e-6)


def test_a_climb_levels_off_at_its_height_without_overshooting() -> None:
    """Climbing to 30 m: at most the climb limit, never above 30 m, level at the end within a
    step's travel of it."""
    path, used = roll(30.0, 1.0, np.array([V, 0.0, 0.0]), steps=300)
    z, g = path[:used, 2], gammas(np.vstack([np.zeros(3), path[:used]]))
    assert z.max() <= 30.0 and 30.0 - z[-1] <= V * DT
    assert g.max() <= CLIMB + 1e-12 and abs(g[-1]) <= V * DT / R
    # A dive to a floor below does the same downwards.
    path, used = roll(-25.0, 0.0, np.array([V, 0.0, 0.0]), steps=300)
    assert path[:used, 2].min() >= -25.0 and path[used - 1, 2] + 25.0 <= V * DT


def test_a_manoeuvre_flown_on_from_its_own_rollout_stays_on_it() -> None:
    """The manoeuvres read the state alone: flown again from a later state of its own rollout,
    a manoeuvre goes on along the same path (so a way out found stays one as it is flown)."""
    v0 = diving(math.radians(8.0))
    for top, turn in [(math.nan, 1.0), (40.0, -1.0), (-30.0, 0.0)]:
        path, used = roll(top, turn, v0, kappa=(0.5 / R, 0.0), rate=math.radians(60.0))
        k = 10
        v_prev, v_k = (path[k - 1] - path[k - 2]) / DT, (path[k] - path[k - 1]) / DT
        kappa = fk().turn_states(v_prev[None], v_k[None], np.array([CLIMB]), DT)[0]
        again, _ = roll(top, turn, v_k, kappa=kappa, rate=math.radians(60.0), start=path[k])
        np.testing.assert_allclose(again[:50], path[k + 1 : k + 51], atol=1e-6)


def guard_world():  # noqa: ANN201
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [400, 400, 100]},
        sim={"dt": DT, "max_time": 30, "goal_tolerance": 2.0},
        agent_defaults={
            "model": "fixed_wing",
            "radius": 1.0,
            "speed": {"min": 15, "max": 25, "cruise": V},
            "max_accel": 2,
            "min_turn_radius": R,
            "max_climb_angle": 15,
            "min_altitude": 5,
            "separation": [4, 4, 2],
        },  # fmt: skip
        agents=[{"id": "a", "start": [200, 200, 50], "goal": [380, 200, 50]}],
    )
    return make_world(raw)


def test_with_no_way_out_the_guard_keeps_clear_the_longest() -> None:
    """No manoeuvre keeps clear: a level right turn leaves it at once by a little (-0.5 m), a level
    left turn only after 8 s but by far (-100 m), straight on, climbs and dives soon and far. The
    guard flies the left turn: the time to pass for whatever corners it, not the clearance at the
    worst point."""
    p = AgentParams.from_world(guard_world())
    p.clearance[:] = p.radius
    pos, vel = np.array([[200.0, 200.0, 50.0]]), np.array([[V, 0.0, 0.0]])

    def clearance(points, radii, times, extra):  # noqa: ANN001, ANN202
        y = points[:, 1] - 200.0
        out = np.full(len(points), 10.0)
        out[y < -2.0] = -0.5
        out[(y > 2.0) & (times > 8.0)] = -100.0
        out[np.abs(y) <= 2.0] = np.where(points[np.abs(y) <= 2.0, 0] > 205.0, -200.0, 10.0)
        out[np.abs(points[:, 2] - 50.0) > 1.0] = -300.0  # climbs and dives: soon and far
        return out

    idx = np.array([0])
    out, replaced = guard_commands(p, idx, pos, vel, vel.copy(), 0.0, DT, clearance, np.array([1.0]))
    assert replaced[0]
    assert horizon_steps(p, idx, np.array([V]), DT) * DT > 8.0
    # The command is the first step of the level left turn.
    every = np.arange(len(_MANOEUVRES))[None]
    *rows, _ = _rollout_rows(p, idx, pos, vel, np.zeros((1, 2)), every, DT)
    first = fk().first_velocities(*rows, DT)[0]
    j = int(np.argmin(np.linalg.norm(first - out[0], axis=1)))
    assert np.array_equal(first[j], out[0]) and _MANOEUVRES[j] == (1, 0)


def test_an_arrived_fixed_wing_loiters_on_a_circle_through_where_it_arrived() -> None:
    """The circle is tangent to its heading where it arrived, on the side it was turning to
    (left when straight), of 1.2 R when that is clear; else on the other side; else wider."""
    from swarmplan.sim.loiter import Loiter

    p = AgentParams.from_world(guard_world())
    loiter = Loiter(p)
    here, heading = np.array([100.0, 50.0, 30.0]), np.array([0.0, V, 0.0])  # flying north
    loiter.start(0, here, heading, np.zeros(2), lambda pts: np.ones(len(pts)))
    assert loiter.side[0] == 1.0 and loiter.radius[0] == pytest.approx(1.2 * R)
    np.testing.assert_allclose(loiter.center[0], [100.0 - 1.2 * R, 50.0, 30.0])
    # Turning right when it arrived: on its right.
    loiter.start(0, here, heading, np.array([-0.5 / R, 0.0]), lambda pts: np.ones(len(pts)))
    assert loiter.side[0] == -1.0
    np.testing.assert_allclose(loiter.center[0], [100.0 + 1.2 * R, 50.0, 30.0])
    # A wall 1.5 R to its left: the circle on its right.
    loiter.start(0, here, heading, np.zeros(2), lambda pts: pts[:, 0] - (100.0 - 1.5 * R))
    assert loiter.side[0] == -1.0 and loiter.radius[0] == pytest.approx(1.2 * R)
    # Walls 1.5 R to both sides, room ahead and behind: no circle of 1.2 R or more fits: the
    # clearest one (the smallest: its points come least far out).
    loiter.start(0, here, heading, np.zeros(2), lambda pts: 1.5 * R - np.abs(pts[:, 0] - 100.0))
    assert loiter.radius[0] == pytest.approx(1.2 * R)


def test_a_fixed_wing_mission_turns_within_its_tracking_bound() -> None:
    """A fixed wing's waypoints on a turn at its minimum radius R = 2 km (tracking bound e = 100 m)
    lie at most sqrt(R e) (447 m) apart, and the tracker flying the polyline on its timing stays
    within e of it (within half of it, as the waypoint rule works out)."""
    from swarmplan.export import mission
    from swarmplan.export.check import path_distance
    from swarmplan.export.files import FIXED_WING_WAYPOINT_SHARE
    from swarmplan.export.source import AgentLimits, FlownPath
    from swarmplan.track.fixed_wing import Aircraft, FixedWingConfig, error_limit, fly

    radius, speed, dt = 2000.0, 55.0, 1.0
    t = dt * np.arange(int(1.5 * math.pi * radius / speed))
    th = speed * t / radius
    pos = np.column_stack([radius * np.sin(th), radius * (1 - np.cos(th)), np.full_like(th, 3000.0)])
    lim = AgentLimits("uav", "fixed_wing", 10.0, 50.0, 70.0, speed, 10.0, radius, 20.0, (50.0, 50.0, 20.0))
    ac = Aircraft(50.0, 70.0, 10.0, radius, 20.0, 0.0, speed)
    e = error_limit(ac)
    m = mission.mission_of(FlownPath(lim, t, pos, True), FIXED_WING_WAYPOINT_SHARE * e)
    legs = np.linalg.norm(np.diff(m.waypoints, axis=0), axis=1)
    assert legs.max() <= math.sqrt(radius * e) * 1.01
    times, planned = mission.timed(m)
    flight = fly(times, planned, ac, FixedWingConfig(), dt)
    assert float(path_distance(flight.pos, flight.ref_pos).max()) <= 0.5 * e


SHIPPED_FIXED_WING = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "worlds").glob("fixed_wing*.yaml"))


@pytest.mark.slow
@pytest.mark.parametrize("path", SHIPPED_FIXED_WING)
def test_shipped_fixed_wing_worlds_export_missions_flown_within_their_bound(path, tmp_path, capsys):
    """Every shipped fixed-wing world flies home without a contact, and its PX4 export loads in
    pymavlink and is flown by the L1/TECS tracker within max(5 m, 0.05 R_min) of the plan, with
    no contact and separation kept (``--check`` exits 0)."""
    import json

    from swarmplan.cli.export import main as export_main
    from swarmplan.io.runner import simulate
    from swarmplan.world import load_world

    mavwp = pytest.importorskip("pymavlink.mavwp")
    world = load_world(ROOT / path)
    log = tmp_path / "run.mcap"
    summary = simulate(world, world.seed, log)
    assert summary["arrived"] == summary["agents_total"] and summary["collisions"] == 0
    out = tmp_path / "px4"
    origin = ["--origin", "47.0,8.0,400"]
    code = export_main([str(log), "--format", "px4", "--out", str(out), "--check", *origin])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "check: OK" in text
    for entry in json.loads((out / "manifest.json").read_text())["agents"]:
        assert mavwp.MAVWPLoader().load(str(out / entry["waypoint_list"])) == entry["items"] + 1


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "k"), [(0, 21), (1, 21), (0, 2)])
def test_bench_worlds_that_cornered_a_fixed_wing(seed: int, k: int) -> None:
    """Worlds of ``python -m swarmplan.bench reach --class fixed_wing`` where a fixed wing flew
    into a face of the flight volume (a turn held at the limit out past its way out, a pull-out
    that widened a turn, a 170 m box with a goal in a corner): no collision, no limit broken."""
    from swarmplan.bench.reach import fly, world_of

    rec = fly(world_of("fixed_wing", seed, k))
    assert not [a for a in rec["agents"] if a["collisions"] or a["limit_break"]], rec["agents"]


def test_a_fixed_wing_approaches_a_goal_in_a_corner_on_a_clear_circle_through_it() -> None:
    """A goal 45 m (1.1 R) from two faces, flown at heading into the corner: no circle through it
    tangent to that heading is clear, so the aircraft takes a circle through its goal that is
    clear of the bounds; a goal in the open is flown at straight."""
    from swarmplan.planner.hold import loiter_circle
    from swarmplan.sim import Simulation
    from swarmplan.sim.loiter import clear_of_statics

    sim = Simulation(guard_world())
    sim.reset(seed=0)
    loiter, obstacles = sim.steering.loiter, sim.obstacles
    here, v = np.array([200.0, 200.0, 50.0]), np.array([V, V, 0.0]) / math.sqrt(2.0)
    corner = np.array([355.0, 355.0, 50.0])
    assert loiter._choose(0, here, v, corner, obstacles)
    c, r, side = loiter.center[0], loiter.radius[0], loiter.side[0]
    assert r >= R and math.hypot(*(corner - c)[:2]) == pytest.approx(r)
    # The circle: tangent to a heading at the goal, all clear of the bounds by the body radius.
    heading = math.atan2(corner[1] - c[1], corner[0] - c[0]) + side * 0.5 * math.pi
    pts = loiter_circle(corner, np.array([math.cos(heading), math.sin(heading), 0.0]), r, side)
    assert clear_of_statics(obstacles, 0)(pts).min() >= 0.0
    # Far out, its field pulls at the circle's tangent point; at the goal's altitude.
    target = loiter._on_circle(0, here, v, corner)
    assert math.hypot(*(target - c)[:2]) == pytest.approx(r) and target[2] == corner[2]
    assert np.dot(target[:2] - c[:2], target[:2] - here[:2]) == pytest.approx(0.0, abs=1e-6)
    # A goal in the open: no circle, flown at directly.
    loiter.reset()
    assert not loiter._choose(0, here, np.array([V, 0.0, 0.0]), np.array([300.0, 200.0, 50.0]), obstacles)
    assert not loiter.approaching[0]


def test_the_way_onto_an_approach_circle_is_a_dubins_way() -> None:
    """The way a fixed wing's approach circle is chosen by: on the circle's tangent already, the
    straight; heading away, the half turn and the inner tangent onto it; from inside a circle
    its turns have no tangent onto, the turn onto the circle's course abreast of it and the
    arc."""
    from swarmplan.sim.loiter import _way_length

    rho, r = 10.0, 10.0
    at, goal = np.zeros(3), np.array([100.0, 0.0, 0.0])
    east, west = np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    # The goal's circle: anticlockwise, heading east at the goal (centre (100, 10)).
    assert _way_length(at, east, goal, 0.0, r, 1.0, rho) == pytest.approx(100.0)
    # Heading west: a right turn of pi + b onto the inner tangent (offset 2 r), the tangent, and
    # the arc b from where it meets the circle to the goal, b = atan(2 r / tangent).
    tangent = math.sqrt(100.0**2 - (2.0 * r) ** 2)
    b = math.atan2(2.0 * r, tangent)
    way = _way_length(at, west, goal, 0.0, r, 1.0, rho)
    assert way == pytest.approx(rho * (math.pi + b) + tangent + r * b)
    # A metre west of the centre of a wide circle, neither turn has a tangent onto it: a quarter
    # turn onto its course abreast (south) and half the circle to the goal opposite (heading
    # north there).
    wide = 50.0
    inside = goal - np.array([wide + 1.0, 0.0, 0.0])
    north = math.pi / 2.0
    way = _way_length(inside, east, goal, north, wide, 1.0, rho)
    assert way == pytest.approx(rho * math.pi / 2.0 + wide * math.pi)


def test_a_fixed_wing_spirals_on_its_approach_circle_until_its_goal_height_is_in_reach() -> None:
    """On its approach circle (radius R, anticlockwise, centre (200, 200)), flying its way, its
    goal 20 degrees of arc ahead (less than ``LEAD``): the field pulls at the goal itself only
    when the height still to win is within what the climb limit wins over that arc,
    R (20 degrees) tan(15 degrees) = 3.74 m; with more it pulls at the point ``LEAD`` along
    its course, at the goal's height, and goes round once more."""
    from swarmplan.sim import Simulation
    from swarmplan.sim.loiter import LEAD

    sim = Simulation(guard_world())
    sim.reset(seed=0)
    loiter = sim.steering.loiter
    c = np.array([200.0, 200.0, 50.0])
    loiter.approaching[0], loiter.center[0], loiter.radius[0], loiter.side[0] = True, c, R, 1.0
    here = c + np.array([R, 0.0, 0.0])  # flying north (anticlockwise) at the circle's east point
    v = np.array([0.0, V, 0.0])
    arc = math.radians(20.0)
    assert arc < LEAD
    won = R * arc * math.tan(CLIMB)
    assert won == pytest.approx(3.74, abs=0.01)
    for rise in (0.0, 0.9 * won, -0.9 * won):
        goal = c + np.array([R * math.cos(arc), R * math.sin(arc), rise])
        np.testing.assert_array_equal(loiter._on_circle(0, here, v, goal), goal)
    for rise in (1.1 * won, -1.1 * won, 40.0):
        goal = c + np.array([R * math.cos(arc), R * math.sin(arc), rise])
        target = loiter._on_circle(0, here, v, goal)
        assert target[2] == goal[2] and math.hypot(*(target - here)[:2]) == pytest.approx(R * LEAD)
        assert target[1] > here[1] and target[0] == pytest.approx(here[0])  # on along its course
