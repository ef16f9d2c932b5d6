"""The evasion's threat pairs from the compiled sweep (only pairs within a threat's reach get
the exact test) are the all-pairs numpy test's, bit for bit: random configurations, pairs
exactly at the bound and a run whose evasion takes the compiled path; and the near misses
found by binary search on the sorted pair keys are the entries into the separation ellipsoids."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from helpers import events_of, run_to_end
from test_evasion import _crossing, _world

from swarmplan.sim import contacts, evasion
from swarmplan.sim.evasion import threat_pairs


def _same(a: tuple, b: tuple) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.shape == y.shape and x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(np.signbit(x), np.signbit(y))


def _both(*args: np.ndarray) -> tuple:
    dense = threat_pairs(*args, compiled=False)
    swept = threat_pairs(*args, compiled=True)
    _same(dense, swept)
    return dense


def _random_case(rng: np.random.Generator, n_r: int, n_t: int, box: float) -> tuple:
    c = rng.uniform(-box, box, (n_t, 3))
    u = rng.normal(0.0, 3.0, (n_t, 3)) * (rng.random((n_t, 1)) < 0.8)  # some stand still
    margin = rng.uniform(0.5, 3.0, n_t)
    rows = np.sort(rng.choice(n_r + n_t, n_r, replace=False)).astype(np.int64)
    who = np.where(rng.random(n_t) < 0.5, -1, rng.choice(rows, n_t)).astype(np.int64)
    radius = rng.uniform(0.1, 0.5, n_r)
    position = rng.uniform(-box, box, (n_r, 3))
    goal = np.where(rng.random((n_r, 1)) < 0.5, position, rng.uniform(-box, box, (n_r, 3)))
    horizon = rng.uniform(0.5, 4.0, n_r)
    return c, u, margin, who, rows, radius, position, goal, horizon


def test_random_configurations_give_the_same_pairs():
    rng = np.random.default_rng(7)
    found = 0
    for n_r, n_t, box in [
        (1, 1, 3.0),
        (1, 5, 3.0),
        (7, 3, 5.0),
        (40, 60, 20.0),
        (200, 90, 60.0),
        (3, 0, 5.0),
    ]:
        for _ in range(5):
            found += len(_both(*_random_case(rng, n_r, n_t, box))[0])
    assert found > 50  # the cases do have threats


def test_pairs_exactly_at_the_bound():
    # need = 1.5 + 0.25 = 1.75; a threat standing 1.75 m off is no threat, one ulp closer is.
    margin, radius, horizon = np.array([1.5, 1.5]), np.array([0.25]), np.array([1.625])
    rows, who, p = np.array([0], np.int64), np.array([-1, -1], np.int64), np.zeros((1, 3))
    far = np.nextafter(1.75, 0.0)
    c = np.array([[1.75, 0.0, 0.0], [0.0, far, 0.0]])
    key, times, misses, _ = _both(c, np.zeros((2, 3)), margin, who, rows, radius, p, p + 50.0, horizon)
    assert key.tolist() == [1] and misses[0, 0] == far and times[0, 0] == 0.0
    # Closing at 2 m/s from 5 m: at the horizon (1.625 s) it is exactly 1.75 m off, the reach's edge.
    u = np.array([[-2.0, 0.0, 0.0], [0.0, -2.0, 0.0]])
    for start, hit in ((5.0, False), (np.nextafter(5.0, 0.0), True), (np.nextafter(5.0, 9.0), False)):
        c = np.array([[start, 0.0, 0.0], [0.0, 40.0, 0.0]])
        key, times, misses, _ = _both(c, u, margin, who, rows, radius, p, p + 50.0, horizon)
        assert key.tolist() == ([0] if hit else []), start
        if hit:
            assert times[0, 0] == 1.625 and misses[0, 0] < 1.75
    # The same at the goal: the pair is a threat to the goal only.
    c = np.array([[50.0 + 1.74, 50.0, 50.0], [0.0, 40.0, 0.0]])
    key, _, misses, _ = _both(c, np.zeros((2, 3)), margin, who, rows, radius, p, p + 50.0, horizon)
    assert key.tolist() == [0] and misses[0, 1] < 1.75 < misses[0, 0]


def test_standing_threats_keep_numpys_zero_times():
    # A threat at rest: its closest approach is now (-0.0 or 0.0 as numpy's clip gives it).
    for n_r in (1, 2):
        for n_t in (1, 2, 5):
            c = np.tile([1.0, 0.0, 0.0], (n_t, 1))
            args = (c, np.zeros((n_t, 3)), np.full(n_t, 1.0), np.full(n_t, -1, np.int64))
            rows = np.arange(n_r, dtype=np.int64)
            p = np.zeros((n_r, 3))
            key, times, _, _ = _both(*args, rows, np.full(n_r, 0.25), p, p, np.full(n_r, 2.0))
            assert len(key) == n_r * n_t and (times == 0.0).all()


@pytest.mark.parametrize("speed", [3.0, 30.0])
def test_a_run_with_the_compiled_pairs_is_the_same_run(tmp_path, monkeypatch, speed):
    world = _world(_crossing(speed, at=8.0))
    base = run_to_end(world, log_path=tmp_path / "dense.mcap")
    monkeypatch.setattr(evasion, "use_compiled_checks", lambda n, fixed_wings=False: True)
    swept = run_to_end(world, log_path=tmp_path / "swept.mcap")
    assert base[1]["agents"][0]["evasions"] == 1
    drop = {"wall_time"}
    assert {k: v for k, v in base[1].items() if k not in drop} == {
        k: v for k, v in swept[1].items() if k not in drop
    }
    np.testing.assert_array_equal(np.array(base[2]), np.array(swept[2]))
    for kind in ("evade_start", "evade_end", "arrived"):
        assert events_of(tmp_path / "dense.mcap", kind) == events_of(tmp_path / "swept.mcap", kind)


@pytest.mark.parametrize("compiled", [False, True])
def test_near_misses_are_the_entries_into_the_separation_ellipsoid(monkeypatch, compiled):
    # A random walk of 60 agents in a small box: each step's near misses are the pairs inside
    # now that were not inside at the step before (all pairs, by hand), in row-major order.
    monkeypatch.setattr(contacts, "use_compiled_checks", lambda n, fixed_wings=False: compiled)
    rng = np.random.default_rng(3)
    n = 60
    params = SimpleNamespace(
        ids=tuple(f"a{i}" for i in range(n)),
        separation=rng.uniform(0.5, 2.0, (n, 3)),
        radius=rng.uniform(0.1, 0.4, n),
        fixed_wing=np.zeros(n, dtype=bool),
    )
    near = contacts.NearMisses(params)
    pos = rng.uniform(0.0, 15.0, (n, 3))
    before: set = set()
    seen = 0
    for step in range(40):
        pos = pos + rng.normal(0.0, 0.4, (n, 3))
        active = rng.random(n) < 0.8
        tally = near.update(pos, active, 0.1 * step)
        scale = (
            np.maximum(params.separation[:, None], params.separation[None])
            + (params.radius[:, None] + params.radius[None])[..., None]
        )
        inside = np.linalg.norm((pos[:, None] - pos[None]) / scale, axis=-1) < 1.0
        inside &= active[:, None] | active[None]
        now = {(i, j) for i, j in zip(*np.nonzero(np.triu(inside, 1)), strict=True)}
        got = [(e.agent, e.detail["other"]) for e in tally.events]
        assert got == [(f"a{i}", f"a{j}") for i, j in sorted(now - before)]
        seen += len(got)
        before = now
    assert seen > 20
