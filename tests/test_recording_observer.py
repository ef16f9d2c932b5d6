"""Recording observes: the simulation names no recorder, every message of a log comes out of
the reset and step results, and the runner owns the log from open to ``/summary`` to close."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest
from helpers import crossing_with_drone, make_world

import swarmplan.sim
from swarmplan.io.runner import RecordingObserver, run_episode
from swarmplan.sim import Simulation

SIM_DIR = Path(swarmplan.sim.__file__).parent


class _Calls:
    """A recorder that notes its calls in order."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, object]] = []

    def write_world(self, world):
        self.calls.append(("world", world["name"]))

    def write_state(self, t, agents, obstacles):
        self.calls.append(("state", (t, len(agents), None if obstacles is None else len(obstacles))))

    def write_event(self, event):
        self.calls.append(("event", event["kind"]))

    def write_optimizer(self, msg):
        self.calls.append(("optimizer", msg["purpose"]))

    def write_summary(self, summary):
        self.calls.append(("summary", summary["interrupted"]))

    def close(self):
        self.calls.append(("close", None))


def _world(max_time: float = 3.0):
    return make_world(crossing_with_drone(max_time))


def test_the_simulation_names_no_recorder():
    assert "recorder" not in inspect.signature(Simulation).parameters
    for path in sorted(SIM_DIR.glob("*.py")):
        assert not re.search(r"recorder", path.read_text(), re.IGNORECASE), path.name


def test_the_runner_writes_results_then_summary_then_closes():
    rec = _Calls()
    summary = run_episode(Simulation(_world(), planner="none"), seed=0, recorder=rec)
    kinds = [k for k, _ in rec.calls]
    assert kinds[0] == "world" and kinds[-2:] == ["summary", "close"]
    states = [v for k, v in rec.calls if k == "state"]
    assert states[0] == (0.0, 2, 1) and len(states) == summary["steps"] + 1
    assert rec.calls[-2] == ("summary", False)


def test_a_stop_request_and_an_exception_still_finish_the_log():
    rec = _Calls()
    asked = []

    def stop() -> bool:
        asked.append(1)
        return len(asked) > 5

    summary = run_episode(Simulation(_world(), planner="none"), seed=0, should_stop=stop, recorder=rec)
    assert summary["interrupted"] and rec.calls[-2:] == [("summary", True), ("close", None)]
    assert sum(k == "state" for k, _ in rec.calls) == 6  # t = 0 and five steps

    rec = _Calls()

    class Boom:
        def on_reset(self, result):
            pass

        def on_step(self, result):
            if result.state.step == 3:
                raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        run_episode(Simulation(_world(), planner="none"), seed=0, observers=[Boom()], recorder=rec)
    assert rec.calls[-2:] == [("summary", True), ("close", None)]


def test_results_carry_what_the_log_needs():
    sim = Simulation(_world(), planner="none")
    first = sim.start(seed=0)
    assert first.world["name"] == sim.world.name and first.records == []
    assert first.agents.ids == ("a", "b") and first.obstacles.ids == ("drone",)
    r = sim.step()
    assert r.agents.position.tolist() == r.state.position.round(6).tolist()
    assert r.obstacles.dicts()[0]["position"] == [70.0, 89.5, 20.0]
    observer = RecordingObserver(_Calls())
    observer.on_reset(first)
    observer.on_step(r)
    seen = [k for k, _ in observer.recorder.calls]
    assert seen == ["world", "state", "state"]
