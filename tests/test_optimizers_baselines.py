"""Behaviour of the baselines: random, PSO, DE, GA (swarmplan/optimizers/baselines.py)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.optimizers import available, make
from swarmplan.optimizers.baselines import distinct_indices, polynomial_mutation, sbx_crossover

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
    from swarmplan.optimizers.core import Problem

    problem = Problem(sphere, LOWER, UPPER, 2000)
    rng = np.random.default_rng(3)
    state = ga.setup(problem, rng, None)
    best = state.F.min()
    for it in range(1, 30):
        ga.iterate(state, problem, rng, it)
        assert state.F.min() <= best
        best = state.F.min()
        assert state.X.shape == (20, D) and state.F.shape == (20,)


def test_distinct_indices_are_distinct_and_exclude_self():
    rng = np.random.default_rng(0)
    idx = distinct_indices(rng, 7, 3)
    assert idx.shape == (7, 3)
    for i, row in enumerate(idx):
        assert len(set(row)) == 3 and i not in row
    with pytest.raises(ValueError):
        distinct_indices(rng, 3, 3)


def test_polynomial_mutation_stays_in_bounds_and_mutates_at_rate():
    rng = np.random.default_rng(1)
    lower, upper = np.array([-1.0, 0.0, 5.0]), np.array([1.0, 2.0, 5.5])
    X = lower + rng.random((4000, 3)) * (upper - lower)
    X[:10] = lower  # points on the bounds
    X[10:20] = upper
    Y = polynomial_mutation(rng, X, lower, upper, 20.0, 0.5)
    assert np.all(Y >= lower) and np.all(Y <= upper)
    changed = np.mean(Y != X)
    assert 0.45 < changed < 0.55


def test_sbx_children_are_symmetric_about_parents_mean():
    rng = np.random.default_rng(2)
    P1, P2 = rng.random((50, 4)), rng.random((50, 4))
    C1, C2 = sbx_crossover(rng, P1, P2, 15.0, 1.0)
    assert np.allclose(C1 + C2, P1 + P2)
    assert not np.allclose(C1, P1)


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
