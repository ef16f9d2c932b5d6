"""Same-named algorithms from other Python libraries (mealpy, niapy), run at our budget.

Optional: ``pip install swarmplan[peers]``. Each peer minimizes the same cost on the same box
with the same seed; the objective is wrapped so that only the first ``max_evals`` evaluations
count (the libraries stop on their own budget check, which may overshoot by part of a
generation): the peer's result is the best of those evaluations, exactly as our
``Problem`` accounts for ours. Every peer runs with the suite's population and the library's
own defaults otherwise.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: our registry name -> [(label, library, class path)]
PEERS: dict[str, list[tuple[str, str, str]]] = {
    "woa": [("mealpy.OriginalWOA", "mealpy", "WOA.OriginalWOA")],
    "ba": [("mealpy.OriginalBA", "mealpy", "BA.OriginalBA"), ("niapy.BatAlgorithm", "niapy", "BatAlgorithm")],
    "pso": [
        ("mealpy.OriginalPSO", "mealpy", "PSO.OriginalPSO"),
        ("niapy.ParticleSwarmAlgorithm", "niapy", "ParticleSwarmAlgorithm"),
    ],
    "de": [
        ("mealpy.OriginalDE", "mealpy", "DE.OriginalDE"),
        ("niapy.DifferentialEvolution", "niapy", "DifferentialEvolution"),
    ],
    "ga": [("mealpy.BaseGA", "mealpy", "GA.BaseGA"), ("niapy.GeneticAlgorithm", "niapy", "GeneticAlgorithm")],
    "abc": [
        ("mealpy.OriginalABC", "mealpy", "ABC.OriginalABC"),
        ("niapy.ArtificialBeeColonyAlgorithm", "niapy", "ArtificialBeeColonyAlgorithm"),
    ],
}

INSTALL_HINT = "the peer comparison needs mealpy and niapy: pip install 'swarmplan[peers]'"


def check_installed() -> str | None:
    """``None`` when both libraries import, else a one-line install hint."""
    try:
        import mealpy  # noqa: F401
        import niapy  # noqa: F401
    except ImportError as exc:
        return f"{INSTALL_HINT} ({exc})"
    return None


class _Budgeted:
    """Row-wise objective counting evaluations; only the first ``max_evals`` count."""

    def __init__(
        self, cost: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, max_evals: int
    ):
        self.cost, self.lo, self.hi, self.max_evals = cost, lo, hi, max_evals
        self.evaluations = 0
        self.best = np.inf

    def __call__(self, x: np.ndarray) -> float:
        x = np.clip(np.asarray(x, dtype=float).reshape(1, -1), self.lo, self.hi)
        f = float(self.cost(x)[0])
        self.evaluations += 1
        if self.evaluations <= self.max_evals and f < self.best:
            self.best = f
        return f


def run_peer(
    label: str, cost, lo: np.ndarray, hi: np.ndarray, *, max_evals: int, seed: int, population: int
) -> dict:
    """Run one peer; returns ``{"value", "evaluations"}`` (evaluations counted, capped at ``max_evals``)."""
    lib, path = next((lib, path) for peers in PEERS.values() for lab, lib, path in peers if lab == label)
    obj = _Budgeted(cost, lo, hi, max_evals)
    if lib == "mealpy":
        import mealpy

        module, cls = path.split(".")
        # epoch = budget / population so that schedules (e.g. WOA's ``a``) run their full course
        epochs = max(1, -(-max_evals // population))
        model = getattr(getattr(mealpy, module), cls)(epoch=epochs, pop_size=population)
        problem = {
            "obj_func": obj,
            "bounds": mealpy.FloatVar(lb=lo.tolist(), ub=hi.tolist()),
            "minmax": "min",
            "log_to": None,
        }
        model.solve(problem, termination={"max_fe": max_evals}, seed=seed)
    else:
        from niapy import algorithms
        from niapy.problems import Problem
        from niapy.task import Task

        class _P(Problem):
            def __init__(self) -> None:
                super().__init__(len(lo), lo, hi)

            def _evaluate(self, x):
                return obj(x)

        algo = getattr(algorithms.basic, path)(population_size=population, seed=seed)
        algo.run(Task(problem=_P(), max_evals=max_evals))
    return {"value": obj.best, "evaluations": min(obj.evaluations, max_evals)}
