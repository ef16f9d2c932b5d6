"""The library's own overhead per evaluation, for every registered algorithm.

Method: minimize a cheap vectorized function (the sphere, ``(n, d) -> (n,)``) at d = 50
with a fixed budget. The cost is wrapped so that the time spent *inside* the sphere is
summed with ``time.perf_counter`` around each call. Overhead per evaluation is

    (wall time of ``minimize`` - time inside the cost) / evaluations

so it counts everything the library does (the algorithm's own arithmetic, random numbers,
bound repair, the ``Problem`` bookkeeping, the wrapper's call itself) except the function.
Each algorithm is measured ``--repeats`` times and the minimum is reported (the least
disturbed by other processes on the machine); the median is printed too. The same figure
in CPU time (``time.process_time`` of the process, minus the CPU time inside the cost) is
printed beside it: on a shared machine it is the steadier one, since it does not count the
time the process waits for a core. The first run of each algorithm in a fresh process also
pays numba's one-time import and kernel load/compile; the minimum leaves it out, the
``first run`` column shows it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


class TimedCost:
    """Sphere that accumulates its own evaluation time and row count."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.cpu_seconds = 0.0
        self.rows = 0
        self.calls = 0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        c0 = time.process_time()  # inside the wall window: the CPU clock's cost counts as cost
        f = np.einsum("ij,ij->i", X, X)
        self.cpu_seconds += time.process_time() - c0
        self.seconds += time.perf_counter() - t0
        self.rows += len(X)
        self.calls += 1
        return f


def measure(name: str, *, dim: int = 50, evals: int = 30_000, repeats: int = 3, seed: int = 0) -> dict:
    """Overhead of ``name`` in µs per evaluation (min and median over ``repeats``)."""
    from swarmplan.optimizers import make

    opt = make(name)
    lo, hi = np.full(dim, -100.0), np.full(dim, 100.0)
    per_eval, cpu_per_eval, cost_us, rows_per_call = [], [], [], []
    for r in range(repeats):
        cost = TimedCost()
        c0 = time.process_time()
        t0 = time.perf_counter()
        res = opt.minimize(cost, lo, hi, max_evals=evals, seed=seed + r)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
        per_eval.append((wall - cost.seconds) / res.evaluations * 1e6)
        if r == 0:
            first_run_s = wall - cost.seconds
        cpu_per_eval.append((cpu - cost.cpu_seconds) / res.evaluations * 1e6)
        cost_us.append(cost.seconds / res.evaluations * 1e6)
        rows_per_call.append(cost.rows / max(cost.calls, 1))
    return {
        "algorithm": name,
        "overhead_us_min": float(np.min(per_eval)),
        "overhead_us_median": float(np.median(per_eval)),
        "overhead_cpu_us_min": float(np.min(cpu_per_eval)),
        "first_run_s": float(first_run_s),
        "cost_us": float(np.median(cost_us)),
        "rows_per_call": float(np.median(rows_per_call)),
        "evaluations": int(res.evaluations),
    }


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = type(
        "_Fmt", (argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter), {}
    )
    p.add_argument("--dim", type=int, default=50, help="dimension")
    p.add_argument("--evals", type=int, default=30_000, help="evaluations per run")
    p.add_argument("--repeats", type=int, default=3, help="runs per algorithm; the minimum is reported")
    p.add_argument("--algorithms", help="comma-separated registry names (default: all registered)")


def main(args: argparse.Namespace) -> int:
    from swarmplan.optimizers import available

    names = [a.strip() for a in args.algorithms.split(",")] if args.algorithms else available()
    unknown = [a for a in names if a not in available()]
    if unknown:
        print(f"unknown algorithm(s) {', '.join(unknown)}; known: {', '.join(available())}")
        return 2
    print(
        f"overhead per evaluation = (minimize wall time - time inside the cost) / evaluations; "
        f"cost = vectorized sphere, d={args.dim}, {args.evals} evaluations, default parameters, "
        f"min (median) over {args.repeats} runs"
    )
    print(
        "\n| algorithm | overhead µs/eval (min) | median | CPU µs/eval (min) | first run overhead s "
        "| sphere µs/eval | rows per cost call |"
    )
    print("|---|---|---|---|---|---|---|")
    for name in names:
        m = measure(name, dim=args.dim, evals=args.evals, repeats=args.repeats)
        print(
            f"| {name} | {m['overhead_us_min']:.2f} | {m['overhead_us_median']:.2f} | "
            f"{m['overhead_cpu_us_min']:.2f} | {m['first_run_s']:.2f} | "
            f"{m['cost_us']:.3f} | {m['rows_per_call']:.1f} |",
            flush=True,
        )
    return 0
