"""Behaviour of the baselines: random, PSO, DE, GA (swarmplan/optimizers/baselines.py)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.optimizers import available, make
from swarmplan.optimizers._baseline_kernels import (
    abc_greedy,
    abc_moves,
    de_trials,
    ga_draws,
    ga_mutate,
    ga_offspring,
    partners,
)

D = 10
LOWER = -100.0 * np.ones(D)
UPPER = 100.0 * np.ones(D)
BUDGET = 5000
SEEDS = (0, 1, 2)


def sphere(X: np.ndarray) -> np.ndarray:
    return np.sum(X**2, axis=1)


def shifted_sphere(X: np.ndarray) -> np.ndarray:
    return np.sum((X - 17.0) ** 2, axis=1)


def test_baselines_registered_under_their_names():
    assert {"random", "pso", "de", "ga"} <= set(available())


@pytest.fixture(scope="module")
def random_results() -> dict[int, float]:
    return {s: make("random").minimize(sphere, LOWER, UPPER, max_evals=BUDGET, seed=s).f for s in SEEDS}


# Observed at 5000 evaluations, d = 10, seeds 0-4: random 4.7e3-8.1e3, PSO <= 7.4e-6,
# DE <= 1.0, GA <= 9.9. Thresholds leave one to two orders of magnitude of margin.
@pytest.mark.parametrize(("name", "threshold"), [("pso", 1e-3), ("de", 20.0), ("ga", 100.0)])
def test_beats_random_search_on_sphere(name, threshold, random_results):
    for seed in SEEDS:
        res = make(name).minimize(sphere, LOWER, UPPER, max_evals=BUDGET, seed=seed)
        assert res.f < threshold, (name, seed, res.f)
        assert res.f < 1e-2 * random_results[seed], (name, seed, res.f, random_results[seed])


@pytest.mark.parametrize(("name", "threshold"), [("pso", 1e-3), ("de", 20.0), ("ga", 100.0)])
def test_no_centre_bias_on_shifted_sphere(name, threshold):
    # Same thresholds as the centred sphere: a baseline must not depend on the optimum being at 0.
    res = make(name).minimize(shifted_sphere, LOWER, UPPER, max_evals=BUDGET, seed=0)
    assert res.f < threshold
    assert np.allclose(res.x, 17.0, atol=5.0)


def test_pso_defaults_are_the_inertia_weight_settings():
    p = make("pso").params
    assert p["w"] == pytest.approx(0.7298)
    assert p["c1"] == p["c2"] == pytest.approx(1.49618)


def test_de_defaults():
    p = make("de").params
    assert (p["F"], p["CR"]) == (0.5, 0.9)


def test_ga_keeps_its_elite():
    # With elitism the best cost of the population never gets worse: history is the best
    # ever found anyway, so check the population directly through the state.
    ga = make("ga", population=20)
    from swarmplan.optimizers.base import Problem

    problem = Problem(sphere, LOWER, UPPER, 2000)
    rng = np.random.default_rng(3)
    state = ga.setup(problem, rng, None)
    best = state.F.min()
    for it in range(1, 30):
        ga.iterate(state, problem, rng, it)
        assert state.F.min() <= best
        best = state.F.min()
        assert state.X.shape == (20, D) and state.F.shape == (20,)


def test_partners_map_the_uniform_grid_onto_every_ordered_triple_once():
    # u at the centres of the floor(u m) cells: each cell combination must give a different
    # ordered triple of distinct indices other than i, i.e. all (n-1)(n-2)(n-3) of them
    n = 7
    for i in range(n):
        seen = set()
        for a in range(n - 1):
            for b in range(n - 2):
                for c in range(n - 3):
                    t = partners((a + 0.5) / (n - 1), (b + 0.5) / (n - 2), (c + 0.5) / (n - 3), i, n)
                    assert len({i, *t}) == 4 and all(0 <= x < n for x in t), (i, t)
                    seen.add(t)
        assert len(seen) == (n - 1) * (n - 2) * (n - 3)
    # the smallest population DE accepts (4): the partners are the other three
    assert sorted(partners(0.0, 0.0, 0.0, 2, 4)) == [0, 1, 3]
    assert sorted(partners(0.999, 0.999, 0.999, 0, 4)) == [1, 2, 3]


def test_de_partners_distinct_not_self_and_uniform():
    # X = identity, CR = 1: the mutant row is e_r1 + F (e_r2 - e_r3), which spells r1, r2, r3
    n, trials = 7, 6000
    X = np.eye(n)
    lower, upper = np.full(n, -1.0), np.full(n, 2.0)
    rng = np.random.default_rng(4)
    counts = np.zeros((n, n, n, n), dtype=int)
    for _ in range(trials // n):
        U = np.empty((n, n))
        de_trials(X, rng.random((n, n + 4)), 0.5, 1.0, lower, upper, U)
        for i, u in enumerate(U):
            r1, r2, r3 = int(np.argmax(u == 1.0)), int(np.argmax(u == 0.5)), int(np.argmax(u == -0.5))
            assert np.count_nonzero(u) == 3 and len({i, r1, r2, r3}) == 4, (i, u)
            counts[i, r1, r2, r3] += 1
    # every ordered triple of the n - 1 others is equally likely: 120 cells per i, ~7 each
    per_i = counts.reshape(n, -1)
    cells = (n - 1) * (n - 2) * (n - 3)
    assert np.all(np.count_nonzero(per_i, axis=1) == cells)
    # r1 alone: uniform over the 6 others (~143 each); a 4-sigma band
    r1 = counts.sum(axis=(2, 3))
    expected = trials / n / (n - 1)
    off = r1[~np.eye(n, dtype=bool)]
    assert np.all(np.abs(off - expected) < 4 * np.sqrt(expected)), off


def test_de_bound_repair_is_the_midpoint_to_the_violated_bound():
    X = np.array([[0.0, 0.0], [9.0, -9.0], [0.0, 0.0], [-9.0, 9.0]])
    lower, upper = np.array([-10.0, -10.0]), np.array([10.0, 10.0])
    R = np.zeros((4, 6))  # every partner index 0 -> the first allowed ones; CR = 1
    U = np.empty_like(X)
    de_trials(X, R, 2.0, 1.0, lower, upper, U)
    assert np.all(U >= lower) and np.all(U <= upper)
    # row 0: partners 1, 2, 3 -> v = x1 + 2 (x2 - x3) = (27, -27): both repaired
    np.testing.assert_allclose(U[0], [0.5 * (10.0 + 0.0), 0.5 * (-10.0 + 0.0)])


def _ga(X, F, R, pc, pm, k=1, lower=-100.0, upper=100.0):
    d = X.shape[1]
    lo, hi = np.full(d, lower), np.full(d, upper)
    children = np.empty_like(X)
    ga_offspring(X, F, k, R, pc, 15.0, pm, 20.0, lo, hi, children)
    return children


def _ga_draws(rng, n, d, k=1, pm=0.5):
    return rng.random(ga_draws(n, d, k, pm)[0])


def test_sbx_children_are_symmetric_about_parents_mean():
    rng = np.random.default_rng(2)
    n, d = 50, 4
    X, F = rng.random((n, d)), rng.random(n)
    R = _ga_draws(rng, n, d)
    C = _ga(X, F, R, pc=1.0, pm=0.0)
    winners = np.floor(R[:n] * n).astype(int)  # tournament size 1: the entrant itself
    P1, P2 = X[winners[: n // 2]], X[winners[n // 2 :]]
    assert np.allclose(C[: n // 2] + C[n // 2 :], P1 + P2)
    assert not np.allclose(C[: n // 2], P1)
    # no crossing at all (pc = 0): the children are their parents (up to rounding)
    C0 = _ga(X, F, R, pc=0.0, pm=0.0)
    assert np.allclose(C0[: n // 2], P1) and np.allclose(C0[n // 2 :], P2)


def test_tournament_winner_is_the_lower_cost_entrant():
    rng = np.random.default_rng(6)
    n, d = 20, 3
    X = np.repeat(np.arange(n, dtype=float)[:, None], d, axis=1)  # row i is (i, i, i)
    F = rng.permutation(n).astype(float)
    R = _ga_draws(rng, n, d, k=2)
    C = _ga(X, F, R, pc=0.0, pm=0.0, k=2)
    entrants = np.floor(R[: 2 * n] * n).astype(int).reshape(n, 2)
    best = np.where(F[entrants[:, 1]] < F[entrants[:, 0]], entrants[:, 1], entrants[:, 0])
    np.testing.assert_allclose(C[:, 0], best)


@pytest.mark.parametrize("pm", [0.5, 0.02, 1.0])
def test_polynomial_mutation_stays_in_bounds_and_mutates_at_rate(pm):
    rng = np.random.default_rng(1)
    n, d = 2000, 3
    X = rng.uniform(-1.0, 1.0, (n, d))
    X[:10] = -1.0  # points on the bounds
    X[10:20] = 1.0
    lower, upper = np.full(d, -1.0), np.full(d, 1.0)
    Y = X.copy()
    pos = ga_mutate(Y, rng.random(ga_draws(n, d, 1, pm)[1]), 0, pm, 20.0, lower, upper)
    assert pos == n * d  # the batch sufficed
    assert np.all(Y >= -1.0) and np.all(Y <= 1.0)
    # (a coordinate on a bound pushed towards it stays put: count the interior rows only)
    changed = Y[20:] != X[20:]
    assert abs(np.mean(changed) - pm) < 4 * np.sqrt(pm * (1 - pm) / changed.size) + 1e-3
    # per-coordinate trials are independent: no column is favoured
    per_col = np.mean(changed, axis=0)
    assert np.all(np.abs(per_col - pm) < 4 * np.sqrt(pm * (1 - pm) / len(changed)) + 1e-3)
    # the mutation is local (eta_m = 20): most moves are a small fraction of the box
    moved = np.abs(Y - X)[Y != X]
    assert np.median(moved) < 0.1


def test_mutation_continues_from_a_fresh_batch():
    """A batch that runs short resumes where it stopped: the same mutations as one long batch
    read in the same order."""
    rng = np.random.default_rng(5)
    n, d, pm = 200, 5, 0.3
    X = rng.uniform(-1.0, 1.0, (n, d))
    lower, upper = np.full(d, -1.0), np.full(d, 1.0)
    R = rng.random(4001)
    whole = X.copy()
    assert ga_mutate(whole, R, 0, pm, 20.0, lower, upper) == n * d
    parts, pos, at = X.copy(), 0, 0
    while pos < n * d:  # batches of 7 uniforms: 3 events each, the 7th is read again next time
        pos = ga_mutate(parts, R[at : at + 7], pos, pm, 20.0, lower, upper)
        at += 6
    np.testing.assert_array_equal(parts, whole)
    assert 0.25 < np.mean(whole != X) < 0.35
    # pm = 0: nothing mutates
    none = X.copy()
    assert ga_mutate(none, R, 0, 0.0, 20.0, lower, upper) == n * d
    np.testing.assert_array_equal(none, X)


def test_abc_onlookers_follow_the_roulette():
    rng = np.random.default_rng(8)
    X = rng.random((4, 2))
    fit = np.array([0.0, 1.0, 3.0, 9.0])  # fitness 1, 1/2, 1/4, 1/10 -> p = 1/1.85, ...
    m = 20000
    R = rng.random((4, m))
    V, src = np.empty((m, 2)), np.empty(m, dtype=np.int64)
    abc_moves(X, fit, R, True, np.zeros(2), np.ones(2), V, src)
    p = np.array([1.0, 0.5, 0.25, 0.1]) / 1.85
    freq = np.bincount(src, minlength=4) / m
    assert np.all(np.abs(freq - p) < 4 * np.sqrt(p * (1 - p) / m)), (freq, p)
    # every candidate differs from its source in at most one coordinate, inside the box
    assert np.all(np.count_nonzero(V != X[src], axis=1) <= 1)
    assert np.all((V >= 0.0) & (V <= 1.0))
    # all-infeasible sources: a uniform choice
    abc_moves(X, np.full(4, -np.inf), R, True, np.zeros(2), np.ones(2), V, src)
    assert np.all(np.abs(np.bincount(src, minlength=4) / m - 0.25) < 0.02)


def test_abc_greedy_keeps_the_best_candidate_per_source_and_counts_trials():
    X = np.zeros((3, 2))
    fit = np.array([5.0, 5.0, 5.0])
    trial = np.array([0, 4, 7])
    src = np.array([0, 0, 1, 0])
    V = np.arange(8, dtype=float).reshape(4, 2)
    fv = np.array([4.0, 3.0, 6.0, 3.0])  # source 0: rows 1 and 3 tie at 3 -> the first (row 1)
    top = abc_greedy(X, fit, trial, src, V, fv)
    np.testing.assert_array_equal(X[0], V[1])
    assert fit.tolist() == [3.0, 5.0, 5.0]
    assert trial.tolist() == [0, 5, 7]  # improved -> 0, tried without gain -> +1, untried kept
    assert top == 2


@pytest.mark.parametrize(
    ("name", "param", "value"),
    [
        ("pso", "w", 1.5),
        ("pso", "vmax_fraction", 0.0),
        ("pso", "c1", -1.0),
        ("de", "F", 0.0),
        ("de", "CR", 1.5),
        ("ga", "crossover_rate", -0.1),
        ("ga", "eta_m", 0.0),
        ("ga", "elite", 50),
        ("ga", "tournament", 0),
    ],
)
def test_bad_parameters_raise_naming_the_parameter(name, param, value):
    with pytest.raises(ValueError, match=param):
        make(name, **{param: value})
