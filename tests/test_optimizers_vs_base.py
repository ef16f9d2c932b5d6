"""Each paper's improved variant must beat its base algorithm (the papers' central claim).

rscdwoa vs woa (001), iba_abc vs ba (000), iba_gauss vs ba (003), mcfo vs cfo (004), iafsa vs
afsa (002), on *shifted* multimodal functions (optimum moved away from the origin and the box
centre, see :mod:`swarmplan.bench.functions`) over 12 seeds at the same evaluation budget,
judged by the one-sided Wilcoxon rank-sum test (``scipy.stats.ranksums``, alternative
``less``, p < 0.05). Seeds are fixed, so the outcome is deterministic.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.bench.functions import get, with_box
from swarmplan.bench.optimizers import BA_003
from swarmplan.optimizers import available, make

PAIRS = [
    ("rscdwoa", "woa"),
    ("iba_abc", "ba"),
    ("iba_gauss", "ba"),
    ("mcfo", "cfo"),
    ("iafsa", "afsa"),
]
FUNCTIONS = ["rastrigin", "ackley"]
DIM = 10
BUDGET = 20_000  # 2000 d
SEEDS = range(12)
ALPHA = 0.05

#: each pair compares at its own paper's settings: 003 compares IBA with BA at its Table 3
#: settings, not 000's; the others use the registry defaults.
BASE_PARAMS: dict[tuple[str, str], dict] = {("iba_gauss", "ba"): BA_003}

# Measured, reported and kept visible: a strict xfail turns into a failure the day it passes.
KNOWN_FAILURES = {
    # MCFO = CFO + eq 18 memory + eq 19 mutation, with CFO's rank masses; with the additions off
    # it is CFO move for move (tests/test_optimizers_central_force.py). Ablation at these
    # settings: memory alone (c3 = 0) 24.7 / 2.41, mutation alone (c1 = c2 = 0) 20.2 / 1.46:
    # the memory pull without inertia (c1 = c2 = 1, ours; 004 gives none) is what costs. Re-read
    # neither order of 004's step 4 (update="eq23" / "steps") nor c1 = c2 in 0.5-2,
    # with or without mutation, beats CFO on both functions (table in docs/benchmarks.md).
    ("mcfo", "rastrigin"): (
        "MCFO (004 eqs 19, 23 literal, rank masses as CFO) does not beat CFO on shifted Rastrigin: "
        "p = 0.52, medians 18.49 vs 18.24 (2026-11-26). See docs/benchmarks.md."
    ),
    ("mcfo", "ackley"): (
        "MCFO (004 eqs 19, 23 literal, rank masses as CFO) does not beat CFO on shifted Ackley: "
        "p = 0.99, medians 2.57 vs 1.61 (2026-11-26). See docs/benchmarks.md."
    ),
    ("iba_gauss", "rastrigin"): (
        "IBA-Gauss does not beat BA at 003's own Table 3 settings on shifted Rastrigin: p = 0.52, "
        "medians 48.97 vs 54.92 (2026-11-23, cforce); it does on shifted Ackley. See docs/benchmarks.md."
    ),
}

_cache: dict[tuple[str, str], np.ndarray] = {}


def finals(name: str, fn_name: str, params: dict | None = None) -> np.ndarray:
    key = (name, fn_name, repr(sorted((params or {}).items())))
    if key not in _cache:
        bench = get(fn_name)
        lower, upper = bench.bounds(DIM)
        cost = bench.cost(DIM, shifted=True)
        opt = make(name, **(params or {}))
        _cache[key] = np.array(
            [opt.minimize(cost, lower, upper, max_evals=BUDGET, seed=1000 + s).f for s in SEEDS]
        )
    return _cache[key]


@pytest.mark.slow
@pytest.mark.parametrize("fn_name", FUNCTIONS)
@pytest.mark.parametrize(("improved", "base"), PAIRS, ids=[f"{a}-vs-{b}" for a, b in PAIRS])
def test_improved_beats_base(improved, base, fn_name, request):
    from scipy.stats import ranksums  # here: the default suite does not pay its import

    if (improved, fn_name) in KNOWN_FAILURES:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[improved, fn_name]))
    missing = [n for n in (improved, base) if n not in available()]
    if missing:
        # the product requires every paper algorithm: a missing one is a failure, not a skip
        pytest.fail(f"{', '.join(missing)} not registered; available: {', '.join(available())}")
    a, b = finals(improved, fn_name), finals(base, fn_name, BASE_PARAMS.get((improved, base)))
    p = ranksums(a, b, alternative="less").pvalue
    msg = (
        f"{improved} vs {base} on shifted {fn_name} d={DIM}, {BUDGET} evals: p={p:.3g}; "
        f"{improved} median {np.median(a):.4g} {np.round(a, 4)}; "
        f"{base} median {np.median(b):.4g} {np.round(b, 4)}"
    )
    print(msg)
    assert p < ALPHA, msg


# ---------------------------------------------------------------------------------------------
# fast versions for the default suite: fewer seeds, smaller budget, medians compared


FAST_SEEDS = range(5)
FAST_BUDGET = 3000


def _fast(name: str, fn_name: str, params: dict | None = None, box: float | None = None) -> np.ndarray:
    bench = get(fn_name)
    if box is not None:
        bench = with_box(bench, -box, box)
    lower, upper = bench.bounds(DIM)
    cost = bench.cost(DIM, shifted=True)
    opt = make(name, **(params or {}))
    return np.array([opt.minimize(cost, lower, upper, max_evals=FAST_BUDGET, seed=s).f for s in FAST_SEEDS])


# measured 2026-11-23, CFO and MCFO both with rank masses: MCFO does not beat CFO on shifted
# Rastrigin (medians of 5: 38.03 vs 22.28) nor on shifted Ackley (5.06 vs 4.34)
FAST_KNOWN = {
    ("mcfo", "cfo"): "MCFO does not beat CFO: shifted Rastrigin 38.03 vs 22.28, Ackley 5.06 vs 4.34"
}


@pytest.mark.parametrize(("improved", "base"), PAIRS, ids=[f"{a}-vs-{b}" for a, b in PAIRS])
def test_improved_beats_base_fast(improved, base, request):
    """Median over 5 seeds on shifted Rastrigin + Ackley (d = 10, 3000 evaluations), both lower."""
    if (improved, base) in FAST_KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=FAST_KNOWN[improved, base]))
    wins = 0
    for fn_name in FUNCTIONS:
        a = _fast(improved, fn_name)
        b = _fast(base, fn_name, BASE_PARAMS.get((improved, base)))
        wins += int(np.median(a) < np.median(b))
    assert wins == len(FUNCTIONS), f"{improved} beat {base} on {wins}/{len(FUNCTIONS)} shifted functions"


# Strict xfails (they fail the day the algorithm passes). Empty since the scale fixes: with 002's CEC
# settings in box widths (Visual 25 %, Step 3 %) no fish ever saw another in d = 10 and AFSA
# lost to random search (medians of 5: sphere 1.49e4 vs 7.75e3, Rastrigin 94.8 vs 95.0, with
# 1.42e4 / 98.5 before the random stream changed); with Visual / Step as fractions of the box
# diagonal and 002's path-planning Visual and Try_Num (the registry defaults, see
# fish_swarm.py): 3032 and 84.6.
BEATS_RANDOM_KNOWN: dict[str, str] = {}


@pytest.mark.parametrize("name", [a for a in available() if a != "random"])
def test_beats_random_on_shifted_sphere_and_rastrigin(name, request):
    """Every registry algorithm beats random search (medians of 5 seeds, d = 10, 3000 evals)."""
    if name in BEATS_RANDOM_KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=BEATS_RANDOM_KNOWN[name]))
    for fn_name in ("sphere", "rastrigin"):
        ours = np.median(_fast(name, fn_name, {"population": 30}))
        rand = np.median(_fast("random", fn_name, {"population": 30}))
        assert ours < rand, f"{name} median {ours:.4g} vs random {rand:.4g} on shifted {fn_name}"
