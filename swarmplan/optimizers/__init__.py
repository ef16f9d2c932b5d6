"""Metaheuristic optimizers behind one interface.

``make(name, **params).minimize(cost, lower, upper, max_evals=...)`` minimizes a vectorized cost.

Each family lives in its own module (``baselines``, ``bat``, ``bat_gauss``, ``bee_colony``,
``central_force``, ``fish_swarm``, ``whale``); ``make`` imports the one it needs
(``registry.BUILTIN``).
"""

from swarmplan.optimizers.base import Optimizer, Problem, Result
from swarmplan.optimizers.registry import available, defaults, make, optimizer_class, register

__all__ = ["Optimizer", "Problem", "Result", "available", "defaults", "make", "optimizer_class", "register"]
