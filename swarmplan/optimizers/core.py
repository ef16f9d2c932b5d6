"""Contracts shared by every optimizer: the budgeted problem, the result, the base class.

Design (after pymoo): an algorithm proposes a whole population as one ``(n, d)`` array and
the :class:`Problem` evaluates it in one call to the user's vectorized cost. All run state
lives in the per-call ``state`` object an algorithm builds in :meth:`Optimizer.setup`; the
optimizer object itself only holds its (immutable) parameters, so two ``minimize`` calls
never interfere. Randomness comes from one ``np.random.Generator`` passed explicitly.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from swarmplan.runtime.compiled import kernel_module

CostFn = Callable[[np.ndarray], np.ndarray]
Callback = Callable[[int, np.ndarray, float], "bool | None"]


class BudgetExhausted(Exception):
    """Raised inside an iteration when ``max_evals`` is used up; the run then stops cleanly."""


@dataclass(frozen=True)
class Result:
    """Outcome of one ``minimize`` call.

    ``x`` is the best point ever evaluated and ``f`` its cost exactly as the cost function
    returned it; ``history[k]`` is the best cost found up to the end of iteration ``k``
    (iteration 0 is the initial population).
    """

    x: np.ndarray
    f: float
    evaluations: int
    iterations: int
    history: np.ndarray
    wall_time: float
    algorithm: str = ""

    def __repr__(self) -> str:
        """One line: the best cost, the budget used and the point's size (``x`` and the
        per-iteration ``history`` are attributes to read, too long to print)."""
        return (
            f"Result(algorithm={self.algorithm!r}, f={self.f!r}, evaluations={self.evaluations}, "
            f"iterations={self.iterations}, x: {np.shape(self.x)[0] if np.ndim(self.x) else 1} values, "
            f"history: {len(self.history)} iterations, wall_time={self.wall_time:.3g} s)"
        )


_F64 = np.dtype(np.float64)
_kernels: Any = None

#: algorithms (name and parameters) whose compiled kernels this process has loaded
_WARMED: set[tuple[str, str]] = set()
#: generations of the warm-up run: enough to pass every kernel an algorithm calls periodically
WARM_UP_GENERATIONS = 12


def kernels() -> Any:
    """The compiled helpers (:mod:`swarmplan.optimizers._kernels`), imported at first use.

    numba's import costs ~0.5 s, so nothing imports it before the first ``Problem`` is
    built; the planner's start-up (which imports the registry) stays free of it.
    """
    global _kernels
    _kernels = kernel_module("swarmplan.optimizers._kernels")
    return _kernels


class Problem:
    """A cost function with box bounds and an evaluation budget.

    ``evaluate`` clips candidates into the box (a guard: algorithms repair bounds their own
    way first), evaluates at most the remaining budget of rows, and remembers the best point.
    When the budget runs out mid-batch the rows that could not be evaluated get ``inf`` and
    :class:`BudgetExhausted` is raised *after* the best point has been updated.

    Fast path (optimizer overhead): ``evaluate`` costs two compiled calls besides
    the user's cost when it gets a float64 ``(n, d)`` ndarray and the cost returns a float64
    ``(k,)`` ndarray; anything else (lists, other dtypes, ``(k, 1)`` costs) takes the general
    path with the same results. ``uniform`` is one batched draw plus one compiled call. The
    array passed to the cost is always a fresh C-ordered copy (the cost may keep or modify
    it), the returned costs are a fresh array the caller may keep and update; so an
    algorithm may pass its own work buffers (no copy needed on its side). For the rest of a
    generation the same recipe pays off: one ``rng.random`` batch per generation and one
    compiled kernel over the whole population (see ``_baseline_kernels.py``); never pass the
    ``Generator`` into a numba kernel (~20 µs to unbox per call).
    """

    def __init__(self, cost: CostFn, lower: np.ndarray, upper: np.ndarray, max_evals: int):
        self.cost = cost
        self.lower = np.ascontiguousarray(lower, dtype=float).reshape(-1)
        self.upper = np.ascontiguousarray(upper, dtype=float).reshape(-1)
        if self.lower.shape != self.upper.shape:
            raise ValueError(f"lower and upper differ in shape: {self.lower.shape} vs {self.upper.shape}")
        if not np.all(np.isfinite(self.lower)) or not np.all(np.isfinite(self.upper)):
            raise ValueError("lower and upper must be finite")
        if np.any(self.lower > self.upper):
            raise ValueError("every lower bound must be <= its upper bound")
        if int(max_evals) < 1:
            raise ValueError(f"max_evals must be >= 1, got {max_evals}")
        self.dim = self.lower.size
        self.span = self.upper - self.lower
        self.max_evals = int(max_evals)
        self.evaluations = 0
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf
        kernels()  # numba is imported here, at the first Problem (evaluate reads _kernels)

    @property
    def remaining(self) -> int:
        return self.max_evals - self.evaluations

    def clip(self, X: np.ndarray) -> np.ndarray:
        # two ufunc calls: same values as np.clip without its Python-level dispatch (overhead)
        return np.minimum(np.maximum(X, self.lower), self.upper)

    def uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points drawn uniformly in the box: ``lower + U * span``, ``U ~ U[0, 1)^(n, d)``."""
        return _kernels.scale_into_box(rng.random((n, self.dim)), self.lower, self.span)

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        if type(X) is not np.ndarray or X.dtype is not _F64 or X.ndim != 2:
            X = np.atleast_2d(np.asarray(X, dtype=float))
        n, d = X.shape
        if d != self.dim:
            raise ValueError(f"candidates have {d} columns, problem has {self.dim}")
        k = self.max_evals - self.evaluations
        if k <= 0:
            raise BudgetExhausted
        if n < k:
            k = n
            if n == 0:  # nothing to evaluate (the cost still sees the empty batch, as before)
                f = np.asarray(self.cost(X[:0].copy()), dtype=float).reshape(-1)
                if f.shape != (0,):
                    raise ValueError(f"cost returned shape {f.shape} for 0 candidates; expected (0,)")
                return f.copy()
        K = _kernels
        # a fresh copy: the cost may keep or modify its argument, the algorithm's array stays
        Xe = np.empty((k, d))
        K.clip_into(X, Xe, self.lower, self.upper)
        f = self.cost(Xe)
        if type(f) is not np.ndarray or f.dtype is not _F64 or f.ndim != 1:
            f = np.asarray(f, dtype=float).reshape(-1)
        if f.shape[0] != k:
            raise ValueError(f"cost returned shape {f.shape} for {k} candidates; expected ({k},)")
        # a copy with NaN -> inf (algorithms keep and update it) and its argmin
        fe = np.empty(k)
        i = K.finish_costs(f, fe)
        self.evaluations += k
        fi = float(fe[i])
        if fi < self.best_f or self.best_x is None:
            self.best_f = fi
            self.best_x = Xe[i].copy()
        if k == n:
            return fe
        raise BudgetExhausted


class Optimizer(ABC):
    """Base class of every algorithm.

    Subclasses declare ``name`` and ``defaults`` (the paper's recommended settings, and a
    docstring citing equations), and implement :meth:`setup` (build and evaluate the
    initial population, return a state object) and :meth:`iterate` (one generation).
    """

    name: ClassVar[str] = ""
    defaults: ClassVar[Mapping[str, Any]] = {"population": 30}

    def __init__(self, **params: Any):
        unknown = sorted(set(params) - set(self.defaults))
        if unknown:
            known = ", ".join(sorted(self.defaults))
            raise ValueError(f"{self.name}: unknown parameter(s) {', '.join(unknown)}; known: {known}")
        merged = dict(self.defaults)
        merged.update(params)
        if int(merged["population"]) < 2:
            raise ValueError(f"{self.name}: population must be >= 2, got {merged['population']}")
        self.params: Mapping[str, Any] = merged
        self.validate()

    def validate(self) -> None:  # noqa: B027 - optional hook, most algorithms need no checks
        """Check parameter values; raise ``ValueError`` naming the bad one."""

    @property
    def population(self) -> int:
        return int(self.params["population"])

    @abstractmethod
    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> Any:
        """Create, evaluate and return the initial run state."""

    @abstractmethod
    def iterate(self, state: Any, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        """Advance ``state`` by one generation (``iteration`` counts from 1)."""

    def warm_up(self, dim: int = 4) -> None:
        """Load the compiled kernels (numba) this algorithm calls, once per process.

        numba loads cached machine code at a kernel's first call in a process (0.5-1 s in all,
        more on a fresh machine, where it compiles). Planners call this before they time a
        plan, so that ``planning_ms`` and ``/optimizer`` ``wall_ms`` measure planning and the
        load lands in the run's start-up. A tiny sphere with its own seed: the caller's random
        streams are untouched.
        """
        key = (self.name, repr(sorted(self.params.items())))
        if key in _WARMED:
            return
        lower, upper = np.zeros(dim), np.ones(dim)
        self.minimize(_warm_up_cost, lower, upper, max_evals=WARM_UP_GENERATIONS * self.population, seed=0)
        _WARMED.add(key)

    def minimize(
        self,
        cost: CostFn,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        max_evals: int,
        seed: int | np.random.Generator | None = None,
        x0: np.ndarray | None = None,
        callback: Callback | None = None,
    ) -> Result:
        """Minimize ``cost`` over the box ``[lower, upper]`` with at most ``max_evals`` evaluations.

        ``x0`` (``(d,)`` or ``(k, d)``) seeds the initial population. ``callback(iteration,
        best_x, best_f)`` runs after every iteration; returning ``True`` stops the run.
        """
        start = time.perf_counter()
        problem = Problem(cost, lower, upper, max_evals)
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        if x0 is not None:
            x0 = problem.clip(np.atleast_2d(np.asarray(x0, dtype=float)))
            if x0.shape[1] != problem.dim:
                raise ValueError(f"x0 has {x0.shape[1]} columns, bounds have {problem.dim}")
        history: list[float] = []
        iteration = 0
        try:
            state = self.setup(problem, rng, x0)
            history.append(problem.best_f)
            iterate = self.iterate
            while problem.evaluations < problem.max_evals:
                iteration += 1
                iterate(state, problem, rng, iteration)
                history.append(problem.best_f)
                if callback is not None and callback(iteration, problem.best_x.copy(), problem.best_f):
                    break
        except BudgetExhausted:
            history.append(problem.best_f)
        if problem.best_x is None:  # budget smaller than anything evaluated: impossible, but be explicit
            raise RuntimeError(f"{self.name}: no point was evaluated")
        return Result(
            x=problem.best_x.copy(),
            f=float(problem.best_f),
            evaluations=problem.evaluations,
            iterations=iteration,
            history=np.asarray(history, dtype=float),
            wall_time=time.perf_counter() - start,
            algorithm=self.name,
        )

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{type(self).__name__}({args})"


def _warm_up_cost(X: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", X - 0.5, X - 0.5)


def initial_population(
    problem: Problem, rng: np.random.Generator, n: int, x0: np.ndarray | None
) -> np.ndarray:
    """``n`` uniform points in the box, the first rows replaced by ``x0`` when given."""
    X = problem.uniform(rng, n)
    if x0 is not None:
        k = min(len(x0), n)
        X[:k] = x0[:k]
    return X
