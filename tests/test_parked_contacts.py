"""One definition of a contact: an agent that has given up stays in the air, and a moving
obstacle passing through it is a collision for the simulator exactly as for the replay's audit."""

from __future__ import annotations

import numpy as np
from helpers import base_world, make_world, replay_audit, run_to_end

from swarmplan.core import FAILED


class _GiveUp:
    """A planner that gives agent 'a' up when stuck (to put a failed agent in a mover's way);
    agent 'b' flies on, so the run goes on."""

    def on_reset(self, sim):
        return {}

    def on_step(self, sim):
        return {}

    def on_stuck(self, sim, i):
        return FAILED if i == 0 else None


def _world(mover: bool):
    obstacles = []
    if mover:
        # Crosses (16.2, 50, 20), where the agent gives up at t = 2 s, at t = 8 s.
        obstacles.append(
            {
                "id": "truck",
                "shape": "sphere",
                "radius": 2.0,
                "position": [16.2, 10.0, 20.0],
                "motion": {"type": "linear", "velocity": [0.0, 5.0, 0.0]},
            }
        )
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [100, 100, 50]},
        sim={"dt": 0.1, "max_time": 14.0, "goal_tolerance": 1.0},
        obstacles=obstacles,
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20], "speed": {"max": 4, "cruise": 4}},
            {"id": "b", "start": [10, 90, 20], "goal": [90, 90, 20], "speed": {"max": 4, "cruise": 4}},
        ],
        # Stuck after 2 s whatever it does: the planner then gives it up, mid-field.
        planner={"stuck": {"window": 2.0, "min_progress": 1000.0}},
    )
    return make_world(raw)


def test_a_mover_through_a_failed_agent_is_counted_by_the_simulator_and_the_replay(tmp_path):
    log = tmp_path / "run.mcap"
    sim, summary, pos = run_to_end(_world(mover=True), seed=0, log_path=log, planner=_GiveUp())
    agent = summary["agents"][0]
    # It failed (stopped where it was), then the truck drove through it.
    np.testing.assert_allclose(np.array(pos)[-1, 0], [16.2, 50.0, 20.0], atol=0.5)
    assert agent["collisions"] == 1 and agent["collided_with"] == ["truck"], agent
    assert agent["final_mode"] == "collided"
    assert agent["min_obstacle_clearance"] < 0
    problems, _notes, stats = replay_audit(log, allow_failure=True)
    assert stats["collisions"] == 1 and stats["sim_time"] >= 10.0
    assert not [p for p in problems if "vs recorded" in p or "/summary" in p], problems


def sim_failed_at(log) -> float:
    from helpers import events_of

    (failed,) = events_of(log, "failed")
    assert failed["detail"]["reason"]
    return failed["t"]


def test_without_the_mover_the_failed_agent_has_no_contact(tmp_path):
    log = tmp_path / "run.mcap"
    _, summary, _ = run_to_end(_world(mover=False), seed=0, log_path=log, planner=_GiveUp())
    agent = summary["agents"][0]
    assert agent["final_mode"] == "failed" and agent["collisions"] == 0
    assert sim_failed_at(log) == 2.0
    problems, _notes, stats = replay_audit(log, allow_failure=True)
    assert stats["collisions"] == 0
    assert not [p for p in problems if "vs recorded" in p], problems
