"""Baselines: random search, PSO, DE, GA. Honest references for the paper algorithms.

Each baseline uses the textbook settings of its own literature (cited per class), not
settings tuned to beat or lose to the paper algorithms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.optimizers.core import Optimizer, Problem, initial_population
from swarmplan.optimizers.registry import register


def _check_positive(name: str, algo: str, value: float, *, upper: float | None = None) -> None:
    if not np.isfinite(value) or value <= 0 or (upper is not None and value > upper):
        bound = f" and <= {upper}" if upper is not None else ""
        raise ValueError(f"{algo}: {name} must be > 0{bound}, got {value!r}")


def _check_unit(name: str, algo: str, value: float) -> None:
    if not np.isfinite(value) or not 0.0 <= value <= 1.0:
        raise ValueError(f"{algo}: {name} must be in [0, 1], got {value!r}")


def distinct_indices(rng: np.random.Generator, n: int, k: int) -> np.ndarray:
    """``(n, k)`` indices: row ``i`` holds ``k`` distinct indices in ``range(n)``, none equal to ``i``.

    Vectorized: random keys per row with the diagonal masked out, the ``k`` smallest kept.
    """
    if k > n - 1:
        raise ValueError(f"need population >= {k + 1} to draw {k} distinct partners, got {n}")
    keys = rng.random((n, n))
    np.fill_diagonal(keys, np.inf)
    return np.argpartition(keys, k - 1, axis=1)[:, :k]


# --------------------------------------------------------------------------- random search


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


@register
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
        return _PSOState(X=X, V=V, P=X.copy(), Pf=F.copy(), g=int(np.argmin(F)), vmax=vmax)

    def iterate(self, state: _PSOState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        p = self.params
        X, V = state.X, state.V
        n, d = X.shape
        r1 = rng.random((n, d))
        r2 = rng.random((n, d))
        V *= p["w"]
        V += p["c1"] * r1 * (state.P - X) + p["c2"] * r2 * (state.P[state.g] - X)
        np.clip(V, -state.vmax, state.vmax, out=V)
        X += V
        out = (X < problem.lower) | (X > problem.upper)
        if out.any():
            np.clip(X, problem.lower, problem.upper, out=X)
            V[out] = 0.0
        F = problem.evaluate(X)
        better = F < state.Pf
        state.P[better] = X[better]
        state.Pf[better] = F[better]
        state.g = int(np.argmin(state.Pf))


# --------------------------------------------------------------------------- DE


@dataclass
class _DEState:
    X: np.ndarray
    F: np.ndarray


@register
class DE(Optimizer):
    """Differential evolution DE/rand/1/bin (Storn & Price 1997).

    Mutation ``v = x_r1 + F (x_r2 - x_r3)`` with r1, r2, r3 distinct and different from i;
    binomial crossover with rate CR and one forced coordinate; greedy one-to-one selection
    (the trial replaces its parent when ``f(u) <= f(x)``). F = 0.5, CR = 0.9 (Storn & Price's
    recommended start). Bounds: a mutant coordinate outside the box is replaced by the
    midpoint between the parent's coordinate and the violated bound (the repair of
    JADE, Zhang & Sanderson 2009), which keeps the search inside without piling points on
    the bound. Population 50 (Storn & Price suggest 5d-10d; 50 is a budget-friendly default).
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
        return _DEState(X=X, F=problem.evaluate(X))

    def iterate(self, state: _DEState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        X = state.X
        n, d = X.shape
        r = distinct_indices(rng, n, 3)
        V = X[r[:, 0]] + self.params["F"] * (X[r[:, 1]] - X[r[:, 2]])
        # Bound repair: midpoint between parent and the violated bound.
        V = np.where(V < problem.lower, 0.5 * (problem.lower + X), V)
        V = np.where(V > problem.upper, 0.5 * (problem.upper + X), V)
        cross = rng.random((n, d)) <= self.params["CR"]
        cross[np.arange(n), rng.integers(0, d, n)] = True
        U = np.where(cross, V, X)
        Fu = problem.evaluate(U)
        better = Fu <= state.F
        X[better] = U[better]
        state.F[better] = Fu[better]


# --------------------------------------------------------------------------- GA


@dataclass
class _GAState:
    X: np.ndarray
    F: np.ndarray


def sbx_crossover(
    rng: np.random.Generator, P1: np.ndarray, P2: np.ndarray, eta: float, pc: float
) -> tuple[np.ndarray, np.ndarray]:
    """Simulated binary crossover (Deb & Agrawal 1995), vectorized over pairs of parents.

    Each pair crosses with probability ``pc``; within a crossing pair each coordinate is
    recombined with probability 1/2 (Deb's usual per-variable rule). Children may leave the
    box: the caller repairs.
    """
    n, d = P1.shape
    mask = (rng.random((n, 1)) < pc) & (rng.random((n, d)) < 0.5)
    u = rng.random(int(np.count_nonzero(mask)))
    beta = np.where(u <= 0.5, 2.0 * u, 0.5 / (1.0 - u)) ** (1.0 / (eta + 1.0))
    mean = 0.5 * (P1 + P2)
    half = 0.5 * (P1 - P2)
    half[mask] *= beta
    return mean + half, mean - half


def polynomial_mutation(
    rng: np.random.Generator, X: np.ndarray, lower: np.ndarray, upper: np.ndarray, eta: float, pm: float
) -> np.ndarray:
    """Bounded polynomial mutation (Deb & Goyal 1996; bounded form of Deb & Deb 2014).

    Each coordinate mutates with probability ``pm``; results stay inside ``[lower, upper]``.
    Only the mutated coordinates are computed (with pm = 1/d that is about one per row).
    """
    rows, cols = np.nonzero(rng.random(X.shape) < pm)
    if rows.size == 0:
        return X
    lo, hi = lower[cols], upper[cols]
    span = np.where(hi > lo, hi - lo, 1.0)
    x = X[rows, cols]
    u = rng.random(rows.size)
    left = u < 0.5
    # Deb's two branches folded into one: v = min(u, 1 - u), dist = delta1 (left) or delta2.
    v = np.where(left, u, 1.0 - u)
    dist = np.where(left, x - lo, hi - x) / span
    val = 2.0 * v + (1.0 - 2.0 * v) * (1.0 - dist) ** (eta + 1.0)
    mag = 1.0 - val ** (1.0 / (eta + 1.0))
    Y = X.copy()
    Y[rows, cols] = np.clip(x + np.where(left, -mag, mag) * span, lo, hi)
    return Y


@register
class GA(Optimizer):
    """Real-coded generational genetic algorithm with elitism.

    Binary tournament selection (size ``tournament``), simulated binary crossover SBX with
    rate ``crossover_rate`` = 0.9 and index ``eta_c`` = 15, bounded polynomial mutation with
    index ``eta_m`` = 20 and per-coordinate rate ``mutation_rate`` (``None`` = 1/d): the
    settings of Deb's NSGA-II/real-coded GA literature. The best ``elite`` = 2 individuals
    survive unchanged; the other ``population - elite`` are offspring, evaluated in one batch.
    SBX children outside the box are clipped onto it.
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
        return _GAState(X=X, F=problem.evaluate(X))

    def iterate(self, state: _GAState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        p = self.params
        n, d = state.X.shape
        elite = int(p["elite"])
        n_off = n - elite
        n_pairs = (n_off + 1) // 2
        k = int(p["tournament"])
        # Tournament selection: 2 * n_pairs tournaments of size k, winners = lowest cost.
        entrants = rng.integers(0, n, (2 * n_pairs, k))
        winners = entrants[np.arange(2 * n_pairs), np.argmin(state.F[entrants], axis=1)]
        P1, P2 = state.X[winners[:n_pairs]], state.X[winners[n_pairs:]]
        C1, C2 = sbx_crossover(rng, P1, P2, float(p["eta_c"]), float(p["crossover_rate"]))
        children = np.clip(np.vstack((C1, C2))[:n_off], problem.lower, problem.upper)
        pm = 1.0 / d if p["mutation_rate"] is None else float(p["mutation_rate"])
        children = polynomial_mutation(rng, children, problem.lower, problem.upper, float(p["eta_m"]), pm)
        Fc = problem.evaluate(children)
        order = np.argsort(state.F, kind="stable")[:elite]
        state.X = np.vstack((state.X[order], children))
        state.F = np.concatenate((state.F[order], Fc))
