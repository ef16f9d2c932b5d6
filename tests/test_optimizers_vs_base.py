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
from scipy.stats import ranksums

from swarmplan.bench.functions import get
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

# Measured, reported and kept visible: a strict xfail turns into a failure the day it passes.
KNOWN_FAILURES = {
    ("mcfo", "rastrigin"): (
        "MCFO written to 004's eqs 19, 23 and 29 does not beat CFO on shifted Rastrigin "
        "(p = 0.43, medians 23.85 vs 23.12 on 2026-11-22); it does on shifted Ackley. See docs/benchmarks.md."
    ),
}

_cache: dict[tuple[str, str], np.ndarray] = {}


def finals(name: str, fn_name: str) -> np.ndarray:
    key = (name, fn_name)
    if key not in _cache:
        bench = get(fn_name)
        lower, upper = bench.bounds(DIM)
        cost = bench.cost(DIM, shifted=True)
        opt = make(name)
        _cache[key] = np.array(
            [opt.minimize(cost, lower, upper, max_evals=BUDGET, seed=1000 + s).f for s in SEEDS]
        )
    return _cache[key]


@pytest.mark.slow
@pytest.mark.parametrize("fn_name", FUNCTIONS)
@pytest.mark.parametrize(("improved", "base"), PAIRS, ids=[f"{a}-vs-{b}" for a, b in PAIRS])
def test_improved_beats_base(improved, base, fn_name, request):
    if (improved, fn_name) in KNOWN_FAILURES:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[improved, fn_name]))
    missing = [n for n in (improved, base) if n not in available()]
    if missing:
        # the product requires every paper algorithm: a missing one is a failure, not a skip
        pytest.fail(f"{', '.join(missing)} not registered; available: {', '.join(available())}")
    a, b = finals(improved, fn_name), finals(base, fn_name)
    p = ranksums(a, b, alternative="less").pvalue
    msg = (
        f"{improved} vs {base} on shifted {fn_name} d={DIM}, {BUDGET} evals: p={p:.3g}; "
        f"{improved} median {np.median(a):.4g} {np.round(a, 4)}; "
        f"{base} median {np.median(b):.4g} {np.round(b, 4)}"
    )
    print(msg)
    assert p < ALPHA, msg
