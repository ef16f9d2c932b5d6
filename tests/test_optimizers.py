"""Contract tests for every registered optimizer (parametrized over ``available()``).

Whatever algorithm gets registered is covered automatically: determinism, bounds, the
evaluation budget, the result/history contract, inf costs, ``x0``, no run state on the
optimizer object, error messages, and beating random search on sphere and Rastrigin.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.bench.functions import rastrigin, sphere
from swarmplan.optimizers import available, defaults, make

ALGORITHMS = available()
NON_RANDOM = [a for a in ALGORITHMS if a != "random"]

# An asymmetric box, different per dimension, so bound bugs (e.g. using lower[0]) show.
LOWER = np.array([-5.0, 0.0, 10.0, -1.0, -100.0])
UPPER = np.array([5.0, 1.0, 30.0, 3.0, -50.0])
CENTRE = 0.5 * (LOWER + UPPER)
TARGET = LOWER + 0.71 * (UPPER - LOWER)  # optimum away from the box centre


def shifted_sphere(X: np.ndarray) -> np.ndarray:
    D = (X - TARGET) / (UPPER - LOWER)
    return np.sum(D * D, axis=1)


class Recorder:
    """Wraps a cost, records every row passed to it."""

    def __init__(self, fn=shifted_sphere):
        self.fn = fn
        self.rows: list[np.ndarray] = []

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X)
        assert X.ndim == 2, f"cost got an array of shape {X.shape}, expected (n, d)"
        self.rows.append(X.copy())
        return self.fn(X)

    @property
    def all(self) -> np.ndarray:
        return np.concatenate(self.rows) if self.rows else np.empty((0, LOWER.size))


def run(name: str, cost=shifted_sphere, *, max_evals: int = 600, seed=1, **kw):
    return make(name).minimize(cost, LOWER, UPPER, max_evals=max_evals, seed=seed, **kw)


def same_result(a, b) -> bool:
    return (
        np.array_equal(a.x, b.x)
        and a.f == b.f
        and a.evaluations == b.evaluations
        and a.iterations == b.iterations
        and np.array_equal(a.history, b.history)
    )


def test_registry_has_algorithms():
    assert "random" in ALGORITHMS
    assert ALGORITHMS == sorted(ALGORITHMS)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_same_seed_same_result(name):
    a, b = run(name, seed=123), run(name, seed=123)
    assert same_result(a, b)
    # a Generator as seed is accepted and equivalent to the int seed
    c = run(name, seed=np.random.default_rng(123))
    assert same_result(a, c)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_different_seeds_differ(name):
    a, b = run(name, seed=1), run(name, seed=2)
    assert not np.array_equal(a.x, b.x)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_points_within_bounds(name):
    rec = Recorder()
    res = run(name, rec, max_evals=800)
    X = rec.all
    assert np.all(np.isfinite(X))
    assert np.all(X >= LOWER) and np.all(X <= UPPER), (
        f"{name}: out-of-box rows, min {X.min(axis=0)} max {X.max(axis=0)}"
    )
    assert np.all(res.x >= LOWER) and np.all(res.x <= UPPER)


@pytest.mark.parametrize("budget", [1, 7, 101, 250])
@pytest.mark.parametrize("name", ALGORITHMS)
def test_budget_is_respected(name, budget):
    rec = Recorder()
    # population 13 divides none of the budgets
    res = make(name, population=13).minimize(rec, LOWER, UPPER, max_evals=budget, seed=5)
    rows = len(rec.all)
    assert rows <= budget, f"{name}: {rows} rows evaluated with max_evals={budget}"
    assert res.evaluations == rows
    assert res.evaluations == budget  # every algorithm should use its whole budget
    assert np.isfinite(res.f)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_result_contract(name):
    rec = Recorder()
    res = run(name, rec, max_evals=500)
    assert res.x.shape == LOWER.shape
    assert res.f == shifted_sphere(res.x[None])[0]
    # f is the best value ever returned by the cost
    assert res.f == min(float(np.min(shifted_sphere(X))) for X in rec.rows)
    h = res.history
    assert len(h) == res.iterations + 1
    assert np.all(h[1:] <= h[:-1]), f"{name}: history increases: {h}"
    assert h[-1] == res.f
    assert res.wall_time >= 0
    assert res.algorithm == name


@pytest.mark.parametrize("name", ALGORITHMS)
def test_inf_costs_are_handled(name):
    def half_inf(X):
        f = shifted_sphere(X)
        return np.where(X[:, 0] > CENTRE[0], np.inf, f)  # whole half of the box infeasible

    res = run(name, half_inf, max_evals=600)
    assert np.isfinite(res.f)
    assert res.x[0] <= CENTRE[0]
    assert res.f == half_inf(res.x[None])[0]
    assert np.all(res.history[1:] <= res.history[:-1])


@pytest.mark.parametrize("name", ALGORITHMS)
def test_nan_costs_are_handled(name):
    def some_nan(X):
        f = shifted_sphere(X)
        return np.where(X[:, 1] > 0.8, np.nan, f)

    res = run(name, some_nan, max_evals=600)
    assert np.isfinite(res.f)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_x0_is_used(name):
    x0 = TARGET.copy()
    res = run(name, max_evals=200, x0=x0)
    assert res.f <= shifted_sphere(x0[None])[0]
    assert res.f == 0.0
    # several starting points are accepted too
    res2 = run(name, max_evals=200, x0=np.stack([CENTRE, TARGET]))
    assert res2.f == 0.0


@pytest.mark.parametrize("name", ALGORITHMS)
def test_callback_can_stop(name):
    calls = []

    def cb(it, x, f):
        calls.append((it, f))
        return it >= 3

    res = run(name, max_evals=10_000, callback=cb)
    assert res.iterations == 3
    assert [c[0] for c in calls] == [1, 2, 3]
    assert res.evaluations < 10_000


@pytest.mark.parametrize("name", ALGORITHMS)
def test_no_run_state_on_the_optimizer(name):
    """A minimize call nested inside another one's cost does not disturb either."""
    opt = make(name)
    alone_a = opt.minimize(shifted_sphere, LOWER, UPPER, max_evals=400, seed=11)
    alone_b = opt.minimize(rastrigin_box, LOWER, UPPER, max_evals=300, seed=22)
    inner = []

    def cost_a(X):
        if len(inner) < 2:  # interleave twice: after the initial population and mid-run
            inner.append(opt.minimize(rastrigin_box, LOWER, UPPER, max_evals=300, seed=22))
        return shifted_sphere(X)

    outer = opt.minimize(cost_a, LOWER, UPPER, max_evals=400, seed=11)
    assert same_result(outer, alone_a)
    assert all(same_result(r, alone_b) for r in inner)
    # and the object is still usable with the same outcome afterwards
    assert same_result(opt.minimize(shifted_sphere, LOWER, UPPER, max_evals=400, seed=11), alone_a)


def rastrigin_box(X):
    return rastrigin((X - TARGET) / (UPPER - LOWER) * 5.0)


def test_unknown_name_names_known_ones():
    with pytest.raises(ValueError) as e:
        make("no-such-optimizer")
    msg = str(e.value)
    assert "no-such-optimizer" in msg
    for name in ALGORITHMS:
        assert name in msg
    with pytest.raises(ValueError):
        defaults("no-such-optimizer")


@pytest.mark.parametrize("name", ALGORITHMS)
def test_unknown_param_names_known_ones(name):
    with pytest.raises(ValueError) as e:
        make(name, no_such_parameter=1)
    msg = str(e.value)
    assert "no_such_parameter" in msg
    for p in defaults(name):
        assert p in msg


@pytest.mark.parametrize("name", ALGORITHMS)
def test_defaults_are_accepted(name):
    d = defaults(name)
    assert "population" in d
    opt = make(name, **d)
    assert dict(opt.params) == d


@pytest.mark.parametrize("name", ALGORITHMS)
def test_bad_population_rejected(name):
    with pytest.raises(ValueError):
        make(name, population=1)


# --- beats random search ----------------------------------------------------------------------
D = 10
BUDGET = 10_000  # 1000 d
SEEDS = range(7)
_random_cache: dict[str, list[float]] = {}


def _finals(name: str, fn_name: str) -> list[float]:
    fn, (lo, hi) = {"sphere": (sphere, (-100.0, 100.0)), "rastrigin": (rastrigin, (-5.12, 5.12))}[fn_name]
    # shift the optimum away from the origin (box centre) so centre-seeking gets no free win
    shift = np.linspace(0.15, 0.35, D) * (hi - lo) * np.where(np.arange(D) % 2, 1, -1)

    def cost(X):
        return fn(X - shift)

    lower, upper = np.full(D, lo), np.full(D, hi)
    return [make(name).minimize(cost, lower, upper, max_evals=BUDGET, seed=s).f for s in SEEDS]


# Measured, kept visible as strict xfails (they fail the day the algorithm passes). Empty since
# AFSA was level with random search on shifted Rastrigin with 002's CEC settings in
# box widths (7-seed medians 80.3 vs 79.0); with Visual / Step as fractions of the box diagonal
# and 002's path-planning Visual and Try_Num (fish_swarm.py) it is 65.7 (sphere 1583 vs 5305).
BEATS_RANDOM_KNOWN: dict[tuple[str, str], str] = {}


@pytest.mark.parametrize("fn_name", ["sphere", "rastrigin"])
@pytest.mark.parametrize("name", NON_RANDOM)
def test_beats_random_search(name, fn_name, request):
    if (name, fn_name) in BEATS_RANDOM_KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=BEATS_RANDOM_KNOWN[name, fn_name]))
    if fn_name not in _random_cache:
        _random_cache[fn_name] = _finals("random", fn_name)
    rnd = _random_cache[fn_name]
    ours = _finals(name, fn_name)
    # deterministic (fixed seeds, so not flaky): median of 7 runs below random search's median
    msg = f"{name} on shifted {fn_name}: {np.round(ours, 3)} vs random {np.round(rnd, 3)}"
    assert np.median(ours) < np.median(rnd), msg


# --- the benchmark functions and the bench CLI ------------------------------------------------
@pytest.mark.parametrize("shifted", [False, True])
def test_benchmark_optima(shifted):
    from swarmplan.bench.functions import BENCHMARKS

    for d in (2, 10, 30):
        for b in BENCHMARKS.values():
            x = b.optimum(d, shifted=shifted)
            if x is None or b.noisy:
                continue
            lo, hi = b.bounds(d)
            assert np.all(x > lo) and np.all(x < hi), b.name
            cost = b.cost(d, shifted=shifted)
            assert cost(x[None])[0] == pytest.approx(b.fopt(d), abs=1e-9), b.name
            X = lo + np.random.default_rng(0).random((20, d)) * (hi - lo)
            assert np.all(cost(X) >= b.fopt(d) - 1e-9), b.name
            assert cost(X).shape == (20,)
            if shifted:  # moved away from the box centre (and the origin)
                assert np.linalg.norm(x - 0.5 * (lo + hi)) > 0.1 * np.linalg.norm(hi - lo), b.name


def test_bench_cli(tmp_path, capsys, monkeypatch):
    import sys

    from swarmplan.bench.__main__ import main

    out = tmp_path / "r.csv"
    argv = ["optimizers", "--suite", "rscdwoa-table4", "--runs", "3", "--algorithms", "random,pso"]
    argv += ["--functions", "sphere,rastrigin", "--evals", "300", "--jobs", "1", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "rastrigin (shifted)" in text and "| pso |" in text
    lines = out.read_text().splitlines()
    assert len(lines) == 1 + 2 * 2 * 2  # header + variants x functions x algorithms
    with pytest.raises(SystemExit):
        main(["optimizers", "--suite", "no-such-suite"])
    monkeypatch.setitem(sys.modules, "opfunu", None)  # import opfunu -> ImportError
    assert main(["optimizers", "--suite", "cec2013", "--runs", "1"]) == 2
    assert "pip install opfunu" in capsys.readouterr().err


def test_bench_help_and_output_defaults(tmp_path, capsys, monkeypatch):
    """Plain help text with defaults, no empty paper column, CSV into logs/."""
    from swarmplan.bench import peers
    from swarmplan.cli.bench import build_parser, main

    parser = build_parser()
    texts = [parser.format_help()]
    sub = next(a for a in parser._actions if a.dest == "command")
    texts += [p.format_help() for p in sub.choices.values()]
    for text in texts:
        assert "``" not in text and "/work/" not in text and "our copy" not in text, text[:200]
    assert "runs per algorithm x function (default: 10)" in " ".join(
        sub.choices["optimizers"].format_help().split()
    )

    monkeypatch.chdir(tmp_path)
    argv = ["optimizers", "--suite", "rscdwoa-table4", "--runs", "2", "--algorithms", "random"]
    argv += ["--functions", "sphere", "--evals", "60", "--jobs", "1", "--no-shifted"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "paper mean" not in text  # 001 prints no numbers: no (empty) paper column
    assert (tmp_path / "logs" / "bench-rscdwoa-table4.csv").exists()
    argv = ["optimizers", "--suite", "iba-table10", "--runs", "1", "--algorithms", "ba"]
    argv += ["--functions", "sphere", "--evals", "60", "--jobs", "1", "--no-shifted"]
    assert main(argv) == 0
    assert "paper mean" in capsys.readouterr().out

    # --peers without mealpy/niapy: one line naming the extra, exit 2
    monkeypatch.setattr(peers, "check_installed", lambda: peers.INSTALL_HINT)
    argv = ["optimizers", "--suite", "shifted", "--peers", "--runs", "1", "--algorithms", "woa"]
    assert main(argv) == 2
    assert "swarmplan[peers]" in capsys.readouterr().err


def test_bench_shifted_suite_runs_bases_and_param_sets(tmp_path, capsys):
    from swarmplan.bench.__main__ import main

    out = tmp_path / "s.csv"
    argv = ["optimizers", "--suite", "shifted", "--runs", "2", "--algorithms", "iba_gauss,mcfo@ours"]
    argv += ["--functions", "sphere", "--evals", "200", "--jobs", "1", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    # iba_gauss is judged against BA at paper 003's settings, added automatically
    assert "| ba@003 |" in text and "vs ba@003" in text and "| mcfo@ours |" in text
    assert "(plain)" not in text  # the shifted suite has no plain variant


@pytest.mark.parametrize("name", ALGORITHMS)
def test_warm_up_loads_once_and_leaves_runs_unchanged(name):
    """Planners call ``warm_up`` before timing a plan: it must not change any run."""
    from swarmplan.optimizers import base

    def cost(X):
        return sphere(X - 0.3)

    lower, upper = np.full(6, -2.0), np.full(6, 2.0)
    before = make(name).minimize(cost, lower, upper, max_evals=600, seed=np.random.default_rng(5))
    opt = make(name)
    rng = np.random.default_rng(5)
    opt.warm_up()
    assert (name, repr(sorted(opt.params.items()))) in base._WARMED
    after = opt.minimize(cost, lower, upper, max_evals=600, seed=rng)
    assert np.array_equal(before.x, after.x) and np.array_equal(before.history, after.history)
    assert before.evaluations == after.evaluations
