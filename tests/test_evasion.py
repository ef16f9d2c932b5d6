"""An agent that has arrived keeps itself safe: a multirotor hovering at its goal gets out of
the way of a mover whose path crosses its goal and comes back, a fixed wing loiters about its
goal clear of a mover aimed at it, and a contact with an arrived agent is a collision for the
simulator's ``/summary`` exactly as for the replay's audit."""

from __future__ import annotations

import numpy as np
from helpers import audit, base_world, check_log_module, events_of, make_world, replay_audit, run_to_end

GOAL = np.array([30.0, 50.0, 20.0])


def _world(mover: dict, model: str = "multirotor"):
    """Agent 'a' hops 10 m to GOAL (arrives after about 3 s); agent 'b' flies 80 m far away, so
    the run goes on while ``mover`` comes through."""
    a = {"id": "a", "start": [20, 50, 20], "goal": GOAL.tolist()}
    if model == "fixed_wing":
        a.update(
            model="fixed_wing",
            start=[0, 50, 20],
            speed={"min": 4, "max": 12, "cruise": 8},
            min_turn_radius=10,
            max_climb_angle=20,
        )
    raw = base_world(
        sim={"dt": 0.1, "max_time": 40, "goal_tolerance": 1.0},
        obstacles=[{"id": "truck", "shape": "sphere", "radius": 2.0, **mover}],
        agents=[
            a,
            {"id": "b", "start": [10, 90, 20], "goal": [90, 90, 20], "speed": {"max": 3, "cruise": 3}},
        ],
    )
    return make_world(raw)


def _crossing(speed: float, at: float) -> dict:
    """A mover on the line x = 30 heading +y that crosses the goal at time ``at``."""
    return {
        "position": [30.0, 50.0 - speed * at, 20.0],
        "motion": {"type": "linear", "velocity": [0.0, speed, 0.0]},
    }


def test_an_arrived_agent_dodges_a_mover_through_its_goal_and_comes_back(tmp_path):
    for speed in (3.0, 30.0):  # a slow truck and one that covers the horizon in 0.1 s steps
        log = tmp_path / f"dodge-{speed}.mcap"
        _, summary, pos = run_to_end(_world(_crossing(speed, at=8.0)), log_path=log)
        a = summary["agents"][0]
        assert a["arrived"] and a["final_mode"] == "arrived", a
        assert a["collisions"] == 0 and summary["collisions"] == 0, summary
        assert a["evasions"] == 1, a
        # It was at its goal before the truck came, left it, and is back within tolerance.
        (arrived,) = events_of(log, "arrived")[:1]
        (start,) = events_of(log, "evade_start")
        (end,) = events_of(log, "evade_end")
        assert arrived["agent"] == start["agent"] == end["agent"] == "a"
        assert arrived["t"] < start["t"] < 8.0 < end["t"], (arrived, start, end)
        assert start["detail"]["threat"] == "truck"
        assert a["arrival_time"] == arrived["t"]  # the first arrival stays the arrival
        track = np.array(pos)[int(round(arrived["t"] / 0.1)) :, 0]
        away = np.linalg.norm(track - GOAL, axis=1)
        assert away.max() > 2.0  # it did move out of the way (the truck is 2 m + its 1 m body)
        assert away.max() < 6.0  # and no farther than the dodge needs (4 m from the truck's axis)
        assert away[-1] <= 1.0 + 1e-9
        # Its clearance to the truck: the dodge keeps clear of it by half its body and more.
        assert a["min_obstacle_clearance"] > 0.5, a
        problems, _notes, stats = audit(log)
        assert not problems, problems
        assert stats["collisions"] == 0


def test_without_a_mover_an_arrived_agent_stays_put(tmp_path):
    far = {"position": [80.0, 10.0, 20.0], "motion": {"type": "linear", "velocity": [0.0, 0.5, 0.0]}}
    log = tmp_path / "calm.mcap"
    _, summary, pos = run_to_end(_world(far), log_path=log)
    a = summary["agents"][0]
    assert a["evasions"] == 0 and not events_of(log, "evade_start")
    track = np.array(pos)[:, 0]
    k = int(round(a["arrival_time"] / 0.1))
    assert np.ptp(track[k:], axis=0).max() == 0.0  # hovering, not drifting


def test_a_contact_after_arrival_is_a_collision_for_summary_and_replay(tmp_path):
    # The truck runs north along x = 60, 30 m beside the goal (no threat on that line), then
    # turns west at 30 m/s straight through it: under 1 s to reach the agent, which needs
    # about 1.9 s to get 3.5 m out of the way from rest.
    sudden = {
        "position": [60.0, -200.0, 20.0],
        "motion": {
            "type": "waypoints",
            "waypoints": [[60, -200, 20], [60, 50, 20], [0, 50, 20]],
            "speed": 30.0,
        },
    }
    log = tmp_path / "sudden.mcap"
    _, summary, _ = run_to_end(_world(sudden), log_path=log)
    a = summary["agents"][0]
    assert a["arrived"] and a["final_mode"] == "collided", a
    assert a["collisions"] == 1 and a["collided_with"] == ["truck"], a
    assert summary["collisions"] == 1 and not summary["success"]
    (hit,) = events_of(log, "collision")
    assert hit["agent"] == "a" and hit["t"] > a["arrival_time"]
    problems, _notes, stats = replay_audit(log, allow_failure=True)
    assert stats["collisions"] == 1, stats
    assert not [p for p in problems if "vs recorded" in p], problems
    # It had taken off (mode apf) when struck: the independent checker audits such steps too.
    mod = check_log_module(required=False)
    if mod is not None:
        c_problems, _, c_stats = mod.check(str(log), True)
        assert c_stats["collisions"] == 1, c_problems


def _fixed_wing_after_arrival(mover: dict, log) -> tuple[dict, np.ndarray]:
    _, summary, pos = run_to_end(_world(mover, model="fixed_wing"), log_path=log)
    return summary, np.array(pos)[:, 0]


def test_an_arrived_fixed_wing_loiters_about_its_goal_and_a_mover_aimed_at_it_misses(tmp_path):
    """A fixed wing cannot hold still: at its goal it loiters on a circle of at least its turn
    radius (10 m) through where it arrived (within its 1 m tolerance): out to the far side of
    the circle and no farther from its goal than its diameter, at its speed floor or faster;
    a truck aimed at where it would be
    (from the same run with the truck far away) does not touch it, for the simulation and
    for the replay's audit alike; its arrival stays its first arrival."""
    far = {"position": [90.0, 5.0, 20.0], "motion": {"type": "linear", "velocity": [0.0, 0.1, 0.0]}}
    calm, track = _fixed_wing_after_arrival(far, tmp_path / "calm.mcap")
    a = calm["agents"][0]
    assert a["arrived"] and a["final_mode"] == "arrived" and a["collisions"] == 0, a
    k = int(round(a["arrival_time"] / 0.1))
    ring = np.linalg.norm(track[k:, :2] - GOAL[:2], axis=1)
    assert 2.0 * 1.2 * 10.0 - 1.0 <= ring.max() <= 2.0 * 2.4 * 10.0 + 1.0, ring.max()
    speed = np.linalg.norm(np.diff(track[k:], axis=0), axis=1) / 0.1
    assert speed.min() >= 4.0 - 1e-6
    # The truck (2 m sphere, 6 m/s heading +y) aimed at where the aircraft is at t = 15 s.
    at = track[150]
    aimed = {
        "position": [float(at[0]), float(at[1]) - 6.0 * 15.0, float(at[2])],
        "motion": {"type": "linear", "velocity": [0.0, 6.0, 0.0]},
    }
    log = tmp_path / "aimed.mcap"
    summary, track = _fixed_wing_after_arrival(aimed, log)
    a = summary["agents"][0]
    assert a["arrived"] and a["final_mode"] == "arrived", a
    assert a["collisions"] == 0 and summary["collisions"] == 0, summary
    (arrived,) = events_of(log, "arrived")[:1]
    assert a["arrival_time"] == arrived["t"] < 15.0
    problems, _notes, stats = replay_audit(log, allow_failure=True)
    assert stats["collisions"] == 0, stats
    assert not [p for p in problems if "vs recorded" in p], problems


def test_the_dodge_is_deterministic(tmp_path):
    logs = []
    for k in range(2):
        log = tmp_path / f"d{k}.mcap"
        run_to_end(_world(_crossing(3.0, at=8.0)), seed=3, log_path=log)
        logs.append([(e["t"], e["kind"], e["detail"]) for e in events_of(log)])
    assert logs[0] == logs[1]


def _pole(x: float, speed: float, at: float) -> dict:
    """A pole 30 m tall (0.5 m radius: a bounding sphere of 15 m) on the line ``x`` heading +y,
    level with the goal at time ``at``."""
    return {
        "shape": "cylinder",
        "radius": 0.5,
        "height": 30.0,
        "position": [x, 50.0 - speed * at, 20.0],
        "motion": {"type": "linear", "velocity": [0.0, speed, 0.0]},
    }


def test_a_pole_passing_beside_an_arrived_agent_leaves_it_at_its_goal(tmp_path):
    """Its surface passes 3.5 m from the goal, beyond the agent's body (1 m) and the room it
    keeps (1 m), though its bounding sphere sweeps over the goal: the agent stays put."""
    log = tmp_path / "beside.mcap"
    _, summary, pos = run_to_end(_world(_pole(34.0, 3.0, at=8.0)), log_path=log)
    a = summary["agents"][0]
    assert a["arrived"] and a["final_mode"] == "arrived" and a["collisions"] == 0, a
    assert a["evasions"] == 0 and not events_of(log, "evade_start")
    k = int(round(a["arrival_time"] / 0.1))
    assert np.ptp(np.array(pos)[k:, 0], axis=0).max() == 0.0


def test_a_pole_aimed_at_an_arrived_agent_misses_it(tmp_path):
    """The pole runs through the goal: the agent gets out of its way and comes back."""
    log = tmp_path / "aimed-pole.mcap"
    _, summary, _ = run_to_end(_world(_pole(30.0, 3.0, at=8.0)), log_path=log)
    a = summary["agents"][0]
    assert a["arrived"] and a["final_mode"] == "arrived", a
    assert a["collisions"] == 0 and summary["collisions"] == 0, summary
    assert a["evasions"] >= 1 and a["min_obstacle_clearance"] > 0.5, a
    problems, _notes, stats = audit(log)
    assert not problems and stats["collisions"] == 0, problems


def test_a_pole_aimed_at_an_arrived_fixed_wing_misses_it(tmp_path):
    """A pole aimed at where the loitering aircraft is at t = 15 s (from a calm run) does not
    touch it."""
    far = {"position": [90.0, 5.0, 20.0], "motion": {"type": "linear", "velocity": [0.0, 0.1, 0.0]}}
    _, track = _fixed_wing_after_arrival(far, tmp_path / "calm.mcap")
    at = track[150]
    aimed = {**_pole(float(at[0]), 6.0, at=15.0), "position": [float(at[0]), float(at[1]) - 90.0, 20.0]}
    log = tmp_path / "aimed-pole-fw.mcap"
    summary, _ = _fixed_wing_after_arrival(aimed, log)
    a = summary["agents"][0]
    assert a["arrived"] and a["collisions"] == 0 and summary["collisions"] == 0, summary
    problems, _notes, stats = replay_audit(log, allow_failure=True)
    assert stats["collisions"] == 0, stats


def test_the_surface_approach_is_exact_on_a_ball():
    """A unit ball at the origin moving along +x past points 2 m off its line: the closest
    approach when it passes them, or at the horizon's end when it cannot get there."""
    from swarmplan.sim.evasion import surface_approach

    def distance(points, movers):  # noqa: ANN001, ANN202, ARG001
        return np.linalg.norm(points, axis=1) - 1.0

    points = np.array([[5.0, 2.0, 0.0], [5.0, 0.0, 2.0], [-3.0, 2.0, 0.0]])
    w = np.array([[1.0, 0.0, 0.0]] * 3)
    t, d = surface_approach(distance, points, np.zeros(3, dtype=int), w, np.array([10.0, 3.0, 10.0]))
    np.testing.assert_allclose(t, [5.0, 3.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(d, [1.0, np.hypot(2.0, 2.0) - 1.0, np.hypot(3.0, 2.0) - 1.0], atol=1e-9)


def _at_the_face(velocity: list[float], passes: list[float]):
    """Agent 'a' parks 1 m from the flight volume's face x = 0 (its body touches the face's
    plane); a 2 m truck at ``velocity`` passes through ``passes`` at t = 8 s, on the agent's
    inner side: the way away from its path leads out of the volume."""
    v = np.array(velocity)
    raw = base_world(
        sim={"dt": 0.1, "max_time": 30, "goal_tolerance": 0.5},
        obstacles=[
            {
                "id": "truck",
                "shape": "sphere",
                "radius": 2.0,
                "position": (np.array(passes) - 8.0 * v).tolist(),
                "motion": {"type": "linear", "velocity": velocity},
            }
        ],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [1.0, 50, 20]},
            {"id": "b", "start": [10, 90, 20], "goal": [90, 90, 20], "speed": {"max": 3, "cruise": 3}},
        ],
    )
    return make_world(raw)


def test_an_agent_pressed_against_a_face_of_the_volume_dodges_along_it(tmp_path):
    """Straight across the face (the way out is through it) and at a slant (part of it is): the
    agent moves along the face, never holds at it, and is back at its goal after the truck."""
    for velocity, passes in (([0.0, 3.0, 0.0], [2.5, 50.0, 20.0]), ([-2.0, 2.0, 0.0], [3.0, 52.0, 20.0])):
        log = tmp_path / f"face-{velocity[0]}.mcap"
        _, summary, pos = run_to_end(_at_the_face(velocity, passes), log_path=log)
        a = summary["agents"][0]
        assert a["collisions"] == 0 and summary["collisions"] == 0, (velocity, summary)
        assert a["evasions"] >= 1 and a["final_mode"] == "arrived", (velocity, a)
        assert a["min_obstacle_clearance"] > 0.0, a
        track = np.array(pos)[:, 0]
        assert track[:, 0].min() >= 0.0  # inside the volume throughout
        problems, _notes, stats = audit(log)
        assert not problems and stats["collisions"] == 0, problems
