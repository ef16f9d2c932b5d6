"""The recorder's array path (``AgentStates``) writes the same bytes as its dict path: the
``/agents/state`` JSON (one format for the whole message) and the Foxglove channels (numbers
packed for all agents at once), with the awkward values included: zeros, -0.0, standing
agents, ids that need JSON escaping or hold a '%', every mode."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader

from swarmplan.core import AgentStates, Mode
from swarmplan.io.recording import McapRecorder

IDS = ("a0", "uav-1", 'q"uote', "pct%s%%", "ü", "x" * 150)


def _states(seed: int, steps: int) -> list[tuple[float, AgentStates]]:
    rng = np.random.default_rng(seed)
    n = len(IDS)
    goal = rng.normal(0, 40, (n, 3))
    goal[0] = [1.0, 0.0, -0.0]
    pos = rng.normal(0, 40, (n, 3))
    out = []
    modes = list(Mode)
    for step in range(steps):
        vel = rng.normal(0, 3, (n, 3))
        move = rng.random(n) < 0.7  # the others stand still (same position, zero velocity)
        vel[~move] = 0.0
        if rng.random() < 0.3:
            vel[rng.integers(n), :2] = [1.0, 0.0]  # heading exactly zero
        if rng.random() < 0.3:
            vel[rng.integers(n), :2] = [-0.0, 0.0]
        pos = pos + vel * 0.1
        if rng.random() < 0.4:
            pos[rng.integers(n), rng.integers(3)] = [0.0, -0.0][rng.integers(2)]
        mode = np.array([modes[k] for k in rng.integers(len(modes), size=n)], dtype=object)
        out.append((round(0.1 * step, 9), AgentStates(IDS, np.round(pos, 6), np.round(vel, 6), mode, goal)))
    return out


def _messages(path) -> list[tuple[str, int, bytes]]:
    with open(path, "rb") as f:
        return [
            (c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)
        ]


@pytest.mark.parametrize("seed", range(3))
def test_array_path_writes_the_dict_path_bytes(tmp_path, seed):
    world = {"name": "w", "agents": [{"id": i, "goal": [0, 0, 0]} for i in IDS], "obstacles": []}
    states = _states(seed, 40)
    paths = []
    for kind in ("arrays", "dicts"):
        path = tmp_path / f"{kind}.mcap"
        with McapRecorder(path) as rec:
            rec.write_world(world)
            for t, agents in states:
                rec.write_state(t, agents if kind == "arrays" else agents.dicts(), None)
        paths.append(path)
    fast, slow = (_messages(p) for p in paths)
    assert fast == slow
    topics = {m[0] for m in fast}
    assert {"/agents/state", "/tf", "/scene", "/scene/paths"} <= topics
    # The dict path is json.dumps itself: the message decodes to the entries.
    last = json.loads([m for m in fast if m[0] == "/agents/state"][-1][2])
    assert [a["id"] for a in last["agents"]] == list(IDS)
    assert last["agents"][0]["goal"] == [1.0, 0.0, -0.0]


def test_agent_states_reads_as_the_list_of_dicts():
    t, agents = _states(0, 1)[0]
    dicts = agents.dicts()
    assert list(agents) == dicts
    assert agents[2] == dicts[2] and agents[1:3] == dicts[1:3] and len(agents) == len(IDS)
    assert dicts[0]["mode"] in {str(m) for m in Mode} and type(dicts[0]["mode"]) is str


def test_non_finite_state_is_refused_as_json_refuses_it(tmp_path):
    _, agents = _states(0, 1)[0]
    agents.position[1, 2] = np.nan
    with McapRecorder(tmp_path / "x.mcap") as rec:
        with pytest.raises(ValueError):
            rec.write_state(0.0, agents, None)


def test_many_agents_array_path_writes_the_dict_path_bytes(tmp_path):
    """Enough agents for the numbers to go through numpy (json_floats), modes changing."""
    ids = tuple(f"uav{i}" for i in range(60)) + IDS
    rng = np.random.default_rng(7)
    n = len(ids)
    goal = np.round(rng.normal(0, 40, (n, 3)), 3)
    modes = np.array([Mode.APF] * n, dtype=object)
    pos = rng.normal(0, 40, (n, 3))
    states = []
    for step in range(25):
        vel = rng.normal(0, 3, (n, 3))
        vel[rng.random(n) < 0.2] = 0.0
        vel[rng.integers(n), 1] = 3e-05  # repr writes it with an exponent
        pos = pos + vel * 0.1
        pos[rng.integers(n), rng.integers(3)] = -0.0
        if step % 4 == 0:
            modes = modes.copy()
            modes[rng.integers(n)] = list(Mode)[rng.integers(len(Mode))]
        states.append(
            (round(0.1 * step, 9), AgentStates(ids, np.round(pos, 6), np.round(vel, 6), modes, goal))
        )
    world = {"name": "w", "agents": [{"id": i, "goal": [0, 0, 0]} for i in ids], "obstacles": []}
    out, recorders = [], []
    for kind in ("arrays", "dicts"):
        with McapRecorder(tmp_path / f"{kind}.mcap") as rec:
            rec.write_world(world)
            for t, agents in states:
                rec.write_state(t, agents if kind == "arrays" else agents.dicts(), None)
        out.append([m for m in _messages(tmp_path / f"{kind}.mcap") if m[0] == "/agents/state"])
        recorders.append(rec)
    assert out[0] == out[1] and len(out[0]) == 25
    assert type(recorders[0]._states._text).__name__ == "Interleaved"  # the numpy path ran


def test_comms_message_written_as_json_writes_it():
    """``/comms``: the bytes of ``json.dumps`` with compact separators, for ages of every kind
    (null, whole steps, many decimals, tiny, large) and ids that need escaping."""
    from swarmplan.core import AgentAges
    from swarmplan.io.recording import CommsText, comms_json

    rng = np.random.default_rng(5)
    ages = [None, 0.0, 0.1, 0.30000000000000004, 1.234567, 3e-07, 12345678.5, 0.05]
    prefixes = CommsText()
    for step in range(20):
        agents = [{"id": a, "age": ages[int(rng.integers(len(ages)))]} for a in IDS]
        msg = {"t": round(0.05 * step, 9), "agents": agents, "sent": 7 * step, "lost": step}
        msg["out_of_range"] = 0
        assert comms_json(msg, prefixes) == json.dumps(msg, separators=(",", ":")).encode()
        # The same entries kept as codes into the step's distinct ages: the same bytes.
        distinct = tuple(dict.fromkeys([None, *(a["age"] for a in agents)]))
        code = np.array([distinct.index(a["age"]) for a in agents])
        coded = {**msg, "agents": AgentAges(IDS, distinct, code)}
        assert coded["agents"] == agents and list(coded["agents"]) == agents
        assert comms_json(coded, prefixes) == json.dumps(msg, separators=(",", ":")).encode()
    assert comms_json({"t": 0.0, "agents": [], "sent": 0, "lost": 0, "out_of_range": 0}, CommsText()) == (
        b'{"t":0.0,"agents":[],"sent":0,"lost":0,"out_of_range":0}'
    )
