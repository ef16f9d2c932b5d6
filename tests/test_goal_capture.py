"""A fixed wing's capture of its goal (``swarmplan.flight.capture``): a goal inside its turn
circle is not turned onto (it flies on straight until it can come round with a final straight
onto it); a goal outside both circles, a multirotor's goal and a waypoint are left alone; and a
fixed wing that passes beside its goal comes round once, at its turn radius and never below
its minimum speed, and arrives without a stuck event or a planned segment."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from helpers import base_world, make_world

from swarmplan.core import Mode
from swarmplan.flight.capture import FINAL, GoalCapture, capture_time
from swarmplan.flight.kinematics import AgentParams

R = 40.0


def _fixed_wing_world(goal: list[float], n: int = 1, max_time: float = 60.0):
    raw = base_world(
        bounds={"min": [-400, -400, 0], "max": [400, 400, 200]},
        sim={"dt": 0.1, "max_time": max_time, "goal_tolerance": 5.0},
        agent_defaults={
            "model": "fixed_wing",
            "radius": 1.0,
            "speed": {"min": 15, "max": 25, "cruise": 20},
            "max_accel": 3,
            "min_turn_radius": R,
            "max_climb_angle": 15,
            "min_altitude": 5,
            "separation": [6, 6, 3],
        },
        agents=[{"id": f"fw{k}", "start": [0, 60 * k, 50], "goal": goal} for k in range(n)],
    )
    return make_world(raw)


def _capture(goal: list[float]) -> tuple[GoalCapture, np.ndarray]:
    params = AgentParams.from_world(_fixed_wing_world(goal))
    return GoalCapture(params), np.array([goal], dtype=float)


def _aim(cap: GoalCapture, pos: list[float], goal: np.ndarray, heading: list[float], t: float = 0.0):
    vel = 20.0 * np.array([heading], dtype=float)
    return cap.targets(t, np.array([0]), np.array([pos], dtype=float), vel, goal, goal.copy())


def test_a_goal_inside_the_turn_circle_is_not_turned_onto():
    # Heading +x at the origin: the left circle's centre is (0, R); (10, 30) lies 14 m from it.
    cap, goal = _capture([10.0, 30.0, 70.0])
    target = _aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(target, [[R, 0.0, 70.0]])  # a turn radius ahead, at the goal's height
    assert cap.extending[0] and cap.hold[0]
    # Mirrored to the right: the right circle.
    cap, goal = _capture([10.0, -30.0, 50.0])
    np.testing.assert_allclose(_aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0]), [[R, 0.0, 50.0]])


def test_a_goal_outside_both_circles_is_flown_at():
    for g in ([100.0, 0.0, 50.0], [20.0, 90.0, 50.0], [-100.0, 0.0, 50.0], [0.0, -2.5 * R, 50.0]):
        cap, goal = _capture(g)
        np.testing.assert_array_equal(_aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0]), goal)
        assert not cap.extending[0]


def test_extending_ends_once_the_final_straight_fits():
    """Flying on straight, the goal at (0, 30) falls behind; the extension ends when the goal is
    FINAL turn radii from the centre of the circle flown after the roll-in, and not before."""
    cap, goal = _capture([0.0, 30.0, 50.0])
    params = cap.params
    speed = 20.0
    bank = math.atan(speed * speed / (9.80665 * R))
    shift = 0.5 * speed * bank / float(params.roll_rate[0])
    # The centre (x + shift, R): the goal is FINAL R from it at x = sqrt((FINAL R)^2 - 10^2) - shift behind.
    x_end = math.sqrt((FINAL * R) ** 2 - (R - 30.0) ** 2) - shift
    assert not np.array_equal(_aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0, 0]), goal)
    assert not np.array_equal(_aim(cap, [x_end - 0.5, 0.0, 50.0], goal, [1.0, 0, 0]), goal)
    np.testing.assert_array_equal(_aim(cap, [x_end + 0.5, 0.0, 50.0], goal, [1.0, 0, 0]), goal)
    # A quarter circle round (the goal outside the circle it turns on): no extending again.
    np.testing.assert_array_equal(_aim(cap, [x_end + 0.5 + R, R, 50.0], goal, [0.0, 1.0, 0]), goal)
    assert not cap.extending[0]


def test_multirotors_and_waypoints_are_left_alone():
    cap, goal = _capture([10.0, 30.0, 50.0])
    waypoint = np.array([[10.0, 31.0, 50.0]])
    pos, vel = np.array([[0.0, 0.0, 50.0]]), np.array([[20.0, 0.0, 0.0]])
    np.testing.assert_array_equal(cap.targets(0.0, np.array([0]), pos, vel, goal, waypoint), waypoint)
    multirotor = dataclasses.replace(cap.params, fixed_wing=np.array([False]))
    cap = GoalCapture(multirotor)
    np.testing.assert_array_equal(cap.targets(0.0, np.array([0]), pos, vel, goal, goal.copy()), goal)


def test_capturing_holds_the_stuck_watch_for_the_time_a_capture_takes():
    cap, goal = _capture([10.0, 30.0, 50.0])
    limit = float(capture_time(cap.params)[0])
    assert limit == (6.0 + 2.0 * math.pi) * R / 15.0
    _aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0], t=5.0)
    assert cap.hold[0]
    _aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0], t=5.0 + limit - 0.1)
    assert cap.hold[0]
    _aim(cap, [0.0, 0.0, 50.0], goal, [1.0, 0.0, 0.0], t=5.0 + limit + 0.1)
    assert not cap.hold[0]


def test_a_fixed_wing_passing_beside_its_goal_comes_round_once_and_arrives():
    """Set flying past its goal 30 m to its side (inside its turn circle), it extends, comes
    round at its turn radius and flies into the tolerance: within one circle and the way out
    and back, never slower than its minimum speed, with no stuck event and no segment."""
    from swarmplan.sim import Simulation

    world = _fixed_wing_world([0.0, 30.0, 50.0])
    sim = Simulation(world)
    s = sim.reset(0)
    s.velocity[0] = [20.0, 0.0, 0.0]  # heading +x, the goal square to its left
    kinds, speeds, arrival = [], [], math.inf
    for _ in range(int(world.max_time / world.dt)):
        r = sim.step()
        kinds += [e.kind for e in r.events]
        arrival = min([arrival] + [e.t for e in r.events if e.kind == "arrived"])
        if r.state.mode[0] == Mode.APF:
            speeds.append(float(np.linalg.norm(r.state.velocity[0])))
        if r.terminated or r.truncated:
            break
    s = sim.state
    assert s.mode[0] == Mode.ARRIVED, kinds
    assert "stuck" not in kinds and "smoothing_start" not in kinds and "escape_start" not in kinds, kinds
    assert min(speeds) >= 15.0 - 1e-9
    # Out to FINAL R and back, and a full circle, at the minimum speed bound the time.
    assert arrival <= float(capture_time(AgentParams.from_world(world))[0]), arrival
    assert arrival > math.pi * R / 25.0  # it came round (half a circle at least, at the top speed)


def test_height_is_won_before_the_last_turn_radius_and_the_last_one_flown_level():
    """``height_first``: between one and ``CAPTURE_RANGE`` turn radii of its goal a fixed wing's
    pull wins the height by a turn radius short of it (at most its climb limit, at most the
    level-off profile ``sqrt(dz / R)``, which alone holds within its last turn radius); beyond the
    capture range, and for a target that is not its way to the goal, the target is left as it is."""
    from swarmplan.flight.capture import CAPTURE_RANGE, height_first

    goal = [0.0, 0.0, 50.0]
    params = AgentParams.from_world(_fixed_wing_world(goal))
    climb = params.max_climb[0]
    g = np.array([goal])

    def aim(pos: list[float], at_goal: bool = True, target: np.ndarray = g) -> np.ndarray:
        return height_first(params, np.array([0]), np.array([pos]), g, np.array([at_goal]), target)

    # 2 R out and 10 m low: the slope over the one turn radius before the last, atan(10 / R).
    out = aim([-2.0 * R, 0.0, 40.0])
    np.testing.assert_allclose(out, [[0.0, 0.0, 40.0 + 2.0 * R * 10.0 / R]])
    # 1.2 R out and 20 m high: the slope (atan(20 / 0.2 R), 68 degrees) and the level-off
    # profile (sqrt(0.5), 35 degrees) are over the climb limit: a dive at the limit.
    out = aim([1.2 * R, 0.0, 70.0])
    np.testing.assert_allclose(out, [[0.0, 0.0, 70.0 - 1.2 * R * math.tan(climb)]])
    # 1.1 R out, 1 m low: the slope atan(1 / 0.1 R) (14 degrees) is over the profile sqrt(1 / R)
    # (9 degrees), both under the climb limit (15): the profile.
    out = aim([-1.1 * R, 0.0, 49.0])
    assert math.sqrt(1.0 / R) < math.atan(1.0 / (0.1 * R)) < climb
    np.testing.assert_allclose(out, [[0.0, 0.0, 49.0 + 1.1 * R * math.tan(math.sqrt(1.0 / R))]])
    # The target is what the pull aims at horizontally: its height follows the same slope.
    ahead = np.array([[-2.0 * R + 10.0, 0.0, 50.0]])
    out = aim([-2.0 * R, 0.0, 40.0], target=ahead)
    np.testing.assert_allclose(out, [[-2.0 * R + 10.0, 0.0, 40.0 + 10.0 * 10.0 / R]])
    # Within the last turn radius, the profile: 0.5 R out, 2 m high.
    out = aim([0.5 * R, 0.0, 52.0])
    np.testing.assert_allclose(out, [[0.0, 0.0, 52.0 - 0.5 * R * math.tan(math.sqrt(2.0 / R))]])
    assert aim([-(CAPTURE_RANGE + 0.1) * R, 0.0, 40.0]) is g
    assert aim([-2.0 * R, 0.0, 40.0], at_goal=False) is g

