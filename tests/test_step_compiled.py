"""The compiled paths of the step give the bits of the paths they replace, on random inputs:
the field's agent term over a window along x against every agent, the commanded velocity and
the reach at speed against their numpy formulas, the roundings of the messages, the
evasion's horizons, and the metrics' step with every agent measured against the general
selection."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import base_world, make_world

import swarmplan.flight.apf as apf
from swarmplan.flight.apf import (
    ApfField,
    FieldInputs,
    Flyers,
    Swarm,
    commanded_velocity,
    commanded_velocity_numpy,
)
from swarmplan.flight.kinematics import AgentParams
from swarmplan.sim.metrics import RunMetrics


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _swarm_world(n: int):
    agents = [
        {"id": f"a{i}", "start": [5.0 + 2.5 * i, 5.0, 30.0], "goal": [5.0 + 2.5 * i, 590.0, 30.0]}
        for i in range(n)
    ]
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [3000, 600, 80]},
        agents=agents,
        agent_defaults={"radius": 1.0, "separation": [4, 4, 2], "min_altitude": 3.0},
        obstacles=[
            {
                "id": "m",
                "shape": "sphere",
                "radius": 5.0,
                "position": [300, 300, 30],
                "motion": {"type": "linear", "velocity": [3.0, 1.0, 0.0]},
            }
        ],
    )
    return make_world(raw)


@pytest.mark.parametrize("seed", range(4))
def test_windowed_agent_term_equals_every_agent(monkeypatch, seed):
    """A dense cluster (more near agents than the short sort takes), lines across and along x,
    fast and resting agents, parked ones, several kinds of agent and fixed wings: the force on
    every flyer has the same bits with the window along x as with every agent tested."""
    n = 300
    world = _swarm_world(n)
    rng = np.random.default_rng(seed)
    params = dataclasses.replace(
        AgentParams.from_world(world),
        radius=rng.choice([0.5, 1.0, 1.5], n),
        separation=rng.choice([2.0, 4.0, 6.0], (n, 3)),
        speed_cruise=rng.choice([4.0, 8.0, 10.0], n),
        fixed_wing=rng.random(n) < (0.2 if seed % 2 else 0.0),
    )
    pos = rng.uniform([1, 1, 1], [2999, 599, 79], (n, 3))
    pos[:90] = pos[0] + rng.normal(0, 5.0, (90, 3))  # a dense cluster
    pos[90:150, 0] = pos[90, 0] + rng.normal(0, 0.5, 60)  # a line across x (one window)
    pos[150:210, 1] = pos[150, 1]  # a line along x
    pos = np.clip(pos, 1.0, [2999, 599, 79])
    vel = rng.normal(0, 6.0, (n, 3))
    vel[::7] = 0.0
    vel[1::11] *= 1.0 + seed  # faster than any cruise
    goal = rng.uniform([5, 5, 5], [2995, 595, 75], (n, 3))
    idx = np.arange(n) if seed < 2 else np.sort(rng.choice(n, n - 40, replace=False))
    q = np.array([[300.0, 300.0, 30.0]])
    rel = pos[idx] - q
    d = np.linalg.norm(rel, axis=1)[:, None] - 5.0
    g = (rel / np.linalg.norm(rel, axis=1)[:, None])[:, None, :]
    inputs = FieldInputs(d, g, np.array([[3.0, 1.0, 0.0]]), np.array([True]), np.array([5.0]), q)
    flyers = Flyers(idx, pos[idx], vel[idx], goal[idx])
    swarm = Swarm(pos, vel, rng.random(n) < 0.2, np.linalg.norm(goal - pos, axis=1))
    field = ApfField(world, params)
    monkeypatch.setattr(apf, "WINDOW_FROM", 10**9)
    every = field.forces(flyers, inputs, swarm)
    monkeypatch.setattr(apf, "WINDOW_FROM", 2)
    windowed = field.forces(flyers, inputs, swarm)
    assert (np.linalg.norm(every, axis=1) > 0).all()
    np.testing.assert_array_equal(_bits(windowed), _bits(every))


def _reach_numpy(params: AgentParams, idx: np.ndarray, vel: np.ndarray, dt: float) -> np.ndarray:
    v = np.sqrt(vel[:, 0] * vel[:, 0] + vel[:, 1] * vel[:, 1] + vel[:, 2] * vel[:, 2])
    return v * dt + v * v / (2.0 * np.maximum(params.max_accel[idx], 1e-9))


@pytest.mark.parametrize("seed", range(3))
def test_reach_at_speed_equals_its_formula(seed):
    n = 120
    world = _swarm_world(n)
    rng = np.random.default_rng(seed)
    params = dataclasses.replace(AgentParams.from_world(world), max_accel=rng.uniform(0.5, 9.0, n))
    field = ApfField(world, params)
    vel = rng.normal(0, 7.0, (n, 3))
    vel[::5] = 0.0
    idx = np.sort(rng.choice(n, 70, replace=False))
    got = field._reach_at_speed(idx, vel[idx])
    np.testing.assert_array_equal(_bits(got), _bits(_reach_numpy(params, idx, vel[idx], world.dt)))
    every = field._reach_at_speed(None, vel)
    np.testing.assert_array_equal(_bits(every), _bits(_reach_numpy(params, np.arange(n), vel, world.dt)))


@pytest.mark.parametrize("seed", range(4))
def test_compiled_commanded_velocity_equals_numpy(seed):
    """Random forces (zero and tiny ones too), goals near and at the agent, clearances below
    the half-metre cut, infinite and negative, normals facing the motion or away."""
    n = 200
    world = _swarm_world(n)
    rng = np.random.default_rng(seed)
    params = dataclasses.replace(
        AgentParams.from_world(world),
        max_accel=rng.uniform(0.5, 9.0, n),
        speed_cruise=rng.uniform(1.0, 15.0, n),
    )
    idx = np.sort(rng.choice(n, 150, replace=False))
    m = len(idx)
    force = rng.normal(0, 3.0, (m, 3))
    force[::9] = 0.0
    force[1::13] *= 1e-12
    pos = rng.uniform(0, 100, (m, 3))
    goal = pos + rng.normal(0, 20.0, (m, 3)) * rng.choice([0.0, 0.01, 1.0], (m, 1))
    clearance = rng.choice([-1.0, 0.2, 0.5, 3.0, 40.0, np.inf], m) * rng.uniform(0.5, 1.5, m)
    normal = rng.normal(0, 1.0, (m, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal[::4] = -force[::4] / np.maximum(np.linalg.norm(force[::4], axis=1, keepdims=True), 1e-9)
    got = commanded_velocity(params, idx, force, pos, goal, clearance, normal, 0.1)
    ref = commanded_velocity_numpy(params, idx, force, pos, goal, clearance, normal, 0.1)
    assert np.isfinite(ref).all()
    np.testing.assert_array_equal(_bits(got), _bits(ref))


@pytest.mark.parametrize("seed", range(3))
def test_metrics_step_with_every_agent_measured_equals_the_selection(seed):
    """Every agent measured: the same bits as the selection ``np.where(active, new, old)``."""
    rng = np.random.default_rng(seed)
    n = 50
    m = RunMetrics(tuple(f"a{i}" for i in range(n)), 3)
    active = np.ones(n, bool)
    ref = {
        name: getattr(m, name).copy()
        for name in ("path_length", "min_clearance", "min_agent_clearance", "min_terrain_clearance")
    }
    for _ in range(5):
        pos0, pos1 = rng.normal(0, 10.0, (n, 3)), rng.normal(0, 10.0, (n, 3))
        clear = [rng.choice([-1.0, 2.0, np.inf], n) * rng.uniform(0.5, 2.0, n) for _ in range(3)]
        m.add_step(pos0, pos1, active, *clear)
        ref["path_length"] += np.where(active, np.linalg.norm(pos1 - pos0, axis=1), 0.0)
        for name, c in zip(
            ("min_clearance", "min_agent_clearance", "min_terrain_clearance"), clear, strict=True
        ):
            ref[name] = np.where(active, np.minimum(ref[name], c), ref[name])
    for name, value in ref.items():
        np.testing.assert_array_equal(_bits(getattr(m, name)), _bits(value))


@pytest.mark.parametrize("seed", range(3))
def test_compiled_rounding_equals_numpy(seed):
    """Both arrays of an ``/agents/state`` message rounded in one compiled call: numpy's bits,
    ties at the sixth decimal, negative zeros, large and tiny values included."""
    from swarmplan.sim.safety import step_kernels

    rng = np.random.default_rng(seed)
    a = rng.normal(0, 100.0, (300, 3)) * rng.choice([1e-9, 1e-3, 1.0, 1e4], (300, 1))
    b = rng.normal(0, 10.0, (300, 3))
    a[:40] = np.round(a[:40], 7) + 5e-7  # ties and near-ties at the sixth decimal
    b[:40] = (rng.integers(-(10**7), 10**7, (40, 3)) + 0.5) / 1e6
    b[40:50] = -0.0
    a[50:60] = -1e-8
    ra, rb = step_kernels().round6(a, b)
    np.testing.assert_array_equal(_bits(ra), _bits(np.round(a, 6)))
    np.testing.assert_array_equal(_bits(rb), _bits(np.round(b, 6)))


@pytest.mark.parametrize("seed", range(3))
def test_compiled_evasion_horizons_equal_numpy(seed):
    """The evasion's horizons (``HORIZON_FACTOR * sideways_time(...) + 3 dt``) in one
    compiled pass: numpy's bits, on both sides of the top-speed switch and at zero distance."""
    from swarmplan.runtime.compiled import kernel_module
    from swarmplan.sim.evasion import HORIZON_FACTOR, sideways_time

    rng = np.random.default_rng(seed)
    n = 400
    radius = rng.uniform(0.0, 3.0, n)
    radius[:5] = 0.0
    amax = rng.uniform(0.0, 10.0, n)
    amax[5:10] = 0.0
    vmax = rng.uniform(0.0, 20.0, n) * rng.choice([1e-3, 1.0], n)
    need = float(rng.choice([0.0, 0.7, 5.0, 40.0]))
    dt = float(rng.choice([0.05, 0.1, 0.2]))
    got = kernel_module("swarmplan.geometry._approach_kernel").horizons(
        need, radius, amax, vmax, HORIZON_FACTOR, 3.0 * dt
    )
    ref = HORIZON_FACTOR * sideways_time(np.float64(need) + radius, amax, vmax) + 3.0 * dt
    np.testing.assert_array_equal(_bits(got), _bits(ref))


def test_mode_masks_equal_the_comparisons():
    """One pass over the modes gives the masks of ``(mode == a) | (mode == b)``; a value that is
    not a mode is an error, as for ``SwarmState.active``."""
    from swarmplan.core import Mode
    from swarmplan.sim.modes import PARKED, mode_in, mode_table

    rng = np.random.default_rng(0)
    mode = np.array(rng.choice(list(Mode), 200).tolist(), dtype=object)
    np.testing.assert_array_equal(mode_in(mode, PARKED), (mode == Mode.ARRIVED) | (mode == Mode.FAILED))
    table = mode_table(Mode.APF, Mode.ARRIVED)
    np.testing.assert_array_equal(mode_in(mode, table), (mode == Mode.APF) | (mode == Mode.ARRIVED))
    mode[3] = None
    with pytest.raises(KeyError):
        mode_in(mode, PARKED)


def test_kept_mode_masks_follow_the_modes():
    """Masks kept for the last modes seen: a mode changed in place, another table, another
    dtype or another state's modes each get their own lookup's answer, and a caller's changes
    to a mask it got do not reach the next caller."""
    from swarmplan.core import Mode, mode_codes
    from swarmplan.sim.modes import ARRIVED, PARKED, mode_in

    rng = np.random.default_rng(1)
    mode = np.array(rng.choice(list(Mode), 64).tolist(), dtype=object)
    first = mode_in(mode, ARRIVED)
    np.testing.assert_array_equal(first, mode == Mode.ARRIVED)
    first[:] = ~first  # the caller's own array
    np.testing.assert_array_equal(mode_in(mode, ARRIVED), mode == Mode.ARRIVED)
    for i in (0, 17, 63):
        mode[i] = Mode.ARRIVED if mode[i] != Mode.ARRIVED else Mode.APF
        np.testing.assert_array_equal(mode_in(mode, ARRIVED), mode == Mode.ARRIVED)
        np.testing.assert_array_equal(mode_in(mode, PARKED), (mode == Mode.ARRIVED) | (mode == Mode.FAILED))
    codes = {m: k for k, m in enumerate(Mode)}
    got = mode_codes(mode, codes, np.int8)
    assert got.dtype == np.int8
    np.testing.assert_array_equal(got, [codes[m] for m in mode.tolist()])
    other = np.array([Mode.APF] * 64, dtype=object)
    assert not mode_in(other, ARRIVED).any()
    assert mode_in(mode, ARRIVED).sum() == int((mode == Mode.ARRIVED).sum())
