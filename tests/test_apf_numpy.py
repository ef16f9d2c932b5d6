"""The numpy field (the first calls of worlds below swarm size) writes the same bits as the
compiled kernel on the random swarms of tests/test_apf_compiled.py (edge cases included:
coincident agents, agents inside bodies and at their surface, at their goals, head-on with
movers, parked agents, fixed wings, several goal powers) and over a whole small run; the
world's size and the field's count of calls choose the implementation."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from helpers import base_world, make_world
from test_apf_compiled import N, _inputs, _world

from swarmplan.flight import _apf_numpy, apf
from swarmplan.flight.apf import ApfField, FieldInputs, Flyers, Swarm
from swarmplan.flight.kinematics import AgentParams
from swarmplan.runtime.compiled import COMPILED_FROM, FIELD_NUMPY_CALLS, kernel_module


def _both(
    field: ApfField, flyers: Flyers, inputs: FieldInputs, swarm: Swarm
) -> tuple[np.ndarray, np.ndarray]:
    """The field's force through each implementation (ApfField.forces with its choice forced)."""
    out = []
    for compiled in (True, False):
        field._numpy_calls = 0 if compiled else 1
        with _numpy_while_numba_loaded():
            out.append(field.forces(flyers, inputs, swarm))
    assert field._numpy_calls == 0 or len(flyers.idx) == 0  # the numpy call was made
    return out[0], out[1]


@contextmanager
def _numpy_while_numba_loaded() -> Iterator[None]:
    """The field's numpy path also in this process, where numba is loaded."""
    saved = apf.use_numpy_twin
    apf.use_numpy_twin = lambda n_agents=None: True
    try:
        yield
    finally:
        apf.use_numpy_twin = saved


def _same_bits(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("peaks", [False, True])
@pytest.mark.parametrize("power", [2.0, 1.5, 3.0, 1.0])
def test_numpy_field_has_the_kernels_bits(peaks, power):
    world = _world(peaks, {"goal_power": power})
    params, pos, vel, goal, f, rng = _inputs(world, int(power * 10) + peaks)
    field = ApfField(world, params)
    touched = 0
    for case in range(5):
        idx = np.arange(N) if case == 0 else np.sort(rng.choice(N, N - 17, replace=False))
        target = None if case < 2 else goal[idx] + rng.normal(0, 5.0, (len(idx), 3))
        if case >= 3:
            target[::3] = goal[idx][::3]
        scale = None if case < 3 else rng.uniform(0.2, 1.0, len(idx))
        if case == 4:  # goals beyond the bodies, so their push holds agents and turns them
            target = None
            goal = pos + np.array([0.0, 60.0, 0.0])
        inputs = FieldInputs(f[0][idx], f[1][idx], *f[2:])
        parked = None if case < 2 else rng.random(N) < 0.3
        to_go = None if case < 2 else np.linalg.norm(goal - pos, axis=1)
        flyers = Flyers(idx, pos[idx], vel[idx], goal[idx], target, scale)
        # From case 3, every fourth agent loiters about its goal and gives way (Swarm.yields).
        yields = None if case < 3 else np.arange(N) % 4 == 1
        compiled, plain = _both(field, flyers, inputs, Swarm(pos, vel, parked, to_go, yields=yields))
        assert np.all(np.isfinite(compiled))
        _same_bits(plain, compiled)
        touched += int(np.abs(compiled).sum() > 0)
    assert touched == 5


def test_numpy_field_on_degenerate_inputs():
    """No flyer, no body, a single agent: the kernel's answers, bit for bit."""
    world = _world(False)
    params, pos, vel, goal, f, _ = _inputs(world, 7)
    field = ApfField(world, params)
    empty = FieldInputs(np.zeros((N, 0)), np.zeros((N, 0, 3)), np.zeros((0, 3)), np.zeros(0, bool),
                        np.zeros(0), np.zeros((0, 3)))  # fmt: skip
    idx = np.arange(N)
    compiled, plain = _both(field, Flyers(idx, pos, vel, goal), empty, Swarm(pos, vel))
    _same_bits(plain, compiled)
    one = Flyers(idx[:1], pos[:1], vel[:1], goal[:1])
    inputs = FieldInputs(f[0][:1], f[1][:1], *f[2:])
    compiled, plain = _both(field, one, inputs, Swarm(pos[:1], vel[:1]))
    _same_bits(plain, compiled)
    none = Flyers(idx[:0], pos[:0], vel[:0], goal[:0])
    inputs = FieldInputs(f[0][:0], f[1][:0], *f[2:])
    assert _both(field, none, inputs, Swarm(pos, vel))[1].shape == (0, 3)


def test_world_size_and_calls_choose_the_implementation(monkeypatch):
    """At swarm size the field runs compiled from its first call; below it, its first
    ``FIELD_NUMPY_CALLS`` calls run numpy and the later ones compiled, unless numba is in the
    process already (then compiled from the first call)."""
    from swarmplan.runtime import compiled

    loaded = [False]
    monkeypatch.setattr(compiled, "numba_loaded", lambda: loaded[0])
    swarm = _world(False)
    assert len(swarm.agents) >= COMPILED_FROM  # the random-swarm world is at swarm size
    assert ApfField(swarm, _inputs(swarm, 0)[0])._numpy_calls == 0
    agents = [
        {"id": f"a{i}", "start": [10.0 + 3 * i, 10, 30], "goal": [10.0 + 3 * i, 90, 30]}
        for i in range(COMPILED_FROM - 1)
    ]
    few = make_world(base_world(bounds={"min": [0, 0, 0], "max": [300, 100, 60]}, agents=agents))
    field = ApfField(few, AgentParams.from_world(few))
    calls = []
    kernel = kernel_module("swarmplan.flight._apf_kernel")
    for module, name in ((_apf_numpy, "numpy"), (kernel, "compiled")):
        real = module.apf_forces
        monkeypatch.setattr(module, "apf_forces", lambda *a, _r=real, _n=name: calls.append(_n) or _r(*a))
    n = len(agents)
    pos = np.array([a["start"] for a in agents], float)
    vel = np.zeros_like(pos)
    goal = np.array([a["goal"] for a in agents], float)
    empty = FieldInputs(np.zeros((n, 0)), np.zeros((n, 0, 3)), np.zeros((0, 3)), np.zeros(0, bool),
                        np.zeros(0), np.zeros((0, 3)))  # fmt: skip
    results = [
        field.forces(Flyers(np.arange(n), pos, vel, goal), empty, Swarm(pos, vel))
        for _ in range(FIELD_NUMPY_CALLS + 2)
    ]
    assert calls == ["numpy"] * FIELD_NUMPY_CALLS + ["compiled"] * 2
    _same_bits(results[0], results[-1])
    calls.clear()
    loaded[0] = True
    field = ApfField(few, AgentParams.from_world(few))
    _same_bits(field.forces(Flyers(np.arange(n), pos, vel, goal), empty, Swarm(pos, vel)), results[0])
    assert calls == ["compiled"]


def test_a_small_world_steps_without_numba():
    """A fresh interpreter builds, resets and steps the 16-agent start-up world (movers and
    static bodies; the bare field, so that only the step is judged, not the guide's start-up)
    without importing numba or scipy.spatial."""
    code = (
        "import sys\n"
        "from swarmplan.bench.sim import swarm_world\n"
        "from swarmplan.planner import make_planner\n"
        "from swarmplan.sim import Simulation\n"
        "from swarmplan.world import parse_world\n"
        "raw = swarm_world(16, 4, 8)\n"
        "raw.setdefault('planner', {}).setdefault('apf', {})['guide'] = False\n"
        "w = parse_world(raw)\n"
        "s = Simulation(w, planner=make_planner(w))\n"
        "s.reset(seed=0); s.step(); s.step()\n"
        "print(sorted(m for m in ('numba', 'llvmlite', 'scipy.spatial', 'yaml') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_small_swarm_flies_the_same_on_both_fields():
    """A 16-agent world (4 movers, 8 static bodies) stepped with the compiled field and with the
    numpy field: the same positions, velocities and events at every step."""
    from swarmplan.bench.sim import swarm_world
    from swarmplan.planner import make_planner
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    world = parse_world(swarm_world(16, 4, 8))
    runs = []
    for compiled in (True, False):
        sim = Simulation(world, planner=make_planner(world))
        sim.apf._numpy_calls = 0 if compiled else 10**9
        sim.reset(seed=0)
        steps = []
        with _numpy_while_numba_loaded():
            for _ in range(120):
                r = sim.step()
                steps.append(
                    (r.state.position.copy(), r.state.velocity.copy(), [(e.kind, e.agent) for e in r.events])
                )
                if r.terminated or r.truncated:
                    break
        assert sim.apf._numpy_calls == (0 if compiled else 10**9 - len(steps))  # the path each run took
        runs.append(steps)
    assert len(runs[0]) == len(runs[1]) > 50
    for (p0, v0, e0), (p1, v1, e1) in zip(*runs, strict=True):
        _same_bits(p0, p1)
        _same_bits(v0, v1)
        assert e0 == e1
    assert np.abs(runs[0][-1][0] - runs[0][0][0]).max() > 10.0  # the agents went somewhere


def test_each_flyers_own_view_of_the_swarm():
    """With ``Swarm.known`` every flyer reads its own rows (its beliefs of the swarm): the force
    on each is the force it gets alone on a shared swarm of its rows with the agents it does not
    know of far away, bit for bit, in both implementations; moving bodies at distance inf (out
    of its sight) change its force and keep it finite."""
    world = _world(False)
    params, pos, vel, goal, f, rng = _inputs(world, 3)
    field = ApfField(world, params)
    idx = np.sort(rng.choice(N, 12, replace=False))
    n, rows = len(idx), np.arange(12)
    # Each flyer believes the swarm moved on by its own noise, and does not know of some agents.
    bpos = pos[None] + rng.normal(0.0, 2.0, (n, N, 3))
    bvel = vel[None] + rng.normal(0.0, 1.0, (n, N, 3))
    bpos[rows, idx], bvel[rows, idx] = pos[idx], vel[idx]
    parked = rng.random((n, N)) < 0.3
    to_go = rng.uniform(0.0, 80.0, (n, N))
    known = rng.random((n, N)) < 0.8
    known[rows, idx] = True
    inputs = FieldInputs(f[0][idx], f[1][idx], *f[2:])
    flyers = Flyers(idx, pos[idx], vel[idx], goal[idx])
    # As a table: flyer k's belief of agent b in row k N + b.
    view = np.where(known, np.arange(n * N).reshape(n, N), -1)
    table = (bpos.reshape(-1, 3), bvel.reshape(-1, 3), parked.reshape(-1), to_go.reshape(-1))
    yields = np.arange(N) % 4 == 1  # every fourth agent loiters about its goal and gives way
    believed = Swarm(*table, view, np.tile(np.arange(N), n), yields=np.tile(yields, n))
    compiled, plain = _both(field, flyers, inputs, believed)
    _same_bits(plain, compiled)
    assert np.all(np.isfinite(compiled)) and np.abs(compiled).sum() > 0
    for k, i in enumerate(idx):
        away = bpos[k].copy()
        away[~known[k]] = 1e7 + 100.0 * np.arange(N)[~known[k], None]
        one = field.forces(
            Flyers(idx[k : k + 1], pos[i : i + 1], vel[i : i + 1], goal[i : i + 1]),
            FieldInputs(f[0][i : i + 1], f[1][i : i + 1], *f[2:]),
            Swarm(away, bvel[k], parked[k], to_go[k], yields=yields),
        )
        _same_bits(one[0], compiled[k])
    moving = f[3]
    assert moving.any()
    blind = f[0][idx].copy()
    blind[:, moving] = np.inf
    unseen_c, unseen_p = _both(field, flyers, FieldInputs(blind, f[1][idx], *f[2:]), believed)
    _same_bits(unseen_c, unseen_p)
    assert np.all(np.isfinite(unseen_c))
    assert not np.array_equal(compiled, unseen_c)


def test_doubt_widens_the_separation():
    """A row's doubt (how far its agent may be from where it is believed) widens the pair's
    separation ellipsoid on every axis: random doubts give the kernel's bits in numpy, and
    one doubt on every row gives the force of a shared swarm whose separation is that much
    wider (the same sums in the same order, to rounding)."""
    from dataclasses import replace

    world = _world(False)
    params, pos, vel, goal, f, rng = _inputs(world, 5)
    field = ApfField(world, params)
    idx = np.sort(rng.choice(N, 12, replace=False))
    n = len(idx)
    inputs = FieldInputs(f[0][idx], f[1][idx], *f[2:])
    flyers = Flyers(idx, pos[idx], vel[idx], goal[idx])
    view = np.tile(np.arange(N), (n, 1))  # every flyer believes the truth, in one table
    doubt = rng.uniform(0.0, 2.0, N)
    compiled, plain = _both(field, flyers, inputs, Swarm(pos, vel, None, None, view, np.arange(N), doubt))
    _same_bits(plain, compiled)
    sure = field.forces(flyers, inputs, Swarm(pos, vel, None, None, view, np.arange(N), np.zeros(N)))
    assert not np.allclose(compiled, sure)
    _same_bits(sure, field.forces(flyers, inputs, Swarm(pos, vel)))
    wide = ApfField(world, replace(params, separation=params.separation + 0.7))
    believed = field.forces(flyers, inputs, Swarm(pos, vel, None, None, view, np.arange(N), np.full(N, 0.7)))
    np.testing.assert_allclose(believed, wide.forces(flyers, inputs, Swarm(pos, vel)), rtol=1e-9, atol=1e-9)


def test_near_agents_put_in_index_order_at_every_count():
    """The window's near agents are summed in index order: short lists by insertion, long ones
    through the marks (left all clear), both giving numpy's sort."""
    from swarmplan.runtime.compiled import kernel_module

    order = kernel_module("swarmplan.flight._apf_kernel")._index_order
    rng = np.random.default_rng(3)
    seen = np.zeros(700, dtype=np.bool_)
    for k in (0, 1, 2, 63, 64, 65, 300, 700):
        rows = np.full(700, -1, dtype=np.int64)
        rows[:k] = rng.permutation(700)[:k]
        want = np.sort(rows[:k])
        order(rows, k, seen)
        np.testing.assert_array_equal(rows[:k], want)
        assert not seen.any()
