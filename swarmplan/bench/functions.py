"""Vectorized benchmark functions, ``(n, d) -> (n,)``, and their shifted versions.

Every function takes a 2-D array of ``n`` candidates of dimension ``d`` and returns ``n``
costs. :class:`Benchmark` bundles a function with its usual box, its known optimum (point
and value, when known) and builds plain or *shifted* costs with :meth:`Benchmark.cost`.

Shifted versions evaluate ``f(x - o)``: the optimum moves from ``x*`` to ``x* + o``, away from
the origin and from the box centre (each coordinate of ``x* + o`` lies 20-40 % of the box
width from the centre, on a random but fixed side), so an algorithm that drifts to the
centre of the box or collapses onto zero gets no free win. The shift vector depends only
on the function name and ``d``, so a shifted function is the same in every run and process.

Definitions follow the papers in ``/work/shared/seeds`` where they give one; where their
printed formula is garbled we use the standard definition and say so in the docstring.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Fn = Callable[[np.ndarray], np.ndarray]


def _idx(X: np.ndarray) -> np.ndarray:
    return np.arange(1, X.shape[1] + 1, dtype=float)


def sphere(X: np.ndarray) -> np.ndarray:
    """De Jong's sphere: ``sum x_i^2`` (000 eq 17, 001 f1). Minimum 0 at 0."""
    return np.einsum("ij,ij->i", X, X)


def rosenbrock(X: np.ndarray) -> np.ndarray:
    """``sum 100 (x_{i+1} - x_i^2)^2 + (x_i - 1)^2``. Minimum 0 at 1.

    000 eq 16 prints ``(1 - x_i^2)^2`` and 001 f5 drops the square on the first term; both
    are extraction/typesetting slips, we use the standard Rosenbrock.
    """
    a = X[:, 1:] - X[:, :-1] ** 2
    b = X[:, :-1] - 1.0
    return np.sum(100.0 * a * a + b * b, axis=1)


def michalewicz(X: np.ndarray, m: int = 10) -> np.ndarray:
    """``-sum sin(x_i) sin(i x_i^2 / pi)^(2m)``, m = 10 (000 eq 18).

    On 000's box ``[-100, 100]^d`` the infimum is (almost) ``-d`` since both sines can be 1.
    """
    s = np.sin(_idx(X) * X * X / np.pi)
    return -np.sum(np.sin(X) * s ** (2 * m), axis=1)


def dixon_price(X: np.ndarray) -> np.ndarray:
    """``(x_1 - 1)^2 + sum_{i>=2} i (2 x_i^2 - x_{i-1})^2`` (000 eq 19).

    Minimum 0 at ``x_i = 2^{-(2^i - 2) / 2^i}`` (000 says "at x_i = 0", which is wrong).
    """
    i = _idx(X)[1:]
    t = 2.0 * X[:, 1:] ** 2 - X[:, :-1]
    return (X[:, 0] - 1.0) ** 2 + np.sum(i * t * t, axis=1)


def dixon_price_xopt(d: int) -> np.ndarray:
    i = np.arange(1, d + 1, dtype=float)
    return 2.0 ** (-(2.0**i - 2.0) / 2.0**i)


def sum_squares(X: np.ndarray) -> np.ndarray:
    """Axis-parallel hyper-ellipsoid / SumSquares: ``sum i x_i^2`` (000 f5, 001 f2)."""
    return np.sum(_idx(X) * X * X, axis=1)


def rotated_ellipsoid(X: np.ndarray) -> np.ndarray:
    """Rotated hyper-ellipsoid: ``sum_i sum_{j<=i} x_j^2`` (000 f6)."""
    return np.sum(np.cumsum(X * X, axis=1), axis=1)


def rastrigin(X: np.ndarray) -> np.ndarray:
    """``10 d + sum x_i^2 - 10 cos(2 pi x_i)`` (000 f7, 001 f7). Minimum 0 at 0."""
    return 10.0 * X.shape[1] + np.sum(X * X - 10.0 * np.cos(2.0 * np.pi * X), axis=1)


def schwefel_2_22(X: np.ndarray) -> np.ndarray:
    """``sum |x_i| + prod |x_i|`` (000 f8, 001 f6; the extraction lost the bars)."""
    A = np.abs(X)
    with np.errstate(over="ignore"):
        return np.sum(A, axis=1) + np.prod(A, axis=1)


def sum_powers(X: np.ndarray) -> np.ndarray:
    """Sum of different powers ``sum |x_i|^(i+1)`` (000 f9).

    000's Table 9 as extracted reads ``|x_i|^{|x_i|+1}``; the function it names ("sum of
    different powers", from the Virtual Library of Simulation Experiments like 000's other
    additions) is ``|x_i|^{i+1}``, which we use. Minimum 0 at 0.
    """
    with np.errstate(over="ignore"):
        return np.sum(np.abs(X) ** (_idx(X) + 1.0), axis=1)


def styblinski_tang(X: np.ndarray) -> np.ndarray:
    """``0.5 sum x_i^4 - 16 x_i^2 + 5 x_i`` (000 f10). Minimum ``-39.16617 d`` at ``x_i = -2.903534``."""
    X2 = X * X
    return 0.5 * np.sum(X2 * X2 - 16.0 * X2 + 5.0 * X, axis=1)


def step(X: np.ndarray) -> np.ndarray:
    """``sum floor(x_i + 0.5)^2`` (001 f3). Minimum 0 on ``[-0.5, 0.5)^d``."""
    Y = np.floor(X + 0.5)
    return np.sum(Y * Y, axis=1)


def quartic_noiseless(X: np.ndarray) -> np.ndarray:
    """``sum i x_i^4`` (001 f4 without its noise term)."""
    X2 = X * X
    return np.sum(_idx(X) * X2 * X2, axis=1)


def griewank(X: np.ndarray) -> np.ndarray:
    """``sum x_i^2 / 4000 - prod cos(x_i / sqrt(i)) + 1`` (001 f8)."""
    return np.sum(X * X, axis=1) / 4000.0 - np.prod(np.cos(X / np.sqrt(_idx(X))), axis=1) + 1.0


def ackley(X: np.ndarray) -> np.ndarray:
    """Ackley (001 f9). Minimum 0 at 0."""
    d = X.shape[1]
    r = np.sqrt(np.sum(X * X, axis=1) / d)
    c = np.sum(np.cos(2.0 * np.pi * X), axis=1) / d
    return -20.0 * np.exp(-0.2 * r) - np.exp(c) + 20.0 + np.e


class Quartic:
    """001 f4, ``sum i x_i^4 + random[0, 1)``: noisy, so it carries its own generator."""

    def __init__(self, seed: int | None = None):
        self.rng = np.random.default_rng(seed)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return quartic_noiseless(X) + self.rng.random(len(X))


@dataclass(frozen=True)
class Benchmark:
    """A benchmark function with its box and optimum.

    ``xopt(d)`` gives the minimizer (``None`` when unknown) and ``fopt(d)`` the minimum.
    """

    name: str
    fn: Fn | None
    lower: float
    upper: float
    fopt: Callable[[int], float]
    xopt: Callable[[int], np.ndarray | None]
    noisy: bool = False
    multimodal: bool = False

    def bounds(self, d: int) -> tuple[np.ndarray, np.ndarray]:
        return np.full(d, float(self.lower)), np.full(d, float(self.upper))

    def shift_vector(self, d: int) -> np.ndarray:
        """The fixed shift ``o`` of the shifted version (depends on the name and ``d`` only)."""
        rng = np.random.default_rng(zlib.crc32(f"{self.name}/{d}".encode()))
        span = self.upper - self.lower
        # where the shifted optimum goes: 20-40 % of the width from the centre, random side
        centre = 0.5 * (self.lower + self.upper)
        target = centre + rng.uniform(0.2, 0.4, d) * span * rng.choice([-1.0, 1.0], d)
        x = self.xopt(d)
        return target - (x if x is not None else centre)

    def cost(self, d: int, *, shifted: bool = False, seed: int | None = None) -> Fn:
        """The vectorized cost at dimension ``d`` (``seed`` feeds a noisy function's noise)."""
        fn: Fn = Quartic(seed) if self.noisy else self.fn  # type: ignore[assignment]
        if not shifted:
            return fn
        o = self.shift_vector(d)

        def shifted_fn(X: np.ndarray) -> np.ndarray:
            return fn(X - o)

        return shifted_fn

    def optimum(self, d: int, *, shifted: bool = False) -> np.ndarray | None:
        x = self.xopt(d)
        if x is None or not shifted:
            return x
        return x + self.shift_vector(d)


def _zero(d: int) -> float:
    return 0.0


def _origin(d: int) -> np.ndarray:
    return np.zeros(d)


def _ones(d: int) -> np.ndarray:
    return np.ones(d)


def _unknown(d: int) -> None:
    return None


BENCHMARKS: dict[str, Benchmark] = {
    b.name: b
    for b in [
        Benchmark("sphere", sphere, -100, 100, _zero, _origin),
        Benchmark("rosenbrock", rosenbrock, -30, 30, _zero, _ones),
        Benchmark("michalewicz", michalewicz, 0, np.pi, lambda d: float("nan"), _unknown, multimodal=True),
        Benchmark("dixon_price", dixon_price, -10, 10, _zero, dixon_price_xopt),
        Benchmark("sum_squares", sum_squares, -10, 10, _zero, _origin),
        Benchmark("rotated_ellipsoid", rotated_ellipsoid, -65.536, 65.536, _zero, _origin),
        Benchmark("rastrigin", rastrigin, -5.12, 5.12, _zero, _origin, multimodal=True),
        Benchmark("schwefel_2_22", schwefel_2_22, -10, 10, _zero, _origin),
        Benchmark("sum_powers", sum_powers, -1, 1, _zero, _origin),
        Benchmark(
            "styblinski_tang",
            styblinski_tang,
            -5,
            5,
            lambda d: -39.16616570377142 * d,
            lambda d: np.full(d, -2.903534027771178),
            multimodal=True,
        ),
        Benchmark("step", step, -100, 100, _zero, _origin),
        Benchmark("quartic", None, -1.28, 1.28, _zero, _origin, noisy=True),
        Benchmark("griewank", griewank, -600, 600, _zero, _origin, multimodal=True),
        Benchmark("ackley", ackley, -32, 32, _zero, _origin, multimodal=True),
    ]
}


def with_box(b: Benchmark, lower: float, upper: float) -> Benchmark:
    """``b`` on another box (e.g. 000 Table 10 puts every function on ``[-100, 100]``)."""
    return Benchmark(b.name, b.fn, lower, upper, b.fopt, b.xopt, b.noisy, b.multimodal)


def get(name: str) -> Benchmark:
    try:
        return BENCHMARKS[name]
    except KeyError:
        raise ValueError(f"unknown benchmark {name!r}; known: {', '.join(sorted(BENCHMARKS))}") from None
