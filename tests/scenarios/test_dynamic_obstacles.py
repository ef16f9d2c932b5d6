"""Dynamic-obstacle scenarios: every agent arrives with zero collisions, audited from the log by
``check_log.py`` and confirmed by the simulator's own summary. Each is flown by the default
planner, and no agent is ever stuck in any of them: the refinement planner's escapes start only
from a stuck agent, so pure APF (``none``) and every seed fly the same steps there (held bit for
bit on the crossing: pure APF, another seed).

Timings: agents cruise at 8 m/s from rest (4 m/s^2), so they pass x = 70 at about 9 s and
x = 130 at about 16.5 s; the movers are placed to be there then.
"""

from __future__ import annotations

import numpy as np
from helpers import log_positions

from .conftest import DEFAULT, scenario_world


def sphere_mover(oid, position, velocity, radius=3.0):
    return {
        "id": oid,
        "shape": "sphere",
        "radius": radius,
        "position": list(position),
        "motion": {"type": "linear", "velocity": list(velocity)},
    }


CROSSING = scenario_world(
    "crossing",
    agents=[
        {"id": "uav1", "start": [10, 60, 20], "goal": [190, 60, 20]},
        {"id": "uav2", "start": [10, 30, 22], "goal": [190, 30, 22]},
    ],
    movers=[
        # Crosses uav1's line (y = 60) at x = 70 around t = 9 s, then uav2's (y = 30) at t = 14 s.
        sphere_mover("crosser_a", [70, 114, 20], [0, -6, 0]),
        # Crosses the other way further on, at x = 130, reaching y = 30 around t = 16 s.
        sphere_mover("crosser_b", [130, -66, 21], [0, 6, 0], radius=2.5),
    ],
)

HEAD_ON = scenario_world(
    "head-on",
    agents=[{"id": "uav1", "start": [10, 60, 20], "goal": [190, 60, 20]}],
    movers=[
        # Straight at the agent along its own line, same height: closing speed 14 m/s.
        sphere_mover("intruder", [170, 60, 20], [-6, 0, 0]),
    ],
)

OVERTAKING = scenario_world(
    "overtaking",
    agents=[{"id": "uav1", "start": [10, 60, 20], "goal": [190, 60, 20]}],
    movers=[
        # A slower body ahead in the same direction, on the agent's line.
        sphere_mover("slowpoke", [40, 60, 20], [3, 0, 0], radius=2.5),
    ],
)

SEVERAL = scenario_world(
    "several-movers",
    agents=[
        {"id": "uav1", "start": [10, 60, 20], "goal": [190, 60, 20]},
        {"id": "uav2", "start": [190, 90, 20], "goal": [10, 90, 20]},
        {"id": "uav3", "start": [100, 10, 20], "goal": [100, 110, 25]},
    ],
    movers=[
        sphere_mover("cross", [60, 110, 20], [0, -5, 0]),
        sphere_mover("headon", [160, 60, 21], [-5, 0, 0], radius=2.0),
        {
            "id": "orbit",
            "shape": "sphere",
            "radius": 3,
            "position": [125, 60, 20],
            "motion": {"type": "circle", "center": [100, 60, 20], "radius": 25, "angular_speed": 0.25},
        },
        {
            "id": "patrol",
            "shape": "box",
            "size": [4, 4, 4],
            "position": [40, 90, 20],
            "motion": {"type": "waypoints", "waypoints": [[160, 90, 20]], "speed": 5, "loop": True},
        },
    ],
)


def lateral_deviation(log, agent: int = 0) -> float:
    """Largest distance of the flown path from the agent's straight start-goal line."""
    _ids, _t, p = log_positions(log)
    a, b = p[0, agent], p[-1, agent]
    u = (b - a) / np.linalg.norm(b - a)
    rel = p[:, agent] - a
    return float(np.linalg.norm(rel - np.outer(rel @ u, u), axis=1).max())


def _never_stuck(summary: dict) -> None:
    assert [a["stuck_events"] for a in summary["agents"]] == [0] * len(summary["agents"])
    assert sum(a["escapes"] for a in summary["agents"]) == 0


def test_crossing(run_scenario):
    summary, log = run_scenario(CROSSING, DEFAULT)
    _never_stuck(summary)
    _, _, p = log_positions(log)
    _, _, p_apf = log_positions(run_scenario(CROSSING, "apf", 1)[1])  # pure APF, another seed
    assert p_apf.tobytes() == p.tobytes()


def test_head_on(run_scenario):
    summary, log = run_scenario(HEAD_ON, DEFAULT)
    _never_stuck(summary)
    # The intruder sat on the agent's line: arriving means it stepped aside.
    assert lateral_deviation(log) > 3.0


def test_overtaking(run_scenario):
    summary, log = run_scenario(OVERTAKING, DEFAULT)
    _never_stuck(summary)
    assert lateral_deviation(log) > 3.0
    # The slower body is overtaken, not followed: the run takes far less than its 50 s trip.
    assert summary["agents"][0]["arrival_time"] < 40


def test_several_movers(run_scenario):
    _never_stuck(run_scenario(SEVERAL, DEFAULT)[0])


FOUR_WAY = scenario_world(
    "four-way",
    agents=[
        {"id": "u1", "start": [10, 60, 20], "goal": [190, 60, 20]},
        {"id": "u2", "start": [190, 60, 20], "goal": [10, 60, 20]},
        {"id": "u3", "start": [100, 5, 20], "goal": [100, 115, 20]},
        {"id": "u4", "start": [100, 115, 22], "goal": [100, 5, 22]},
    ],
    movers=[
        sphere_mover("diag_a", [40, 100, 20], [4, -3, 0]),
        sphere_mover("diag_b", [160, 20, 20], [-4, 3, 0]),
    ],
)

FROM_BEHIND = scenario_world(
    "from-behind",
    agents=[{"id": "uav1", "start": [30, 60, 20], "goal": [190, 60, 20]}],
    # Faster than the agent's top speed, on its line, catching up from behind.
    movers=[sphere_mover("chaser", [5, 60, 20], [14, 0, 0])],
)


def test_four_way_with_diagonal_movers(run_scenario):
    _never_stuck(run_scenario(FOUR_WAY, DEFAULT)[0])


def test_faster_mover_from_behind(run_scenario):
    summary, log = run_scenario(FROM_BEHIND, DEFAULT)
    _never_stuck(summary)
    assert lateral_deviation(log) > 3.0
