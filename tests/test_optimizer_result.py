"""An optimizer's ``Result`` prints as one short line (its best cost, budget and sizes), however
long its run: the point and the convergence history stay attributes to read."""

from __future__ import annotations

import numpy as np

from swarmplan.optimizers import make


def test_result_repr_is_one_short_line():
    lower, upper = np.full(30, -5.0), np.full(30, 5.0)
    res = make("pso").minimize(lambda x: (x**2).sum(axis=1), lower, upper, max_evals=3000, seed=1)
    assert len(res.history) > 50 and res.x.shape == (30,)
    text = repr(res)
    assert "\n" not in text and len(text) < 200
    assert f"f={res.f!r}" in text and f"history: {len(res.history)} iterations" in text
    assert "x: 30 values" in text and f"evaluations={res.evaluations}" in text
