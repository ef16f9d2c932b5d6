"""The compiled phases of the step (``sim._step_kernels``) give the numpy path's bits.

The braking margin: one compiled call over every multirotor row against the numpy path
(``braking_margin`` with the compiled call declined), on random states of a cluttered
64-agent world with movers: commands towards bodies, the ground and the bounds, near goals,
at rest and beyond the speed limit."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.bench.sim import swarm_world
from swarmplan.flight.kinematics import limit_velocity
from swarmplan.sim import Simulation
from swarmplan.world import parse_world


@pytest.fixture(scope="module")
def sim():
    s = Simulation(parse_world(swarm_world(64, 16, 24, 3)), planner="none")
    s.reset(seed=0)
    return s


def _states(rng: np.random.Generator, sim: Simulation, n: int):
    w = sim.world
    pos = rng.uniform(w.bounds_min + 1.5, w.bounds_max - 1.5, (n, 3))
    near_body = rng.random(n) < 0.5
    bodies = np.array([o.position for o in w.obstacles])[rng.integers(len(w.obstacles), size=n)]
    pos[near_body] = bodies[near_body] + rng.normal(0, 8, (near_body.sum(), 3))
    pos[:, 2] = np.clip(pos[:, 2], 1.2, w.bounds_max[2] - 1.2)
    vel = rng.normal(0, 5, (n, 3)) * (rng.random((n, 1)) < 0.9)
    cmd = np.where(rng.random((n, 1)) < 0.5, bodies - pos, rng.normal(0, 8, (n, 3)))
    cmd *= rng.uniform(0.0, 2.0, (n, 1)) * 12.0 / np.maximum(np.linalg.norm(cmd, axis=1, keepdims=True), 1e-9)
    goal = np.where(rng.random((n, 1)) < 0.3, pos + rng.normal(0, 3, (n, 3)), rng.uniform(0, 100, (n, 3)))
    return pos, vel, cmd, goal


@pytest.mark.parametrize("seed", range(4))
def test_compiled_braking_margin_equals_the_numpy_path(sim, seed, monkeypatch):
    rng = np.random.default_rng(seed)
    n = len(sim.params.ids)
    q0, q1 = sim.obstacles.poses(1.0)[0], sim.obstacles.poses(1.1)[0]
    changed = checked = 0
    for _ in range(10):
        pos, vel, cmd, goal = _states(rng, sim, n)
        idx = np.sort(rng.choice(n, size=int(rng.integers(1, n + 1)), replace=False))
        for g in (goal[idx], None):
            compiled = sim.safety.braking_margin(idx, pos, vel, cmd[idx].copy(), q0, q1, g)
            with monkeypatch.context() as m:
                m.setattr(type(sim.safety), "_braking_margin_compiled", lambda *a, **k: None)
                reference = sim.safety.braking_margin(idx, pos, vel, cmd[idx].copy(), q0, q1, g)
            np.testing.assert_array_equal(compiled, reference)
            if g is not None:  # the velocities the step flies, from the same call
                command, velocity, free = sim.safety.brake_and_limit(
                    idx, pos, vel, cmd[idx].copy(), q0, q1, g
                )
                expected = limit_velocity(sim.params, vel[idx], reference, sim.world.dt, idx)
                np.testing.assert_array_equal(command, reference)
                np.testing.assert_array_equal(velocity, expected)
                if free is not None:  # None: a braking sweep went to FCL, the numpy path ran
                    radii = sim.params.radius[idx] + sim.safety.margin(idx)
                    end = pos[idx] + expected * sim.world.dt
                    np.testing.assert_array_equal(free, sim.safety.steps_free(pos[idx], end, radii, q0, q1))
                    checked += 1
            changed += int((reference != cmd[idx]).any(axis=1).sum())
    assert changed > 100  # the margin capped many commands: the test exercised it
    assert checked >= 3


def test_the_compiled_braking_margin_runs_in_swarm_worlds(sim, monkeypatch):
    """At swarm size the step takes the compiled call (the numpy path is its fallback only)."""
    calls = []
    real = type(sim.safety)._braking_margin_compiled

    def spy(*args, **kwargs):
        out = real(*args, **kwargs)
        calls.append(out is not None)
        return out

    monkeypatch.setattr(type(sim.safety), "_braking_margin_compiled", spy)
    s = Simulation(sim.world, planner="none")
    s.reset(seed=0)
    for _ in range(3):
        s.step()
    assert calls and all(calls)


@pytest.mark.parametrize("seed", range(3))
def test_steps_free_answers_as_first_hits(sim, seed):
    """``SafetyFilter.steps_free`` (one compiled call, FCL for what it leaves undecided) says
    free exactly where ``first_hits_fcl`` finds nothing: steps at bodies, movers, the ground and
    the bounds, grazing ones included."""
    from swarmplan.geometry.collision import first_hits_fcl

    rng = np.random.default_rng(seed)
    q0, q1 = sim.obstacles.poses(2.0)[0], sim.obstacles.poses(2.1)[0]
    n = 600
    pos, _, cmd, _ = _states(rng, sim, n)
    end = pos + cmd * rng.choice([0.1, 0.5, 2.0], (n, 1))
    radii = rng.uniform(0.5, 1.5, n)
    free = sim.safety.steps_free(pos, end, radii, q0, q1)
    mv = sim.obstacles.moving_mask
    truth = np.array(
        [h is None for h in first_hits_fcl(sim.obstacles.collision, pos, end, radii, q0[mv], q1[mv])]
    )
    assert 50 < (~truth).sum() < n - 50
    np.testing.assert_array_equal(free, truth)
