"""Whale family: the whale optimization algorithm (WOA) and RSCDWOA of paper 001.

Paper 001: Zhang, Zhu, Li, Wang, "hybrid WOA for multi-agent dynamic planning" (RSCDWOA +
APF). Section 2.2 (eqs 2-10) restates Mirjalili & Lewis's WOA; section 3 and Algorithm 1
define RSCDWOA: chaotic coefficients (eqs 11-15), reverse search with secondary reflection
(Properties 1-3, eq 16), and a differential-evolution stage with local and global donors on a
ring neighbourhood (eqs 17-23) triggered by a stagnation "lifespan".

Both algorithms are budgeted by evaluations, so the iteration ratio t / t_max of eq (6) is
computed as ``evaluations used / max_evals`` at the start of each generation.

Where the paper is ambiguous the reading chosen is stated in the class docstring.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmplan.optimizers.base import Optimizer, Problem, initial_population
from swarmplan.runtime.compiled import kernel_module

_TWO_PI = 2.0 * np.pi
# Chaotic values are kept in [_CHAOS_EPS, 1 - _CHAOS_EPS]: the open interval (0, 1) of eq (13).
_CHAOS_EPS = 1e-9


# --------------------------------------------------------------------------- chaos maps


def tent_map(w: np.ndarray, beta: float) -> np.ndarray:
    """One step of the (skew) tent map, paper 001 eq (14)."""
    return np.where(w < beta, w / beta, (1.0 - w) / (1.0 - beta))


def logistic_map(w: np.ndarray, mu: float) -> np.ndarray:
    """One step of the logistic map, paper 001 eq (13)."""
    return mu * w * (1.0 - w)


def chaos_step(w: np.ndarray, kind: str, beta: float, mu: float, rng: np.random.Generator) -> np.ndarray:
    """Advance every chaotic sequence in ``w`` by one step, keeping them alive inside (0, 1).

    In floating point a chaotic orbit can land on 0, on 1 (which maps to 0), or exactly on a
    fixed point (tent: 1/(2-beta); logistic mu=4: 3/4) and then stay there forever. Such
    sequences are restarted from a fresh uniform draw of ``rng``; this happens with
    negligible probability and keeps eq (13)'s requirement w in (0, 1).
    """
    nxt = tent_map(w, beta) if kind == "tent" else logistic_map(w, mu)
    dead = (nxt <= _CHAOS_EPS) | (nxt >= 1.0 - _CHAOS_EPS) | (nxt == w) | ~np.isfinite(nxt)
    if dead.any():
        nxt = np.where(dead, rng.uniform(_CHAOS_EPS, 1.0 - _CHAOS_EPS, w.shape), nxt)
    return nxt


def chaos_sequence(
    length: int, kind: str = "tent", *, beta: float = 0.74, mu: float = 4.0, seed: int | None = 0
) -> np.ndarray:
    """The first ``length`` values of one chaotic sequence (for inspection and tests)."""
    rng = np.random.default_rng(seed)
    w = rng.uniform(_CHAOS_EPS, 1.0 - _CHAOS_EPS, 1)
    out = np.empty(length)
    for t in range(length):  # a chaotic orbit is intrinsically sequential
        w = chaos_step(w, kind, beta, mu, rng)
        out[t] = w[0]
    return out


def chaotic_population(
    problem: Problem, rng: np.random.Generator, n: int, kind: str, beta: float, mu: float
) -> np.ndarray:
    """Chaotic initialization (001 abstract and section 3): whale ``i`` sits at ``lower + w_i span``.

    One chaotic orbit per dimension, started from a uniform draw and advanced once per whale
    with the map of eq 13/14, so the whales follow the map's orbit in every coordinate.
    """
    w = rng.uniform(_CHAOS_EPS, 1.0 - _CHAOS_EPS, problem.dim)
    W = np.empty((n, problem.dim))
    for i in range(n):  # a chaotic orbit is intrinsically sequential (n steps, d-vectorized)
        w = chaos_step(w, kind, beta, mu, rng)
        W[i] = w
    return problem.lower + W * problem.span


# --------------------------------------------------------------------------- reverse search


def secondary_reflection(rng: np.random.Generator, X: np.ndarray, lower: np.ndarray, upper: np.ndarray):
    """Secondary reflection reverse points of the rows of ``X``, paper 001 Property 3 / eq (16).

    ``x_r = r_d(x, h)`` with ``h = (l + u) / 2``: a normally distributed number in the interval
    between ``x`` and the box centre ``h``. Reading: mean at the interval's midpoint, standard
    deviation a sixth of its length (so +-3 sigma spans it), clipped into the interval. The
    result always lies between ``x`` and ``h``, hence inside ``[lower, upper]``.
    """
    h = 0.5 * (lower + upper)
    mid = 0.5 * (X + h)
    half = 0.5 * np.abs(h - X)
    Y = mid + (half / 3.0) * rng.standard_normal(X.shape)
    return np.clip(Y, mid - half, mid + half)


# --------------------------------------------------------------------------- kernels


def _k():  # noqa: ANN202
    """The compiled kernels; numba is imported at the first run, not with the package."""
    return kernel_module("swarmplan.optimizers._whale_kernels")


@dataclass
class _Kit:
    """Per-run constants and scratch arrays the kernels take (built at the first generation)."""

    c: np.ndarray  # parameters, laid out as _whale_kernels.C_*
    box: np.ndarray  # (3, d): lower, upper, upper - lower
    idx: np.ndarray  # (n,) int: the DE whales of the generation (first m entries)
    dead: np.ndarray  # (3, n) bool: chaotic values to restart
    none: np.ndarray  # (0, d): stands for the reverse-search arrays of a generation without DE
    lifespan: int = 0  # RSCDWOA: S of Algorithm 1 line 16
    de_draws: int = 0  # RSCDWOA: uniforms per DE whale (see _whale_kernels.de_trials)
    # RSCDWOA's work buffers (Problem.evaluate hands the cost a copy, so the cost may keep
    # what it gets): the next generation's positions (the previous generation's array, swapped
    # with state.X every generation) and the reverse points (first m rows)
    spare: np.ndarray | None = None
    xr: np.ndarray | None = None


def _kit(problem: Problem, n: int, **consts: float) -> _Kit:
    wk = _k()
    c = np.zeros(wk.N_C)
    for key, value in consts.items():
        c[getattr(wk, "C_" + key.upper())] = value
    return _Kit(
        c=c,
        box=np.stack([problem.lower, problem.upper, problem.span]),
        idx=np.zeros(n, dtype=np.int64),
        dead=np.zeros((3, n), dtype=bool),
        none=np.empty((0, problem.dim)),
    )


# --------------------------------------------------------------------------- WOA


@dataclass
class _WOAState:
    X: np.ndarray  # whale positions (n, d)
    F: np.ndarray  # their costs (n,)
    best_x: np.ndarray  # X_*: best position found so far (the prey)
    best_f: float
    kit: _Kit | None = None  # kernel constants and scratch, built at the first generation


class WOA(Optimizer):
    """Whale optimization algorithm, paper 001 section 2.2 (Mirjalili & Lewis 2016).

    Per generation every whale i draws A = 2 a r - a, C = 2 r (eqs 4-5), a spiral parameter
    l ~ U(-1, 1) and q ~ U(0, 1), with ``a = 2 - 2 t / t_max`` (eq 6) decreasing linearly
    from 2 to 0, here with t / t_max = evaluations used / max_evals. Then (eq 8):

    * q < 0.5 and |A| < 1: encircling the prey, eqs (2)-(3): X = X_* - A |C X_* - X|;
    * q < 0.5 and |A| >= 1: search for prey, eqs (9)-(10), the same move towards a randomly
      chosen other whale X_rand instead of X_*;
    * q >= 0.5: bubble-net spiral, eq (7): X = |X_* - X| e^{b l} cos(2 pi l) + X_*, b = 1.

    Readings: A and C are scalars per whale (two independent draws r1, r2), as in the
    reference implementation, which makes the test "|A| >= 1" of eqs (8)-(10) well defined.
    All whales move synchronously from the same X_* and the new population is evaluated in
    one batch; X_* is the best point found so far. Positions leaving the box are clipped
    onto it (the reference implementation's repair). Population 30 (Mirjalili & Lewis).

    WOA is known to favour the box centre (the ``C X_*`` term scales the target towards the
    origin): on the d = 30 sphere it reaches ~1e-160 in 30000 evaluations when the optimum
    is at 0 but only ~1e-2 when the optimum is shifted; benchmark on shifted functions.

    Selection (parameter ``selection``). Mirjalili & Lewis and 001's Algorithm 1 (lines
    8-31) replace every whale by its new position whatever its cost (``"none"``, the
    default). mealpy's ``OriginalWOA`` keeps a whale's old position when the new one is worse
    (one-to-one greedy selection, ``"greedy"`` here): that selection, not the spiral distance,
    the a-schedule, the shared ``r`` of its ``A`` and ``C`` or its uniform ``X_rand``, is what
    makes it stronger on the shifted suite (docs/benchmarks.md, "Shifted suite").
    """

    name = "woa"
    defaults = {"population": 30, "b": 1.0, "selection": "none"}

    def validate(self) -> None:
        b = self.params["b"]
        if not np.isfinite(b):
            raise ValueError(f"woa: b must be finite, got {b!r}")
        if self.params["selection"] not in ("none", "greedy"):
            raise ValueError(f"woa: selection must be 'none' or 'greedy', got {self.params['selection']!r}")

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _WOAState:
        X = initial_population(problem, rng, self.population, x0)
        F = problem.evaluate(X)
        i = int(np.argmin(F))
        return _WOAState(X=X, F=F, best_x=X[i].copy(), best_f=float(F[i]))

    def iterate(self, state: _WOAState, problem: Problem, rng: np.random.Generator, iteration: int) -> None:
        k = _k()
        n, d = state.X.shape
        if state.kit is None:
            state.kit = _kit(problem, n, b=self.params["b"], ell_lo=-1.0, ell_span=2.0)
        kit = state.kit
        a = 2.0 - 2.0 * min(problem.evaluations / problem.max_evals, 1.0)  # eq (6)
        # one draw, rows: r1 for A = 2 a r1 - a (eq 4), r2 for C = 2 r2 (eq 5), the spiral
        # parameter l ~ U(-1, 1) of eq (7) (as U[0, 1), see ell_lo/ell_span), q of eq (8),
        # the partner X_rand of eqs (9)-(10) (whale i + 1 + floor(u (n-1)) mod n, never i)
        r = rng.random((5, n))
        Xn = np.empty((n, d))
        k.woa_move(state.X, state.best_x, r, r[3:], a, kit.c, kit.box, Xn, False, kit.idx)
        F = problem.evaluate(Xn)
        state.best_f = k.settle(
            state.X, F, Xn, F, kit.idx, 0, kit.none, kit.box, kit.none, state.best_x, state.best_f
        )
        if self.params["selection"] == "greedy":  # a whale keeps its old position when the new is worse
            worse = F > state.F
            Xn[worse] = state.X[worse]
            F[worse] = state.F[worse]
        state.X, state.F = Xn, F


# --------------------------------------------------------------------------- RSCDWOA


@dataclass
class _RSCDWOAState:
    X: np.ndarray
    F: np.ndarray
    best_x: np.ndarray
    best_f: float
    w: np.ndarray  # (3, n) chaotic sequences driving A, C and the spiral parameter, per whale
    s: int  # generations since X_* last improved (Algorithm 1, lines 3 and 32)
    kit: _Kit | None = None  # kernel constants and scratch, built at the first generation


class RSCDWOA(Optimizer):
    """Reverse-search chaos differential-evolution WOA, paper 001 section 3 and Algorithm 1.

    One generation, following Algorithm 1 (lines 8-33), for all whales at once:

    1. Chaos (eqs 11-15): the random numbers of WOA are replaced by chaotic sequences w(t),
       tent map (eq 14, ``beta`` = 0.74, section 5.2) or logistic map (eq 13, ``mu`` = 4):
       A = 2 a w - a (eq 11), C = 2 w (eq 12), and the spiral becomes
       X = D' e^{b w} cos(2 pi w) + X_* (eq 15). ``a`` falls linearly from 2 to 0 (eq 6) with
       t / t_max = evaluations used / max_evals. q stays uniformly random.
    2. q <= 0.5 and s < S: WOA encircling (eq 3) when |A| < 1, search for prey towards a
       random whale (eqs 9-10) when |A| >= 1 (lines 10-15).
    3. q <= 0.5 and s >= S (lifespan S exhausted, line 16): differential evolution (line 17-23):
       local donor L (eq 18) from the best of the ring neighbourhood [i-k, i+k] and two
       distinct neighbours p1, p2, with gamma = lambda * rand, lambda = 1e-4 (eq 17); global
       donor G (eq 19) from the population best and two random whales r1 != r2 (!= i);
       V = omega G + (1 - omega) L (eq 20); binomial crossover (eq 21) with one forced
       coordinate chi; perturbation (eq 22) with per-coordinate probability alpha; greedy
       selection (eq 23); then reverse search (eq 16): the secondary reflection reverse point
       of the selected position replaces it when strictly better.
    4. q > 0.5: chaotic bubble-net spiral, eq (15) (line 26).
    5. Positions are clipped into the box (line 28), the batch is evaluated (line 29), X_* is
       updated (line 30) and s is incremented when X_* did not improve (line 32).

    Readings where the paper is ambiguous or silent:

    * w(t): one chaotic sequence per whale for each of A, C and the spiral parameter (three
      independent orbits, advanced once per generation, started from uniform draws), so the
      whales do not all move with the same coefficients. A and C are scalars per whale.
    * Lifespan: s counts *consecutive* generations without improvement of X_* and is reset
      when X_* improves (Algorithm 1 shows only the increment; a counter that never resets
      would switch the encircling branch to DE for good after S flat generations).
      S = 3 (not given in the paper).
    * Eq (21) as printed takes V when rand >= C_rate, which contradicts the text's remark that
      the forced coordinate protects against a too *small* C_rate; the standard DE rule
      (take V when rand <= C_rate or j = chi) is used, C_rate = 0.9.
    * Eq (22) as printed swaps in the parent's own coordinate X_ij, which would make the
      perturbation a no-op and break Lemma 2 (every state reachable). The perturbation vector
      is read as a uniform random point of the box, swapped in per coordinate with
      probability alpha = 0.01 ("a smaller number between 0 and 1", Remark 1).
    * Eq (16), Property 3: see :func:`secondary_reflection` (normal between x and the box
      centre). The reverse search is applied to the DE whales only, after their selection, as
      Algorithm 1 places it (line 22-23); it costs a second, smaller evaluation batch.
    * Initialization (``init``): chaotic, as the abstract lists "the chaotic initialization"
      among RSCDWOA's parts (the text gives no formula): :func:`chaotic_population` with the
      same map as the search (tent, ``beta`` = ``tent_beta`` = 0.74). ``init="uniform"`` is
      plain WOA's random start.
    * F = 0.5, omega = 0.5, ring radius k = 1 (the Fig. 4 example): not given in the paper.
    * All whales move synchronously from the same X_* (Algorithm 1 updates X_* inside the
      per-whale loop); this is what allows one evaluation batch per generation.

    Note the reverse search pulls points towards the box centre, which favours problems whose
    optimum is there (such as the unshifted sphere).
    """

    name = "rscdwoa"
    defaults = {
        "population": 30,
        "b": 1.0,
        "chaos": "tent",
        "beta": 0.74,
        "mu": 4.0,
        "lifespan": 3,
        "F": 0.5,
        "C_rate": 0.9,
        "omega": 0.5,
        "alpha": 0.01,
        "k": 1,
        "lam": 1e-4,
        "init": "chaotic",
    }

    #: names the world-format contract uses (shared/spec/world-format.md) -> our parameter
    aliases = {"tent_beta": "beta"}

    def __init__(self, **params: Any):
        for alias, key in self.aliases.items():
            if alias in params:
                if key in params:
                    raise ValueError(
                        f"rscdwoa: give {alias} or {key}, not both ({alias} is an alias of {key})"
                    )
                params[key] = params.pop(alias)
        super().__init__(**params)

    def validate(self) -> None:
        p = self.params
        if p["chaos"] not in ("tent", "logistic"):
            raise ValueError(f"rscdwoa: chaos must be 'tent' or 'logistic', got {p['chaos']!r}")
        if p["init"] not in ("chaotic", "uniform"):
            raise ValueError(f"rscdwoa: init must be 'chaotic' or 'uniform', got {p['init']!r}")
        if not np.isfinite(p["b"]):
            raise ValueError(f"rscdwoa: b must be finite, got {p['b']!r}")
        if not 0.0 < p["beta"] < 1.0:
            raise ValueError(f"rscdwoa: beta (tent_beta) must be in (0, 1), got {p['beta']!r}")
        if not 0.0 < p["mu"] <= 4.0:
            raise ValueError(f"rscdwoa: mu must be in (0, 4], got {p['mu']!r}")
        if int(p["lifespan"]) != p["lifespan"] or p["lifespan"] < 0:
            raise ValueError(f"rscdwoa: lifespan must be an integer >= 0, got {p['lifespan']!r}")
        if not np.isfinite(p["F"]) or p["F"] <= 0:
            raise ValueError(f"rscdwoa: F must be > 0, got {p['F']!r}")
        for key in ("C_rate", "omega", "alpha"):
            if not 0.0 <= p[key] <= 1.0:
                raise ValueError(f"rscdwoa: {key} must be in [0, 1], got {p[key]!r}")
        if not np.isfinite(p["lam"]) or p["lam"] < 0:
            raise ValueError(f"rscdwoa: lam must be >= 0, got {p['lam']!r}")
        n = self.population
        if n < 3:
            raise ValueError(f"rscdwoa: population must be >= 3 (two distinct random whales), got {n}")
        k = p["k"]
        if int(k) != k or not 1 <= k <= (n - 1) // 2:
            raise ValueError(f"rscdwoa: k must be an integer in [1, (population-1)//2], got {k!r}")

    def setup(self, problem: Problem, rng: np.random.Generator, x0: np.ndarray | None) -> _RSCDWOAState:
        n = self.population
        p = self.params
        if p["init"] == "chaotic":
            X = chaotic_population(problem, rng, n, p["chaos"], p["beta"], p["mu"])
            if x0 is not None:
                X[: min(len(x0), n)] = x0[:n]
        else:
            X = initial_population(problem, rng, n, x0)
        w = rng.uniform(_CHAOS_EPS, 1.0 - _CHAOS_EPS, (3, n))
        F = problem.evaluate(X)
        i = int(np.argmin(F))
        return _RSCDWOAState(X=X, F=F, best_x=X[i].copy(), best_f=float(F[i]), w=w, s=0)

    def iterate(
        self, state: _RSCDWOAState, problem: Problem, rng: np.random.Generator, iteration: int
    ) -> None:
        k = _k()
        p = self.params
        n, d = state.X.shape
        if state.kit is None:
            consts = {key: p[key] for key in ("b", "beta", "mu", "k", "lam", "F", "omega", "alpha")}
            state.kit = _kit(
                problem, n, ell_lo=0.0, ell_span=1.0, q_incl=1.0, tent=p["chaos"] == "tent",
                crate=p["C_rate"], **consts,
            )  # fmt: skip
            state.kit.lifespan = int(p["lifespan"])
            state.kit.de_draws = k.DE_SCALARS + 3 * d
            state.kit.spare, state.kit.xr = np.empty((n, d)), np.empty((n, d))
        kit = state.kit
        a = 2.0 - 2.0 * min(problem.evaluations / problem.max_evals, 1.0)  # eq (6)
        if k.chaos_advance(state.w, kit.c, kit.dead):  # eq (13) / (14); rare: see chaos_step
            fresh = rng.uniform(_CHAOS_EPS, 1.0 - _CHAOS_EPS, state.w.shape)
            state.w[kit.dead] = fresh[kit.dead]
        # one draw, rows: q of Algorithm 1 line 10 (encircling / DE when q <= 0.5), and the
        # random whale of eqs (9)-(10) as a uniform (see _whale_kernels.woa_move)
        qp = rng.random((2, n))
        Xn = kit.spare
        # eqs (3), (9)-(10) and the chaotic spiral (15), A = 2 a w - a (11), C = 2 w (12); the
        # encircling whales go to DE instead once the lifespan is used up (line 16)
        m = k.woa_move(
            state.X, state.best_x, state.w, qp, a, kit.c, kit.box, Xn, state.s >= kit.lifespan, kit.idx
        )
        z = Xr = kit.none
        if m:  # DE stage, eqs (17)-(22): one uniform batch, its layout in _whale_kernels.de_trials
            k.de_trials(state.X, state.F, kit.idx, m, rng.random(m * kit.de_draws), kit.c, kit.box, Xn)
        Fn = problem.evaluate(Xn)  # line 29
        if m:  # reverse search of eq (16) on the DE whales after their selection (eq 23)
            z = rng.standard_normal((m, d))
            Xr = kit.xr[:m]
        best_f = k.settle(state.X, state.F, Xn, Fn, kit.idx, m, z, kit.box, Xr, state.best_x, state.best_f)
        improved = best_f < state.best_f
        kit.spare = state.X
        state.X, state.F, state.best_f = Xn, Fn, best_f
        if m:
            Fr = problem.evaluate(Xr)
            best_f = k.reverse_accept(Xn, Fn, kit.idx, Xr, Fr, state.best_x, state.best_f)
            improved |= best_f < state.best_f
            state.best_f = best_f
        state.s = 0 if improved else state.s + 1  # line 32
