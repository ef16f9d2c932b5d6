"""Behaviour of WOA and RSCDWOA (swarmplan/optimizers/whale.py, paper 001 sections 2.2 and 3)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.optimizers import available, make
from swarmplan.optimizers.whale import (
    chaos_sequence,
    chaos_step,
    logistic_map,
    secondary_reflection,
    tent_map,
)

D = 10
LOWER = -100.0 * np.ones(D)
UPPER = 100.0 * np.ones(D)
SEEDS = (0, 1, 2)


def sphere(X: np.ndarray) -> np.ndarray:
    return np.sum(X**2, axis=1)


def shifted_sphere(X: np.ndarray) -> np.ndarray:
    return np.sum((X - 17.0) ** 2, axis=1)


def test_registered():
    assert {"woa", "rscdwoa"} <= set(available())


# Observed at 5000 evaluations, d = 10, seeds 0-4: random 4.7e3-8.1e3 on the sphere,
# WOA <= 8e-25 and RSCDWOA <= 2e-21.
@pytest.mark.parametrize("name", ["woa", "rscdwoa"])
def test_far_below_random_search_on_sphere(name):
    for seed in SEEDS:
        rand = make("random").minimize(sphere, LOWER, UPPER, max_evals=5000, seed=seed).f
        res = make(name).minimize(sphere, LOWER, UPPER, max_evals=5000, seed=seed)
        assert res.f < 1e-12, (name, seed, res.f)
        assert res.f < 1e-6 * rand


# Observed at 30000 evaluations, d = 30: WOA ~1e-160, RSCDWOA ~1e-130 (tent) / ~1e-120
# (logistic). The threshold is far looser than that but still a real convergence claim.
@pytest.mark.parametrize(
    ("name", "params"), [("woa", {}), ("rscdwoa", {}), ("rscdwoa", {"chaos": "logistic"})]
)
def test_converges_on_sphere_d30(name, params):
    d = 30
    res = make(name, **params).minimize(sphere, -100 * np.ones(d), 100 * np.ones(d), max_evals=30000, seed=7)
    assert res.f < 1e-20
    assert res.evaluations == 30000


@pytest.mark.parametrize("name", ["woa", "rscdwoa"])
def test_off_centre_optimum_still_found_roughly(name):
    # WOA is known to favour the box centre; with the optimum at 17 it still gets far below
    # random search (observed at 5000 evals, d = 10: WOA 0.35-26, RSCDWOA 0.12-2.3).
    for seed in SEEDS:
        res = make(name).minimize(shifted_sphere, LOWER, UPPER, max_evals=5000, seed=seed)
        assert res.f < 100.0, (name, seed, res.f)


def test_rscdwoa_improves_on_woa_off_centre():
    # The paper's claim (section 5.5) on a case where the centre bias does not help:
    # observed medians over seeds 0-7 at 10000 evals: WOA 1.3, RSCDWOA 0.037.
    def median_f(name):
        return np.median(
            [make(name).minimize(shifted_sphere, LOWER, UPPER, max_evals=10000, seed=s).f for s in range(4)]
        )

    assert median_f("rscdwoa") < 0.25 * median_f("woa")


def test_woa_a_decreases_with_evaluations_used():
    # Early on |A| can exceed 1 (exploration); with the budget nearly used, a ~ 0 and every
    # whale moves towards X_*: the population contracts around the best point.
    woa = make("woa")
    from swarmplan.optimizers.base import Problem

    problem = Problem(sphere, LOWER, UPPER, 10**6)
    rng = np.random.default_rng(0)
    state = woa.setup(problem, rng, None)
    problem.evaluations = problem.max_evals - 10 * woa.population  # end of the run: a ~ 0
    spread_before = np.ptp(state.X, axis=0).mean()
    for it in range(1, 5):
        woa.iterate(state, problem, rng, it)
    assert np.ptp(state.X, axis=0).mean() < 0.5 * spread_before


# --------------------------------------------------------------------------- chaos maps


def test_tent_map_equation_14():
    assert tent_map(np.array(0.37), 0.74) == pytest.approx(0.5)
    assert tent_map(np.array(0.87), 0.74) == pytest.approx(0.5)


def test_logistic_map_equation_13():
    assert logistic_map(np.array(0.5), 4.0) == pytest.approx(1.0)
    assert logistic_map(np.array(0.25), 4.0) == pytest.approx(0.75)


@pytest.mark.parametrize("kind", ["tent", "logistic"])
def test_chaos_values_stay_in_open_unit_interval(kind):
    seq = chaos_sequence(5000, kind, seed=3)
    assert np.all(seq > 0.0) and np.all(seq < 1.0)
    # Chaotic, not collapsed to a cycle: many distinct values, spread over (0, 1).
    assert len(np.unique(seq)) > 4900
    hist, _ = np.histogram(seq, bins=10, range=(0, 1))
    assert hist.min() > 0


@pytest.mark.parametrize("kind", ["tent", "logistic"])
def test_chaos_step_revives_degenerate_orbits(kind):
    rng = np.random.default_rng(0)
    # 0.5 -> 1 -> 0 for the logistic map; 1/(2 - beta) is the tent map's fixed point; 1e-12 ~ 0.
    w = np.array([0.5, 1.0 / (2.0 - 0.74), 0.75, 1e-12, 1.0 - 1e-12])
    for _ in range(50):
        w = chaos_step(w, kind, 0.74, 4.0, rng)
        assert np.all((w > 0.0) & (w < 1.0))
    assert len(np.unique(w)) == len(w)


# --------------------------------------------------------------------------- reverse search


def test_secondary_reflection_lies_between_point_and_centre():
    rng = np.random.default_rng(5)
    lower, upper = np.array([-5.0, 0.0, 10.0]), np.array([5.0, 1.0, 30.0])
    X = lower + rng.random((5000, 3)) * (upper - lower)
    X[:5] = lower
    X[5:10] = upper
    Y = secondary_reflection(rng, X, lower, upper)
    h = 0.5 * (lower + upper)
    assert np.all(Y >= lower) and np.all(Y <= upper)
    assert np.all(Y >= np.minimum(X, h) - 1e-12) and np.all(Y <= np.maximum(X, h) + 1e-12)
    # Normal around the midpoint of [x, h]: mean offset ~ 0, not a constant.
    offset = (Y - 0.5 * (X + h)) / np.maximum(np.abs(h - X), 1e-12)
    assert abs(offset.mean()) < 0.01
    assert 0.1 < offset.std() < 0.25


def test_lifespan_switches_on_de_and_reverse_search():
    # DE + reverse search costs a second evaluation batch; the WOA moves only one per generation.
    n = 20
    never = make("rscdwoa", population=n, lifespan=10**9).minimize(
        sphere, LOWER, UPPER, max_evals=2000, seed=0
    )
    assert never.evaluations == n * (never.iterations + 1)
    always = make("rscdwoa", population=n, lifespan=0).minimize(sphere, LOWER, UPPER, max_evals=2000, seed=0)
    assert always.iterations + 1 < 2000 // n


@pytest.mark.parametrize(
    ("params", "name"),
    [
        ({"chaos": "sine"}, "chaos"),
        ({"beta": 1.0}, "beta"),
        ({"k": 20}, "k"),
        ({"alpha": 2.0}, "alpha"),
        ({"C_rate": -0.1}, "C_rate"),
        ({"lifespan": -1}, "lifespan"),
        ({"F": 0.0}, "F"),
    ],
)
def test_rscdwoa_bad_parameters(params, name):
    with pytest.raises(ValueError, match=name):
        make("rscdwoa", **params)


def test_rscdwoa_defaults():
    p = make("rscdwoa").params
    assert p["chaos"] == "tent" and p["beta"] == 0.74 and p["b"] == 1.0 and p["lam"] == 1e-4


# --------------------------------------------------------------------------- compiled kernels


def test_woa_generation_is_eqs_2_to_10_on_the_same_draws():
    # one generation of the kernel against the equations written out in numpy
    from swarmplan.optimizers.base import Problem

    opt = make("woa", population=40)
    problem = Problem(shifted_sphere, LOWER, UPPER, 10**6)
    state = opt.setup(problem, np.random.default_rng(1), None)
    problem.evaluations = problem.max_evals // 4  # a = 1.5: both |A| < 1 and |A| >= 1 occur
    X, best = state.X.copy(), state.best_x.copy()
    n = len(X)
    a = 2.0 - 2.0 * problem.evaluations / problem.max_evals
    opt.iterate(state, problem, np.random.default_rng(7), 1)

    r = np.random.default_rng(7).random((5, n))
    A, C, ell, q = 2.0 * a * r[0] - a, 2.0 * r[1], -1.0 + 2.0 * r[2], r[3]
    partner = (np.arange(n) + 1 + np.floor(r[4] * (n - 1)).astype(int)) % n
    explore = np.abs(A) >= 1.0
    ref = np.where(explore[:, None], X[partner], best)
    encircle = ref - A[:, None] * np.abs(C[:, None] * ref - X)  # eqs 2-3 and 9-10
    spiral = np.abs(best - X) * (np.exp(ell) * np.cos(2.0 * np.pi * ell))[:, None] + best  # eq 7
    expected = np.clip(np.where((q < 0.5)[:, None], encircle, spiral), LOWER, UPPER)
    assert np.all(partner != np.arange(n))
    assert explore[q < 0.5].any() and not explore[q < 0.5].all() and (q >= 0.5).any()
    assert np.array_equal(state.X, expected)


@pytest.mark.parametrize("kind", ["tent", "logistic"])
def test_rscdwoa_revives_degenerate_chaos_in_a_run(kind):
    from swarmplan.optimizers.base import Problem

    opt = make("rscdwoa", chaos=kind, population=5)
    problem = Problem(sphere, LOWER, UPPER, 10**6)
    rng = np.random.default_rng(0)
    state = opt.setup(problem, rng, None)
    # 0.5 -> 1 -> 0 (logistic), the tent map's fixed point, ~0 and ~1: all would stay dead
    state.w[0] = [0.5, 1.0 / (2.0 - 0.74), 0.75, 1e-12, 1.0 - 1e-12]
    for it in range(1, 30):
        opt.iterate(state, problem, rng, it)
        assert np.all((state.w > 0.0) & (state.w < 1.0))
    assert len(np.unique(state.w)) == state.w.size


def test_rscdwoa_de_crossover_and_perturbation_frequencies():
    # eqs (21)-(22) share one uniform per coordinate (_whale_kernels.de_trials): perturbed with
    # probability alpha, else the donor's coordinate with probability C_rate (always at chi),
    # else the parent's; perturbed coordinates uniform in the box. With lambda = F = 0 and
    # omega = 1 the donor is the population best's coordinate, so each outcome is recognizable.
    from swarmplan.optimizers import _whale_kernels as wk
    from swarmplan.optimizers.base import Problem
    from swarmplan.optimizers.whale import _kit

    n, d, alpha, c_rate = 20, 50, 0.2, 0.6
    problem = Problem(sphere, LOWER[:1].repeat(d), UPPER[:1].repeat(d), 10)
    kit = _kit(problem, n, k=1, lam=0.0, F=0.0, omega=1.0, alpha=alpha, crate=c_rate)
    rng = np.random.default_rng(3)
    counts = np.zeros(3)  # parent, donor, perturbed (chi excluded)
    unit = []
    for _ in range(5):
        X = problem.uniform(rng, n)
        fit = np.arange(n, dtype=float)  # whale 0 is the best: the donor
        idx = np.arange(1, n)
        Xn = np.full((n, d), np.nan)
        u = rng.random(len(idx) * (wk.DE_SCALARS + 3 * d))
        wk.de_trials(X, fit, idx, len(idx), u, kit.c, kit.box, Xn)
        for t, i in enumerate(idx):
            chi = min(int(u[t * (wk.DE_SCALARS + 3 * d) + 4] * d), d - 1)
            parent, donor = Xn[i] == X[i], Xn[i] == X[0]
            other = ~parent & ~donor
            assert not parent[chi]  # chi always takes the donor's coordinate unless perturbed
            keep = np.arange(d) != chi
            counts += [parent[keep].sum(), donor[keep].sum(), other[keep].sum()]
            unit.extend((Xn[i, other] - problem.lower[other]) / problem.span[other])
    freq = counts / counts.sum()
    expected = [(1 - alpha) * (1 - c_rate), (1 - alpha) * c_rate, alpha]
    assert np.all(np.abs(freq - expected) < 0.03), (freq, expected)  # ~5 sigma at 4900 draws
    unit = np.asarray(unit)
    assert np.all((unit >= 0) & (unit < 1))
    assert abs(unit.mean() - 0.5) < 0.05 and abs(unit.std() - 0.289) < 0.03  # U[0, 1): 1/2, 1/sqrt(12)
