"""Metaheuristic optimizers behind one interface.

``make(name, **params).minimize(cost, lower, upper, max_evals=...)`` minimizes a vectorized cost.

Each family lives in its own module; importing this package registers them all.
"""

# Importing the family modules registers their algorithms.
from swarmplan.optimizers import baselines, bat, bat_gauss, bee_colony, central_force, fish_swarm, whale  # noqa: F401
from swarmplan.optimizers.core import Optimizer, Problem, Result
from swarmplan.optimizers.registry import available, defaults, make, register

__all__ = ["Optimizer", "Problem", "Result", "available", "defaults", "make", "register"]
