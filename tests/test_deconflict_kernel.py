"""The compiled passes of the braking room and of the deconfliction on beliefs (swarm worlds) give
the numpy answers of small worlds: the believed pairs a command closes in on, with their room,
the cuts in order, and the believed motions a step meets."""

from __future__ import annotations

import numpy as np

from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim.deconflict import closing_pairs_numpy, cut_numpy, meetings_numpy


def _case(seed: int) -> tuple:
    rng = np.random.default_rng(seed)
    n, n_all, rows, m = 12, 30, 70, 200
    pos = rng.uniform(0.0, 10.0, (rows, 3))
    at = rng.uniform(0.0, 10.0, (n, 3))
    k = np.sort(rng.integers(0, n, m))
    j = rng.integers(0, n_all, m)
    row = rng.integers(0, rows, m)
    dist = np.linalg.norm(pos[row] - at[k], axis=1)
    dist[::17] = 0.0  # a pair in contact: no direction, left alone
    age = rng.choice([0.0, 0.05, 0.1, 0.3, np.inf], rows)
    own = rng.choice(n_all, n, replace=False).astype(np.int64)
    vel = rng.normal(0.0, 3.0, (rows, 3))
    v_cmd = rng.normal(0.0, 4.0, (n, 3))
    fixed_wing = rng.random(n_all) < 0.2
    max_accel = rng.uniform(1.0, 6.0, n_all)
    checked = rng.uniform(0.1, 0.8, n_all)
    believed = (own, age, pos, vel, at)
    return (k, j, row, dist), believed, v_cmd, (fixed_wing, max_accel, checked)


def test_closing_pairs_and_cuts_compiled_and_numpy_agree():
    kernel = kernel_module("swarmplan.sim._deconflict_kernel")
    found = 0
    for seed in range(6):
        pairs, believed, v_cmd, agents = _case(seed)
        for radius in (0.0, 4.0, 9.0, 100.0):
            want = closing_pairs_numpy(pairs, radius, believed, v_cmd, agents, 0.1)
            got = kernel.closing_pairs(pairs, radius, believed, v_cmd, agents, 0.1)
            for w, g in zip(want, got, strict=True):
                np.testing.assert_array_equal(w, g)
            k, n, room, brake = want
            found += len(k)
            assert (room >= 0.0).all() and (np.diff(k) >= 0).all()
            np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
            assert (np.einsum("ij,ij->i", v_cmd[k], n) > 0.0).all()  # only pairs closed in on
            allowed = np.sqrt(room)  # any cap: the cuts are compared, not the law
            a, b = v_cmd.copy(), v_cmd.copy()
            cut_numpy(a, k, n, allowed)
            kernel.cut(b, k, n, allowed)
            np.testing.assert_array_equal(a, b)
            if len(k):
                assert not np.array_equal(a, v_cmd) or (np.einsum("ij,ij->i", v_cmd[k], n) <= allowed).all()
    assert found > 50  # the cases hold pairs of every kind


def test_a_cut_leaves_the_command_at_the_allowed_speed_along_the_line():
    """One flyer closing in at 5 m/s along x where 3 is allowed: x cut to 3, y kept."""
    out = np.array([[5.0, 2.0, 0.0]])
    k, n, allowed = np.array([0]), np.array([[1.0, 0.0, 0.0]]), np.array([3.0])
    for run in (cut_numpy, kernel_module("swarmplan.sim._deconflict_kernel").cut):
        got = out.copy()
        run(got, k, n, allowed)
        np.testing.assert_array_equal(got, [[3.0, 2.0, 0.0]])


def test_meetings_compiled_and_numpy_agree():
    """Random believed pairs (ages of every kind, the unknown one included), flyers that decide
    or not, steps short and long, with and without pairs agreed within the step: the same
    pairs kept, in order, with the same bits."""
    kernel = kernel_module("swarmplan.sim._deconflict_kernel")
    met = kept = 0
    for seed in range(6):
        (k, j, row, dist), (own, age, pos, vel, _), _, (_, max_accel, checked) = _case(seed)
        rng = np.random.default_rng(100 + seed)
        n_all = len(max_accel)
        pos0 = rng.uniform(0.0, 10.0, (n_all, 3))
        pos1 = pos0 + rng.normal(0.0, 0.6, (n_all, 3))
        pos1[::5] = pos0[::5]  # at rest
        cap = rng.uniform(0.5, 3.0, n_all)
        deciding = rng.random(n_all) < 0.8
        for agreed in (np.zeros((0, 0), dtype=bool), rng.random((n_all, n_all)) < 0.3):
            for radius in (0.0, 4.0, 100.0):
                args = ((k, j, row, dist), radius, (own, age, pos, vel), (pos0, pos1),
                        (max_accel, cap, checked, deciding), agreed, 0.1)  # fmt: skip
                want = meetings_numpy(*args)
                got = kernel.meetings(*args)
                for w, g in zip(want, got, strict=True):
                    np.testing.assert_array_equal(w, g)
                    assert w.dtype == g.dtype
                kept += len(want[0])
                met += int(want[-1].sum())
    assert kept > 100 and met > 10  # the cases keep pairs and meet some
