"""Textbook artificial bee colony (ABC): Karaboga & Basturk, J. Glob. Optim. 39 (2007) 459-471.

Paper 000 compares its IBA against ABC (Table 10), and ABC is the strongest same-named peer
in this field's Python libraries (niapy, mealpy), so the registry carries the plain
algorithm as a reference. Nothing here is tuned: the settings are Karaboga's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.optimizers.base import Optimizer, Problem, initial_population
from swarmplan.optimizers.baselines import baseline_kernels


@dataclass
class _AbcState:
    X: np.ndarray  # (SN, d) food sources
    fit: np.ndarray  # (SN,) their costs
    trial: np.ndarray  # (SN,) cycles without improvement
    V: np.ndarray  # (SN, d) candidates of the current phase (a buffer)
    src: np.ndarray  # (SN,) their sources


class ArtificialBeeColony(Optimizer):
    """Artificial bee colony (Karaboga & Basturk 2007), one cycle per generation.

    ``population`` is the colony size: ``SN = population // 2`` food sources, one employed
    bee each, and ``SN`` onlookers.

    1. Employed phase: every source ``i`` tries ``v_ij = x_ij + phi (x_ij - x_kj)``
       (one random dimension ``j``, a random partner ``k != i``, ``phi ~ U(-1, 1)``); greedy
       selection; a source that does not improve increments its trial counter.
    2. Onlooker phase: ``SN`` onlookers choose sources by roulette on
       ``fit = 1/(1+f)`` (``1+|f|`` for ``f <= 0``; paper 000 eq 20 uses the same) and try the
       same move from them; greedy selection.
    3. Scout phase: the source with the most trials, if that exceeds ``limit``, is replaced by
       a uniform random point (at most one scout per cycle, as in Karaboga's code).

    Reading for batching: each phase is evaluated as one batch, so the onlookers of one cycle
    all start from the sources as they stand after the employed phase and each source keeps
    the best of the candidates built from it (the sequential original would let a later
    onlooker start from an earlier onlooker's improvement). Trial counters count *phases*
    without improvement for the sources that were tried, as in the original. Per phase: one
    uniform batch, one compiled call to build the candidates and one for the greedy selection
    (``_baseline_kernels.abc_moves`` / ``abc_greedy``, which say how each uniform is used).

    Defaults: colony 40 (SN = 20), ``limit = None`` meaning ``SN * d`` (Karaboga & Basturk's
    recommendation).
    """

    name = "abc"
    defaults = {"population": 40, "limit": None}

    def validate(self) -> None:
        p = self.params
        if self.population < 4:
            raise ValueError(
                f"{self.name}: population must be >= 4 (two food sources), got {self.population}"
            )
        if p["limit"] is not None and (int(p["limit"]) != p["limit"] or p["limit"] < 1):
            raise ValueError(
                f"{self.name}: limit must be None (SN * d) or an integer >= 1, got {p['limit']!r}"
            )

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _AbcState:
        sn = self.population // 2
        X = initial_population(problem, rng, sn, x0)
        fit = problem.evaluate(X)
        trial = np.zeros(sn, dtype=np.int64)
        return _AbcState(X=X, fit=fit, trial=trial, V=np.empty_like(X), src=np.empty(sn, dtype=np.int64))

    def iterate(self, state: _AbcState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        K = baseline_kernels()
        sn, d = state.X.shape
        limit = sn * d if self.params["limit"] is None else int(self.params["limit"])
        # one batch per phase: partner, dimension, phi (and the onlookers' roulette spin)
        R = rng.random((2, 4, sn))
        # 1. employed bees
        V, src = state.V, state.src
        K.abc_moves(state.X, state.fit, R[0], False, problem.lower, problem.upper, V, src)
        K.abc_greedy(state.X, state.fit, state.trial, src, V, problem.evaluate(V))
        # 2. onlookers
        K.abc_moves(state.X, state.fit, R[1], True, problem.lower, problem.upper, V, src)
        i = K.abc_greedy(state.X, state.fit, state.trial, src, V, problem.evaluate(V))
        # 3. one scout: the source with the most trials (the first on ties)
        if state.trial[i] > limit:
            state.X[i] = problem.uniform(rng, 1)[0]
            state.fit[i] = problem.evaluate(state.X[i : i + 1])[0]
            state.trial[i] = 0
