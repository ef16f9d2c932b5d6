"""The live view: ``run --live`` serves the log's channels over the Foxglove WebSocket protocol
(loopback only) to several viewers at once while the log is written; a viewer that joins late
still gets the static scene; Ctrl-C closes the server and the log (``/summary`` interrupted)."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import read_log

from swarmplan.core import ResetResult, StepResult
from swarmplan.io.runner import Pacer

websockets = pytest.importorskip("websockets", reason="the live-view test needs the websockets package")

REPO = Path(__file__).resolve().parents[1]
# The Foxglove WebSocket protocol under its first name and the one foxglove-sdk's server
# negotiates (the same messages); a viewer offers both, as the Foxglove app does.
SUBPROTOCOLS = ("foxglove.websocket.v1", "foxglove.sdk.v1")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def _viewer(port: int, topics: tuple[str, ...], want: int, deadline: float) -> dict[str, list]:
    """Connect (retrying while the server starts), subscribe to ``topics``, collect ``want``
    messages of the first topic: {topic: [(log_time, payload)]}."""
    while True:
        try:
            ws = await websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=list(SUBPROTOCOLS))
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.1)
    got: dict[str, list] = {t: [] for t in topics}
    channels: dict[str, int] = {}
    subscribed: dict[int, str] = {}
    async with ws:
        assert ws.subprotocol in SUBPROTOCOLS
        while len(got[topics[0]]) < want:
            msg = await asyncio.wait_for(ws.recv(), max(0.1, deadline - time.monotonic()))
            if isinstance(msg, str):
                op = json.loads(msg)
                if op["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in op["channels"]})
                    new = [t for t in topics if t in channels and channels[t] not in subscribed.values()]
                    subs = [
                        {"id": len(subscribed) + k + 1, "channelId": channels[t]} for k, t in enumerate(new)
                    ]
                    subscribed.update({s["id"]: t for s, t in zip(subs, new, strict=True)})
                    if subs:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif msg[0] == 0x01:  # message data: subscription id, log time, payload
                sub, log_time = struct.unpack_from("<IQ", msg, 1)
                got[subscribed[sub]].append((log_time, bytes(msg[13:])))
    return got


def test_two_viewers_receive_states_and_ctrl_c_closes_the_log(tmp_path: Path):
    port, log = _free_port(), tmp_path / "live.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "swarmplan.run", str(REPO / "worlds/quickstart.yaml"), "--out", str(log)]
        + ["--live", "--port", str(port), "--speed", "4", "--quiet"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=dict(os.environ),
    )
    try:
        deadline = time.monotonic() + 60.0

        async def both():
            first = _viewer(port, ("/agents/state", "/scene/world"), 5, deadline)
            second = _viewer(port, ("/agents/state",), 3, deadline)
            return await asyncio.gather(first, second)

        one, two = asyncio.run(both())
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, err.decode()
    states = [json.loads(p) for _, p in one["/agents/state"]]
    assert [a["id"] for a in states[0]["agents"]] and all("position" in a for a in states[0]["agents"])
    times = [t for t, _ in one["/agents/state"]]
    assert times == sorted(times) and times == [round(s["t"] * 1e9) for s in states]
    assert len(two["/agents/state"]) >= 3
    assert one["/scene/world"]  # sent at t = 0, before this viewer subscribed: sent again
    msgs = read_log(log)
    assert msgs["/summary"][-1][1]["interrupted"] is True
    logged = {t for t, _ in msgs["/agents/state"]}
    assert set(times) <= logged  # the viewers saw what the log holds


def test_pacer_holds_steps_to_their_time():
    class _State:
        t = 0.0

    pacer = Pacer(speed=4.0)
    pacer.on_reset(ResetResult(_State(), {}, [], None, None))
    start = time.perf_counter()
    state = _State()
    for k in range(1, 5):
        state.t = 0.1 * k
        pacer.on_step(StepResult(state, [], False, False))
    assert 0.1 - 1e-3 <= time.perf_counter() - start < 0.6  # 0.4 s simulated at 4x: 0.1 s
    with pytest.raises(ValueError):
        Pacer(speed=0.0)


def test_the_layout_shows_channels_a_log_has(tmp_path: Path):
    """docs/foxglove-layout.json: a 3D panel on the scene topics, a plot of speeds and the event
    log, every topic it names written by a run (events as foxglove.Log entries)."""
    from foxglove_schemas_protobuf.Log_pb2 import Log
    from helpers import base_world, make_world, run_to_end

    layout = json.loads((REPO / "docs" / "foxglove-layout.json").read_text())
    panels = layout["configById"]
    assert {k.split("!")[0] for k in panels} == {"3D", "Plot", "RosOut"}
    named = set(panels["3D!swarm"]["topics"]) | {panels["RosOut!events"]["topicToRender"]}
    named |= {p["value"].split(".")[0] for p in panels["Plot!speeds"]["paths"]}
    world = make_world(
        base_world(
            sim={"dt": 0.1, "max_time": 30.0, "goal_tolerance": 2.0},
            agents=[{"id": "a", "start": [10, 50, 20], "goal": [40, 50, 20]}],
        )
    )
    log = tmp_path / "run.mcap"
    run_to_end(world, seed=0, log_path=log, foxglove=True)
    msgs = read_log(log)
    assert named <= set(msgs), named - set(msgs)
    entries = [Log.FromString(p) for _, p in msgs["/events/log"]]
    arrived = [e for e in entries if e.message.startswith("arrived")]
    assert len(arrived) == 1 and arrived[0].name == "a" and arrived[0].level == Log.INFO
    speeds = [p for _, p in msgs["/agents/speed"]]
    assert all(0.0 <= s["max"] and s["speed"][0] == s["max"] for s in speeds)


def test_a_closed_log_lets_its_channels_go(tmp_path: Path):
    """A process that records many runs (a sweep worker) keeps none of their channels."""
    from foxglove import channel as foxglove_channel

    from swarmplan.io.recording import McapRecorder

    before = len(foxglove_channel._channels_by_id)
    for k in range(5):
        rec = McapRecorder(tmp_path / f"{k}.mcap")
        rec.write_world({"name": "w", "agents": [], "obstacles": [], "bounds": {}, "seed": 0})
        rec.close()
    assert len(foxglove_channel._channels_by_id) == before


def test_a_viewer_that_unsubscribes_and_leaves_prints_nothing(tmp_path: Path, capfd, caplog):
    """A viewer that connects, subscribes, unsubscribes and closes: the server answers every
    callback the protocol makes (nothing logged, nothing on stderr) and the run goes on."""
    import logging

    from swarmplan.io.sink import LogSink

    caplog.set_level(logging.DEBUG)

    sink = LogSink(tmp_path / "live.mcap", live=("127.0.0.1", 0))
    try:
        channel = sink.register_channel("/a", "json", sink.register_schema("a", "jsonschema", b"{}"))
        sink.add_message(channel, 1, b"{}")

        async def visit() -> int:
            got = 0
            url = f"ws://127.0.0.1:{sink.port}"
            async with websockets.connect(url, subprotocols=list(SUBPROTOCOLS)) as ws:
                ids: dict[str, int] = {}
                while "/a" not in ids:
                    op = json.loads(await asyncio.wait_for(ws.recv(), 10.0))
                    if op["op"] == "advertise":
                        ids.update({c["topic"]: c["id"] for c in op["channels"]})
                subscription = {"id": 1, "channelId": ids["/a"]}
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": [subscription]}))
                for k in range(100):  # until the subscription is in place
                    sink.add_message(channel, 2 + k, b"{}")
                    try:
                        msg = await asyncio.wait_for(ws.recv(), 0.05)
                    except asyncio.TimeoutError:
                        continue
                    if isinstance(msg, bytes) and msg[0] == 0x01:
                        got += 1
                        break
                await ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [1]}))
                await ws.send(json.dumps({"op": "unadvertise", "channelIds": [7]}))
                await asyncio.sleep(0.2)
            await asyncio.sleep(0.3)  # the server sees the viewer leave
            return got

        assert asyncio.run(visit()) == 1
        sink.add_message(channel, 500, b"{}")
    finally:
        sink.close()
    out, err = capfd.readouterr()
    assert err == "" and out == ""
    complaints = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert complaints == []
