"""Baselines: random search, PSO, DE, GA. Honest references for the paper algorithms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.optimizers.core import Optimizer, Problem
from swarmplan.optimizers.registry import register


@dataclass
class _RandomState:
    pass


@register
class RandomSearch(Optimizer):
    """Uniform random sampling of the box, one population-sized batch per iteration."""

    name = "random"
    defaults = {"population": 30}

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _RandomState:
        X = problem.uniform(rng, self.population)
        if x0 is not None:
            X[: len(x0)] = x0[: len(X)]
        problem.evaluate(X)
        return _RandomState()

    def iterate(self, state: _RandomState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        problem.evaluate(problem.uniform(rng, self.population))
