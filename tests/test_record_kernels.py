"""The recorder's compiled pieces write the bytes of its numpy and Python paths: JSON numbers
as ``repr`` writes them, yaw quaternions as ``math`` computes them, and a swarm's whole log
identical with and without them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from helpers import read_log

from swarmplan.io.json_floats import Interleaved, record_kernels


def _values(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = rng.normal(0, 10.0 ** rng.integers(-6, 11, 3000), 3000)
    y = np.round(y, 6) if seed % 2 == 0 else np.round(y, int(rng.integers(0, 10)))
    special = [0.0, -0.0, 1.0, -3.0, 1e-4, -1e-4, 9.9e-5, 5e-06, 1e-06, 0.1, 0.5, 123456.000001, 100.0]
    special += [2.0**33 - 2.0**-20, -(2.0**33) + 0.5, 8589934591.999999, 1000000.0, 0.000100]
    special += [0.000101, -0.010203, 10.000001, 99.99, 100.01, 999999.9, 1234567890.5]  # digit pairs
    y[: len(special)] = special
    return y


@pytest.mark.parametrize("seed", range(4))
def test_compiled_numbers_equal_json(seed):
    y = _values(seed)[:600]
    pieces = [b'{"v":['] + [b","] * (len(y) - 1) + [b"]}"]
    want = json.dumps({"v": y.tolist()}, separators=(",", ":")).encode()
    assert Interleaved(pieces, compiled=True).fill(y) == want
    # values outside the fast form (an exponent, more decimals) go the numpy way: same bytes
    odd = y.copy()
    odd[7] = 1e-7 if seed % 2 else 1.2345678
    assert (
        Interleaved(pieces, compiled=True).fill(odd)
        == json.dumps({"v": odd.tolist()}, separators=(",", ":")).encode()
    )


def test_compiled_small_numbers_take_repr_exponent_form():
    """Below 1e-4 repr writes an exponent (5e-06, 1.2e-05): every such multiple of 1e-6 and
    its negative, compiled (no fallback: the compiled pass alone)."""
    y = np.array([k / 1e6 for k in range(1, 100)] + [-k / 1e6 for k in range(1, 100)] + [1e-4, -0.0])
    pieces = [b"["] + [b","] * (len(y) - 1) + [b"]"]
    assert (
        Interleaved(pieces, compiled=True).fill_compiled(y)
        == json.dumps(y.tolist(), separators=(",", ":")).encode()
    )


def test_compiled_headings_equal_math():
    rng = np.random.default_rng(1)
    vel = rng.normal(0, 5, (5000, 3))
    vel[::7, 0] = 0.0
    vel[::11, 1] = -0.0
    vel[::13, :2] = 0.0  # no horizontal motion: the last heading stays
    slots = rng.permutation(5000).astype(np.intp)
    qz, qw = np.full(5000, 0.25), np.full(5000, 0.5)
    record_kernels().headings(vel, slots, qz, qw)
    for i in range(5000):
        vx, vy = float(vel[i, 0]), float(vel[i, 1])
        if vx or vy:
            half = math.atan2(vy, vx) / 2.0
            assert (qz[slots[i]], qw[slots[i]]) == (math.sin(half), math.cos(half))
        else:
            assert (qz[slots[i]], qw[slots[i]]) == (0.25, 0.5)


def test_a_swarm_log_is_the_same_with_and_without_the_kernels(tmp_path: Path, monkeypatch):
    """64 agents (compiled from the second step) and the same run with the numpy paths forced."""
    from swarmplan.bench.sim import swarm_world
    from swarmplan.io import recording
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import run_episode
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    raw = swarm_world(64, 8, 6, 0)
    raw["sim"]["max_time"] = 3.0
    logs = []
    for compiled in (True, False):
        monkeypatch.setattr(recording, "use_compiled", lambda n, fixed_wings=False, c=compiled: c)
        path = tmp_path / f"{compiled}.mcap"
        run_episode(Simulation(parse_world(raw), planner="none"), 0, recorder=McapRecorder(path))
        logs.append(read_log(path))
    compiled, plain = logs
    assert compiled.keys() == plain.keys() and len(compiled["/agents/state"]) == 31
    for topic in compiled:
        if topic != "/summary":  # wall time
            assert compiled[topic] == plain[topic], topic


def test_a_state_that_is_not_finite_is_refused_compiled_or_not(tmp_path: Path):
    from swarmplan.core import AgentStates, Mode
    from swarmplan.io.recording import McapRecorder

    pos = np.array([[1.0, 2.0, np.nan]])
    agents = AgentStates(("a",), pos, np.zeros((1, 3)), np.array([Mode.APF], dtype=object), np.ones((1, 3)))
    for compiled in (False, True):
        rec = McapRecorder(tmp_path / f"{compiled}.mcap", foxglove=False)
        rec._states.compiled = compiled
        with pytest.raises(ValueError, match="JSON compliant"):
            rec.write_state(0.1, agents, None)
        rec.close()


def test_compiled_numbers_at_the_digit_tables_edges():
    """Whole parts around 10**4 (the four-digit table's end) and fractions with zeros in either
    of their parts (two and four digits), both signs: json's text from the compiled pass alone."""
    wholes = [0, 1, 9, 10, 99, 100, 999, 1000, 9999, 10000, 10001, 99999, 123456789, 2**33 - 1]
    fracs = [0, 1, 9, 10, 100, 1000, 9999, 10000, 10001, 99000, 100000, 120000, 500000, 999999]
    y = np.array([(w * 10**6 + f) / 1e6 for w in wholes for f in fracs if w or f >= 100])
    y = np.concatenate([y, -y])
    pieces = [b"["] + [b","] * (len(y) - 1) + [b"]"]
    got = Interleaved(pieces, compiled=True).fill_compiled(y)
    assert got == json.dumps(y.tolist(), separators=(",", ":")).encode()


def test_compiled_text_between_numbers_of_every_length():
    """The pieces between the numbers, 0 to 300 bytes, come out as they went in, around the
    numbers as ``repr`` writes them."""
    rng = np.random.default_rng(3)
    pieces = [bytes(rng.integers(32, 127, m, dtype=np.uint8)) for m in range(301)]
    y = np.round(rng.normal(0, 50.0, 300), 6)
    want = b"".join(p + repr(float(v)).encode() for p, v in zip(pieces, y, strict=False)) + pieces[-1]
    assert Interleaved(pieces, compiled=True).fill_compiled(y) == want
    rows = Interleaved(pieces[:2] + pieces[-6:] + pieces[100:106], compiled=True)
    a, b = y[1:7].reshape(2, 3), y[7:13].reshape(2, 3)
    values = [y[0], *a[0], *b[0], *a[1], *b[1]]
    want = b"".join(p + repr(float(v)).encode() for p, v in zip(rows._list, values, strict=False))
    assert rows.fill_rows(y[0], a, b) == want + rows._list[-1]


def test_recorded_messages_are_compact_json_with_non_finite_numbers_as_null(tmp_path: Path):
    from mcap.reader import make_reader

    from swarmplan.io.recording import McapRecorder

    finite = {"t": 1.5, "agent": "a", "kind": "stuck", "detail": {"d": [0.1, (2, 3.25)], "n": None}}
    odd = {
        "t": 2.0,
        "agent": None,
        "kind": "x",
        "detail": {"c": math.inf, "v": [1.0, math.nan], "w": (-math.inf,)},
    }
    with McapRecorder(tmp_path / "m.mcap", foxglove=False) as rec:
        rec.write_event(finite)
        rec.write_event(odd)
    with open(tmp_path / "m.mcap", "rb") as f:
        got = [m.data for _, ch, m in make_reader(f).iter_messages() if ch.topic == "/events"]
    assert got[0] == json.dumps(finite, separators=(",", ":")).encode()
    assert json.loads(got[1]) == {
        "t": 2.0,
        "agent": None,
        "kind": "x",
        "detail": {"c": None, "v": [1.0, None], "w": [None]},
    }
