"""Baselines: random search, PSO, DE, GA. Honest references for the paper algorithms.

Each baseline uses the textbook settings of its own literature (cited per class), not
settings tuned to beat or lose to the paper algorithms.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmplan.optimizers.base import Optimizer, Problem, initial_population
from swarmplan.runtime.compiled import kernel_module


def _check_positive(name: str, algo: str, value: float, *, upper: float | None = None) -> None:
    if not np.isfinite(value) or value <= 0 or (upper is not None and value > upper):
        bound = f" and <= {upper}" if upper is not None else ""
        raise ValueError(f"{algo}: {name} must be > 0{bound}, got {value!r}")


def _check_unit(name: str, algo: str, value: float) -> None:
    if not np.isfinite(value) or not 0.0 <= value <= 1.0:
        raise ValueError(f"{algo}: {name} must be in [0, 1], got {value!r}")


def baseline_kernels() -> Any:
    """The compiled generation steps (:mod:`swarmplan.optimizers._baseline_kernels`),
    imported at first use so that importing the registry does not import numba."""
    return kernel_module("swarmplan.optimizers._baseline_kernels")


# --------------------------------------------------------------------------- random search


@dataclass
class _RandomState:
    pass


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

    def iterate(
        self, state: _RandomState, problem: Problem, rng: np.random.Generator, iteration: int
    ) -> None:
        problem.evaluate(problem.uniform(rng, self.population))


# --------------------------------------------------------------------------- PSO


@dataclass
class _PSOState:
    X: np.ndarray  # positions (n, d)
    V: np.ndarray  # velocities (n, d)
    P: np.ndarray  # personal best positions (n, d)
    Pf: np.ndarray  # personal best costs (n,)
    g: int  # index of the swarm's best personal best
    vmax: np.ndarray  # per-dimension velocity clamp (d,)
    coef: tuple[float, float, float]  # w, c1, c2 as floats (one type for the compiled kernel)


class PSO(Optimizer):
    """Global-best inertia-weight particle swarm optimization.

    Velocity update (Shi & Eberhart 1998; constants of Clerc & Kennedy 2002, the
    constriction-equivalent setting w = 0.7298, c1 = c2 = 1.49618):

        v <- w v + c1 r1 (p_i - x) + c2 r2 (g - x),    x <- x + v

    with r1, r2 ~ U(0, 1) drawn per particle and dimension. Velocities are clamped to
    ``vmax_fraction * (upper - lower)`` per dimension. Bounds: a coordinate that leaves the
    box is set onto the violated bound and its velocity component zeroed ("absorbing walls").
    Swarm size 30 (a common choice in the PSO literature).
    """

    name = "pso"
    defaults = {"population": 30, "w": 0.7298, "c1": 1.49618, "c2": 1.49618, "vmax_fraction": 0.2}

    def validate(self) -> None:
        p = self.params
        if not np.isfinite(p["w"]) or not 0 <= p["w"] < 1:
            raise ValueError(f"pso: w must be in [0, 1), got {p['w']!r}")
        for key in ("c1", "c2"):
            if not np.isfinite(p[key]) or p[key] < 0:
                raise ValueError(f"pso: {key} must be >= 0, got {p[key]!r}")
        _check_positive("vmax_fraction", "pso", p["vmax_fraction"], upper=1.0)

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _PSOState:
        n = self.population
        X = initial_population(problem, rng, n, x0)
        vmax = float(self.params["vmax_fraction"]) * problem.span
        V = (2.0 * rng.random((n, problem.dim)) - 1.0) * vmax
        F = problem.evaluate(X)
        coef = (float(self.params["w"]), float(self.params["c1"]), float(self.params["c2"]))
        return _PSOState(X=X, V=V, P=X.copy(), Pf=F.copy(), g=int(np.argmin(F)), vmax=vmax, coef=coef)

    def iterate(self, state: _PSOState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        K = baseline_kernels()
        X = state.X
        R = rng.random((2, *X.shape))  # r1 = R[0], r2 = R[1]: the same stream as two (n, d) draws
        w, c1, c2 = state.coef
        K.pso_move(X, state.V, state.P, state.g, R, w, c1, c2, state.vmax, problem.lower, problem.upper)
        state.g = K.pso_personal_best(X, problem.evaluate(X), state.P, state.Pf)


# --------------------------------------------------------------------------- DE


@dataclass
class _DEState:
    X: np.ndarray
    F: np.ndarray
    U: np.ndarray  # trial vectors (a buffer, rewritten every generation)
    F_scale: float  # the parameters as floats (one type for the compiled kernel)
    CR: float


class DE(Optimizer):
    """Differential evolution DE/rand/1/bin (Storn & Price 1997).

    Mutation ``v = x_r1 + F (x_r2 - x_r3)`` with r1, r2, r3 distinct and different from i;
    binomial crossover with rate CR and one forced coordinate; greedy one-to-one selection
    (the trial replaces its parent when ``f(u) <= f(x)``). F = 0.5, CR = 0.9 (Storn & Price's
    recommended start). Bounds: a mutant coordinate outside the box is replaced by the
    midpoint between the parent's coordinate and the violated bound (the repair of
    JADE, Zhang & Sanderson 2009), which keeps the search inside without piling points on
    the bound. Population 50 (Storn & Price suggest 5d-10d; 50 is a budget-friendly default).
    r1, r2, r3 are drawn uniformly without replacement from the other members, from one
    uniform batch per generation (``_baseline_kernels.de_trials``).
    """

    name = "de"
    defaults = {"population": 50, "F": 0.5, "CR": 0.9}

    def validate(self) -> None:
        _check_positive("F", "de", self.params["F"], upper=2.0)
        _check_unit("CR", "de", self.params["CR"])
        if self.population < 4:
            raise ValueError(f"de: population must be >= 4 for DE/rand/1, got {self.population}")

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _DEState:
        X = initial_population(problem, rng, self.population, x0)
        F = problem.evaluate(X)
        p = self.params
        return _DEState(X=X, F=F, U=np.empty_like(X), F_scale=float(p["F"]), CR=float(p["CR"]))

    def iterate(self, state: _DEState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        K = baseline_kernels()
        n, d = state.X.shape
        # per row: 3 partner draws, the forced coordinate, d crossover tests (one batch)
        R = rng.random((n, d + 4))
        U = state.U
        K.de_trials(state.X, R, state.F_scale, state.CR, problem.lower, problem.upper, U)
        K.de_select(state.X, state.F, U, problem.evaluate(U))


# --------------------------------------------------------------------------- GA


@dataclass
class _GAState:
    X: np.ndarray
    F: np.ndarray
    children: np.ndarray  # (population - elite, d) buffer, rewritten every generation
    draws: tuple[int, int]  # uniforms per generation, of which for the mutation
    pm: float  # per-coordinate mutation probability
    args: tuple[int, float, float]  # tournament size, crossover rate, eta_c (typed for the kernel)
    eta_m: float


class GA(Optimizer):
    """Real-coded generational genetic algorithm with elitism.

    Binary tournament selection (size ``tournament``), simulated binary crossover SBX
    (Deb & Agrawal 1995) with rate ``crossover_rate`` = 0.9 and index ``eta_c`` = 15, bounded
    polynomial mutation (Deb & Goyal 1996; bounded form of Deb & Deb 2014) with index
    ``eta_m`` = 20 and per-coordinate rate ``mutation_rate`` (``None`` = 1/d): the settings of
    Deb's NSGA-II/real-coded GA literature. Each pair crosses with probability
    ``crossover_rate``; within a crossing pair each coordinate is recombined with probability
    1/2 (Deb's usual per-variable rule). The best ``elite`` = 2 individuals survive unchanged;
    the other ``population - elite`` are offspring, evaluated in one batch. SBX children
    outside the box are clipped onto it; mutation keeps them inside. One generation is one
    uniform batch and two compiled calls (``_baseline_kernels.ga_offspring`` / ``ga_survivors``,
    whose docstring gives how each uniform is used).
    """

    name = "ga"
    defaults = {
        "population": 50,
        "tournament": 2,
        "crossover_rate": 0.9,
        "eta_c": 15.0,
        "eta_m": 20.0,
        "mutation_rate": None,
        "elite": 2,
    }

    def validate(self) -> None:
        p = self.params
        if int(p["tournament"]) < 1 or int(p["tournament"]) != p["tournament"]:
            raise ValueError(f"ga: tournament must be an integer >= 1, got {p['tournament']!r}")
        _check_unit("crossover_rate", "ga", p["crossover_rate"])
        _check_positive("eta_c", "ga", p["eta_c"])
        _check_positive("eta_m", "ga", p["eta_m"])
        if p["mutation_rate"] is not None:
            _check_unit("mutation_rate", "ga", p["mutation_rate"])
        if int(p["elite"]) != p["elite"] or not 0 <= int(p["elite"]) < self.population:
            raise ValueError(f"ga: elite must be an integer in [0, population), got {p['elite']!r}")

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _GAState:
        X = initial_population(problem, rng, self.population, x0)
        F = problem.evaluate(X)
        p = self.params
        n_off, d = self.population - int(p["elite"]), problem.dim
        pm = 1.0 / d if p["mutation_rate"] is None else float(p["mutation_rate"])
        draws = baseline_kernels().ga_draws(n_off, d, int(p["tournament"]), pm)
        args = (int(p["tournament"]), float(p["crossover_rate"]), float(p["eta_c"]))
        children = np.empty((n_off, d))
        return _GAState(X=X, F=F, children=children, draws=draws, pm=pm, args=args, eta_m=float(p["eta_m"]))

    def iterate(self, state: _GAState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        K = baseline_kernels()
        children = state.children
        k, pc, eta_c = state.args
        lower, upper = problem.lower, problem.upper
        # one batch: tournaments, crossover tests, per-coordinate SBX draws, mutation draws
        R = rng.random(state.draws[0])
        pos = K.ga_offspring(state.X, state.F, k, R, pc, eta_c, state.pm, state.eta_m, lower, upper, children)
        while pos < children.size:  # the mutation draws ran short (~1e-15 per generation)
            pos = K.ga_mutate(children, rng.random(state.draws[1]), pos, state.pm, state.eta_m, lower, upper)
        K.ga_survivors(state.X, state.F, children, problem.evaluate(children))
