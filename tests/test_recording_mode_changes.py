"""Modes changing between steps: the agents' pieces written again in place (``/agents/state``
text, ``/scene`` records) give the bytes of a message made from scratch, with the numbers
written compiled (a swarm-sized world) or by numpy."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader

from swarmplan.core import AgentStates, Mode
from swarmplan.io.recording import McapRecorder
from swarmplan.runtime.compiled import COMPILED_FROM


def _states(n: int, steps: int, seed: int) -> list[tuple[float, AgentStates]]:
    rng = np.random.default_rng(seed)
    ids = tuple(f"uav{i}" for i in range(n))
    goal = np.round(rng.normal(0, 40, (n, 3)), 3)
    pos = rng.normal(0, 40, (n, 3)) + 0.5  # no coordinate 0: the scene's templates are used
    modes = np.array([Mode.APF] * n, dtype=object)
    out = []
    for step in range(steps):
        vel = rng.normal(0, 3, (n, 3))
        pos = pos + vel * 0.1
        modes = modes.copy()
        for i in rng.integers(n, size=rng.integers(0, 4)).tolist():
            modes[i] = list(Mode)[rng.integers(len(Mode))]
        out.append((round(0.1 * step, 9), AgentStates(ids, np.round(pos, 6), np.round(vel, 6), modes, goal)))
    return out


def _messages(path) -> list[tuple[str, int, bytes]]:
    with open(path, "rb") as f:
        return [
            (c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)
        ]


@pytest.mark.parametrize("n", [40, COMPILED_FROM])
def test_mode_changes_write_the_bytes_of_a_fresh_message(tmp_path, n):
    states = _states(n, 30, n)
    world = {"name": "w", "agents": [{"id": a, "goal": [0, 0, 0]} for a in states[0][1].ids], "obstacles": []}
    logs = []
    for kind in ("kept", "fresh"):
        with McapRecorder(tmp_path / f"{kind}.mcap") as rec:
            rec.write_world(world)
            for t, agents in states:
                if kind == "fresh":  # every template made again from the step's agents
                    rec._states._key = None
                    rec._scene._scene_templates = {}
                rec.write_state(t, agents, None)
        logs.append(_messages(tmp_path / f"{kind}.mcap"))
    kept, fresh = logs
    assert kept == fresh
    assert sum(1 for m in kept if m[0] == "/scene") >= 10
    states_json = [json.loads(m[2]) for m in kept if m[0] == "/agents/state"]
    assert [a["mode"] for a in states_json[-1]["agents"]] == [str(m) for m in states[-1][1].mode]
    assert rec._states.compiled == (n >= COMPILED_FROM)
