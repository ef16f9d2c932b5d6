"""The benchmark tables' verdicts: paper cells, best of ours vs best peer, against random search."""

from __future__ import annotations

import numpy as np

from swarmplan.bench.optimizers import format_best, format_vs_random
from swarmplan.bench.paper_tables import cell_verdict


def test_cell_verdicts():
    assert cell_verdict(3.15e-6, 2.6e-5) == "within 10x"
    assert cell_verdict(3.15e-6, 3.5e4).startswith("worse, 1.1e+10x")
    assert cell_verdict(12.6, 0.5).startswith("better, 0.04")
    assert cell_verdict(-49.9, -49.8) == "within 10 %"
    assert cell_verdict(-1958.3, 1.7e7).startswith("worse by")
    assert cell_verdict(-10.7, -49.0).startswith("better by")
    assert cell_verdict(float("nan"), 1.0) == ""
    assert "|" not in cell_verdict(-1958.3, 1.7e7)  # table cell


def _row(alg: str, fn: str, values: list[float]) -> dict:
    v = np.asarray(values, float)
    return {
        "variant": "shifted",
        "function": fn,
        "algorithm": alg,
        "median": float(np.median(v)),
        "values": list(v),
    }


def test_best_against_best_peer_and_random():
    rng = np.random.default_rng(0)
    low, mid, high = (list(c + rng.random(12)) for c in (0.0, 5.0, 10.0))
    rows = [
        _row("lshade", "sphere", low),
        _row("woa", "sphere", high),
        _row("random", "sphere", high),
        _row("peer:mealpy.OriginalPSO", "sphere", mid),
        _row("peer:niapy.BatAlgorithm", "sphere", high),
    ]
    best = format_best(rows).splitlines()
    assert best[2].startswith("| sphere | lshade |") and "mealpy.OriginalPSO" in best[2]
    assert best[2].endswith("+ (p=4.3e-05) |") or "| + (p=" in best[2]
    vs = format_vs_random(rows)
    assert "| lshade | 0." in vs and "+ (p=" in vs.split("| lshade |")[1].splitlines()[0]
    assert "~ (p=1)" in vs.split("| woa |")[1].splitlines()[0]
    rows[0] = _row("lshade", "sphere", [x + 20 for x in low])  # now worse than random search
    assert "- (p=" in format_vs_random(rows).split("| lshade |")[1].splitlines()[0]
