"""L-SHADE: success-history adaptive differential evolution with linear population size
reduction (Tanabe & Fukunaga, CEC 2014), a strong general-purpose baseline.

Not one of the papers' algorithms: it is here as an honest, well-known reference point (the
winner of the CEC 2014 single-objective competition) next to the textbook ``de``, so that
"the best of ours" on a benchmark is a documented algorithm at its published settings and not
a paper algorithm tuned to the benchmark. Everything follows the paper (Tanabe & Fukunaga
2014, Algorithm 1 and section III):

* mutation current-to-pbest/1 with an external archive:
  ``v = x_i + F (x_pbest - x_i) + F (x_r1 - x_r2)``, ``x_pbest`` uniformly among the best
  ``max(2, round(p n))`` members, ``x_r1 != x_i`` from the population, ``x_r2 != x_r1, x_i``
  from the population and the archive together;
* binomial crossover with one forced coordinate;
* bound repair: a coordinate outside the box is set halfway between the parent's coordinate
  and the violated bound (JADE's rule, kept by L-SHADE);
* per trial ``CR ~ N(M_CR[k], 0.1)`` clipped to ``[0, 1]`` (0 when ``M_CR[k]`` is the
  terminal value) and ``F ~ Cauchy(M_F[k], 0.1)``, redrawn while ``<= 0`` and truncated at 1,
  with ``k`` a uniformly chosen cell of the ``H``-cell success history;
* greedy one-to-one selection (the trial wins ties); replaced parents go to the archive
  (size ``round(arc_rate n)``, random members removed when full);
* memory update with the improvement-weighted Lehmer mean (``M_F``) and, since L-SHADE,
  the weighted Lehmer mean for ``M_CR`` too; ``M_CR`` becomes terminal once its max is 0;
* linear population size reduction from ``population`` to ``n_min = 4`` over the
  evaluation budget, dropping the worst members (and shrinking the archive with it).

Settings (the paper's): ``p = 0.11``, ``H = 6``, ``arc_rate = 2.6``; memories start at 0.5.
The paper's initial population is ``18 d``; the registry default is 100 (a fixed number, like
every other entry here; benchmarks that fix the population pass it explicitly).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.optimizers.base import Optimizer, Problem, initial_population

_N_MIN = 4


@dataclass
class _ShadeState:
    X: np.ndarray  # population (n, d)
    F: np.ndarray  # costs (n,)
    archive: np.ndarray  # replaced parents (k, d)
    m_cr: np.ndarray  # (H,) success history of CR (nan = terminal value)
    m_f: np.ndarray  # (H,) success history of F
    k: int  # next memory cell to write
    n_init: int


class LShade(Optimizer):
    """L-SHADE (Tanabe & Fukunaga 2014): see the module docstring for every step."""

    name = "lshade"
    defaults = {"population": 100, "p": 0.11, "H": 6, "arc_rate": 2.6}

    def validate(self) -> None:
        p = self.params
        if not (np.isfinite(p["p"]) and 0.0 < p["p"] <= 1.0):
            raise ValueError(f"lshade: p must be in (0, 1], got {p['p']!r}")
        if int(p["H"]) != p["H"] or p["H"] < 1:
            raise ValueError(f"lshade: H must be an integer >= 1, got {p['H']!r}")
        if not (np.isfinite(p["arc_rate"]) and p["arc_rate"] >= 0.0):
            raise ValueError(f"lshade: arc_rate must be >= 0, got {p['arc_rate']!r}")
        if self.population < _N_MIN:
            raise ValueError(f"lshade: population must be >= {_N_MIN}, got {self.population}")

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _ShadeState:
        n = self.population
        X = initial_population(problem, rng, n, x0)
        F = problem.evaluate(X)
        H = int(self.params["H"])
        return _ShadeState(
            X=X,
            F=F,
            archive=np.empty((0, problem.dim)),
            m_cr=np.full(H, 0.5),
            m_f=np.full(H, 0.5),
            k=0,
            n_init=n,
        )

    def iterate(self, state: _ShadeState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        prm = self.params
        X, Fx = state.X, state.F
        n, d = X.shape
        H = state.m_cr.size
        # parameters of each trial from a random memory cell
        cell = rng.integers(H, size=n)
        mcr = state.m_cr[cell]
        cr = np.where(np.isnan(mcr), 0.0, np.clip(rng.normal(np.nan_to_num(mcr), 0.1), 0.0, 1.0))
        mf = state.m_f[cell]
        f = mf + 0.1 * np.tan(np.pi * (rng.random(n) - 0.5))
        bad = f <= 0.0
        while bad.any():  # Cauchy draws <= 0 are redrawn (the paper's rule)
            f[bad] = mf[bad] + 0.1 * np.tan(np.pi * (rng.random(int(bad.sum())) - 0.5))
            bad = f <= 0.0
        f = np.minimum(f, 1.0)
        # current-to-pbest/1 with the archive
        order = np.argsort(Fx, kind="stable")
        n_p = max(2, int(round(prm["p"] * n)))
        pbest = order[rng.integers(n_p, size=n)]
        idx = np.arange(n)
        r1 = (idx + 1 + rng.integers(n - 1, size=n)) % n  # != i
        pool = np.vstack([X, state.archive]) if len(state.archive) else X
        m = len(pool)
        r2 = rng.integers(m, size=n)
        clash = (r2 == idx) | (r2 == r1)
        while clash.any():  # != i and != r1 (uniform over the rest)
            r2[clash] = rng.integers(m, size=int(clash.sum()))
            clash = (r2 == idx) | (r2 == r1)
        fc = f[:, None]
        V = X + fc * (X[pbest] - X) + fc * (X[r1] - pool[r2])
        # bound repair: halfway between the parent and the violated bound
        lo, hi = problem.lower, problem.upper
        V = np.where(V < lo, 0.5 * (lo + X), V)
        V = np.where(V > hi, 0.5 * (hi + X), V)
        # binomial crossover, one forced coordinate per trial
        take = rng.random((n, d)) < cr[:, None]
        take[idx, rng.integers(d, size=n)] = True
        U = np.where(take, V, X)
        Fu = problem.evaluate(U)
        # selection and success history
        better = Fu < Fx
        win = Fu <= Fx
        if better.any():
            lost = X[better]
            state.archive = np.vstack([state.archive, lost]) if len(state.archive) else lost.copy()
            gain = Fx[better] - Fu[better]
            total = gain.sum()
            # improvement weights; equal weights when a parent's cost was inf (no finite gain)
            w = gain / total if np.isfinite(total) and total > 0 else np.full(gain.size, 1.0 / gain.size)
            s_f, s_cr = f[better], cr[better]
            state.m_f[state.k] = np.sum(w * s_f**2) / np.sum(w * s_f)
            if np.isnan(state.m_cr[state.k]) or s_cr.max() == 0.0:
                state.m_cr[state.k] = np.nan
            else:
                state.m_cr[state.k] = np.sum(w * s_cr**2) / np.sum(w * s_cr)
            state.k = (state.k + 1) % H
        X = np.where(win[:, None], U, X)
        Fx = np.where(win, Fu, Fx)
        # linear population size reduction over the budget
        frac = problem.evaluations / problem.max_evals
        n_next = max(_N_MIN, int(round(state.n_init + (_N_MIN - state.n_init) * frac)))
        if n_next < n:
            keep = np.sort(np.argsort(Fx, kind="stable")[:n_next])
            X, Fx = X[keep], Fx[keep]
        arc_max = int(round(prm["arc_rate"] * len(X)))
        if len(state.archive) > arc_max:
            state.archive = state.archive[rng.choice(len(state.archive), arc_max, replace=False)]
        state.X, state.F = X, Fx
