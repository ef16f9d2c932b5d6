"""Run a paper's benchmark suite over the registered optimizers and compare with the paper.

Suites (papers: 000 Zhou et al., IBA; 001 Zhang et al., RSCDWOA; 003 Huang & Ma, IBA
with Gaussian distribution; see docs/benchmarks.md):

* ``iba-table10``: 000 (Zhou et al., IBA = BA + ABC) Table 10: ten functions (eqs 16-19 and
  Table 9), d = 50, every box [-100, 100], 3e5 evaluations, 20 runs in the paper.
* ``rscdwoa-table4``: 001 (Zhang et al., RSCDWOA) Table 4: nine functions, d = 30, 100
  iterations (population 30 assumed, so 3000 evaluations); 001 prints no boxes, we use the
  standard ones of the WOA paper (Mirjalili & Lewis 2016). 001 prints no numeric results, so
  the table has no paper column.
* ``cec2013``: 003 (Huang & Ma, IBA-Gauss) Table 4: CEC2013 F1-F28 via ``opfunu``, d = 30,
  population 100 x 3000 iterations = 3e5 evaluations, 51 runs; values are errors f - f*.
  ``ba`` runs with 003's Table 3 settings here (population 100, f in [0, 5], alpha 0.99...).
* ``shifted``: sphere, Rastrigin, Ackley, d = 10, their usual boxes (+-100, +-5.12, +-32) with
  the optimum moved off centre, 3000 evaluations, population 30 for every algorithm. With ``--peers`` the
  same-named algorithms of mealpy and niapy run beside ours (optional extra ``[peers]``).

Every paper suite also runs a *shifted* variant (optimum moved away from the origin and box
centre, see swarmplan.bench.functions); CEC2013 functions are shifted by definition.

For each algorithm x function it prints mean, median, std, best over the runs, the paper's
mean where it reports one, evaluations used, wall time per run, and for each improved
algorithm a Wilcoxon rank-sum verdict against its base: + better (p < 0.05), - worse,
~ no significant difference. The 003 pair iba_gauss vs ba compares with ``ba`` at 003's
settings (``ba@003``), the others with the base's registry defaults.
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing as mp
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from swarmplan.bench.suites import (  # noqa: F401 - BA_003 and SUITES are part of this module's API
    BA_003,
    PAIRS,
    PARAM_SETS,
    SUITE_ALIASES,
    SUITES,
    Suite,
    problem,
    resolve,
)


def _run_one(job: tuple) -> dict:
    suite_name, fn_name, algorithm, shifted, seed, evals = job
    from swarmplan.optimizers import make

    suite = SUITES[suite_name]
    cost, lo, hi, offset = problem(suite, fn_name, shifted=shifted, seed=seed + 7919)
    t0 = time.perf_counter()
    if algorithm.startswith("peer:"):
        from swarmplan.bench.peers import run_peer

        out = run_peer(
            algorithm[5:],
            cost,
            lo,
            hi,
            max_evals=evals,
            seed=seed,
            population=int(suite.common.get("population", 30)),
        )
        value, n_evals = out["value"], out["evaluations"]
    else:
        name, params = resolve(suite, algorithm)
        res = make(name, **params).minimize(cost, lo, hi, max_evals=evals, seed=seed)
        value, n_evals = res.f, res.evaluations
    wall = time.perf_counter() - t0
    return {
        "variant": "shifted" if shifted else "plain",
        "function": fn_name,
        "algorithm": algorithm,
        "seed": seed,
        "value": value - offset if suite.error else value,
        "evaluations": n_evals,
        "wall": wall,
    }


def verdict(improved: np.ndarray, base: np.ndarray, alpha: float = 0.05) -> tuple[str, float]:
    """Wilcoxon rank-sum of ``improved`` vs ``base`` (minimization): ``+``, ``~`` or ``-`` and p."""
    from scipy.stats import ranksums

    a = np.nan_to_num(np.asarray(improved, float), nan=np.inf, posinf=np.finfo(float).max)
    b = np.nan_to_num(np.asarray(base, float), nan=np.inf, posinf=np.finfo(float).max)
    if np.array_equal(np.sort(a), np.sort(b)):
        return "~", 1.0
    stat, p = ranksums(a, b)
    if not np.isfinite(p) or p >= alpha:
        return "~", float(p) if np.isfinite(p) else 1.0
    return ("+" if stat < 0 else "-"), float(p)


def summarize(suite: Suite, records: list[dict]) -> list[dict]:
    """One row per variant x function x algorithm, with the paper value and the verdict vs base."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for r in records:
        groups.setdefault((r["variant"], r["function"], r["algorithm"]), []).append(r)
    rows = []
    for (variant, fn, alg), rs in groups.items():
        rs.sort(key=lambda r: r["seed"])
        v = np.array([r["value"] for r in rs])
        paper_mean, paper_std = suite.paper.get(alg, {}).get(fn, (float("nan"), float("nan")))
        row = {
            "suite": suite.name,
            "variant": variant,
            "function": fn,
            "algorithm": alg,
            "runs": len(v),
            "mean": float(np.mean(v)),
            "std": float(np.std(v, ddof=1)) if len(v) > 1 else float("nan"),
            "best": float(np.min(v)),
            "median": float(np.median(v)),
            "paper_mean": paper_mean if variant == "plain" or suite.name == "cec2013" else float("nan"),
            "paper_std": paper_std if variant == "plain" or suite.name == "cec2013" else float("nan"),
            "evaluations": float(np.mean([r["evaluations"] for r in rs])),
            "wall_s": float(np.mean([r["wall"] for r in rs])),
            "base": "",
            "verdict": "",
            "p_value": float("nan"),
            "values": v.tolist(),  # per seed, in seed order (not written to the CSV)
        }
        if alg.startswith("peer:"):
            ours = next((k for k, v in _peer_table().items() if any(lab == alg[5:] for lab, _, _ in v)), "")
            if (variant, fn, ours) in groups:
                vo = np.array(
                    [r["value"] for r in sorted(groups[(variant, fn, ours)], key=lambda r: r["seed"])]
                )
                row["base"] = ours
                # orientation: "+" means ours is better than this peer
                row["verdict"], row["p_value"] = verdict(vo, v)
            rows.append(row)
            continue
        base = PAIRS.get(alg)
        base = {v: k for k, v in SUITE_ALIASES.get(suite.name, {}).items()}.get(base, base)
        if base and (variant, fn, base) in groups:
            vb = np.array([r["value"] for r in sorted(groups[(variant, fn, base)], key=lambda r: r["seed"])])
            row["base"] = base
            row["verdict"], row["p_value"] = verdict(v, vb)
        rows.append(row)
    order = {f: i for i, f in enumerate(suite.functions)}
    rows.sort(key=lambda r: (r["variant"] != "plain", order.get(r["function"], 0), r["algorithm"]))
    return rows


def _peer_table() -> dict[str, list[tuple[str, str, str]]]:
    from swarmplan.bench.peers import PEERS

    return PEERS


def _fmt(x: float) -> str:
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return ""
    if x == 0:
        return "0"
    if abs(x) >= 1e5 or abs(x) < 1e-3:
        return f"{x:.3e}"
    return f"{x:.4g}"


def format_tables(suite: Suite, rows: list[dict]) -> str:
    """Markdown tables, one per variant x function."""
    out = []
    key = None
    has_paper = bool(suite.paper)  # a paper without numbers gets no (empty) paper column
    for r in rows:
        if r["algorithm"].startswith("peer:"):
            continue
        if (r["variant"], r["function"]) != key:
            key = (r["variant"], r["function"])
            out.append(f"\n#### {r['function']} ({r['variant']})\n")
            paper = " paper mean |" if has_paper else ""
            out.append(f"| algorithm | mean | median | std | best |{paper} evals | wall s/run | vs base |")
            out.append("|---|---|---|---|---|" + ("---|" if has_paper else "") + "---|---|---|")
        vs = f"{r['verdict']} vs {r['base']} (p={r['p_value']:.2g})" if r["base"] else ""
        paper = f" {_fmt(r['paper_mean'])} |" if has_paper else ""
        out.append(
            f"| {r['algorithm']} | {_fmt(r['mean'])} | {_fmt(r['median'])} | {_fmt(r['std'])} | "
            f"{_fmt(r['best'])} |{paper} {r['evaluations']:.0f} | {r['wall_s']:.2f} | {vs} |"
        )
    return "\n".join(out)


def format_peers(rows: list[dict]) -> str:
    """Per function: our algorithm's median beside each same-named peer's, with the verdict."""
    ours = {
        (r["variant"], r["function"], r["algorithm"]): r
        for r in rows
        if not r["algorithm"].startswith("peer:")
    }
    lines = []
    for r in rows:
        if not r["algorithm"].startswith("peer:") or not r["base"]:
            continue
        o = ours[(r["variant"], r["function"], r["base"])]
        lines.append(
            f"| {r['function']} | {r['base']} | {_fmt(o['median'])} | {r['algorithm'][5:]} | "
            f"{_fmt(r['median'])} | {r['verdict']} (p={r['p_value']:.2g}) |"
        )
    if not lines:
        return ""
    head = [
        "| function | ours | median | peer | median | ours vs peer |",
        "|---|---|---|---|---|---|",
    ]
    return "\n".join(head + lines)


def format_best(rows: list[dict]) -> str:
    """Per function: our best algorithm (lowest median) against the best peer of any name.

    ``+``: ours significantly better (rank-sum, p < 0.05), ``~`` level, ``-`` the peer better.
    """
    by_fn: dict[tuple[str, str], dict[str, dict]] = {}
    for r in rows:
        by_fn.setdefault((r["variant"], r["function"]), {})[r["algorithm"]] = r
    lines = []
    for (_, fn), algs in by_fn.items():
        ours = [r for a, r in algs.items() if not a.startswith("peer:")]
        peers = [r for a, r in algs.items() if a.startswith("peer:")]
        if not ours or not peers:
            continue
        o = min(ours, key=lambda r: r["median"])
        q = min(peers, key=lambda r: r["median"])
        sign, p = verdict(np.asarray(o["values"]), np.asarray(q["values"]))
        lines.append(
            f"| {fn} | {o['algorithm']} | {_fmt(o['median'])} | {q['algorithm'][5:]} | {_fmt(q['median'])} | "
            f"{sign} (p={p:.2g}) |"
        )
    if not lines:
        return ""
    head = [
        "| function | our best | median | best peer | median | ours vs peer |",
        "|---|---|---|---|---|---|",
    ]
    return "\n".join(head + lines)


def format_vs_random(rows: list[dict], reference: str = "random") -> str:
    """Every algorithm of ours against random search: medians, rank-sum sign and p per function
    (``+`` better than random search, ``-`` worse, ``~`` level; p < 0.05, two-sided)."""
    ref = {(r["variant"], r["function"]): r for r in rows if r["algorithm"] == reference}
    if not ref:
        return ""
    fns = list(dict.fromkeys((r["variant"], r["function"]) for r in rows))
    algs = sorted({r["algorithm"] for r in rows if not r["algorithm"].startswith("peer:")} - {reference})
    cell = {(r["variant"], r["function"], r["algorithm"]): r for r in rows}
    head = "| algorithm | " + " | ".join(f"{fn} median (vs {reference})" for _, fn in fns) + " |"
    lines = [head, "|---|" + "---|" * len(fns), "| " + reference + " | " + " | ".join(
        _fmt(ref[k]["median"]) for k in fns) + " |"]  # fmt: skip
    for a in algs:
        cells = []
        for v, fn in fns:
            r = cell.get((v, fn, a))
            if r is None or (v, fn) not in ref:
                cells.append("")
                continue
            sign, p = verdict(np.asarray(r["values"]), np.asarray(ref[(v, fn)]["values"]))
            cells.append(f"{_fmt(r['median'])} {sign} (p={p:.2g})")
        lines.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_verdicts(rows: list[dict]) -> str:
    """Summary: per improved algorithm and variant, counts of + / ~ / - against its base."""
    counts: dict[tuple[str, str, str], list[int]] = {}
    for r in rows:
        if r["base"] and not r["algorithm"].startswith("peer:"):
            c = counts.setdefault((r["algorithm"], r["base"], r["variant"]), [0, 0, 0])
            c["+~-".index(r["verdict"])] += 1
    if not counts:
        return ""
    lines = ["| improved | base | variant | + | ~ | - |", "|---|---|---|---|---|---|"]
    for (a, b, v), (p, t, m) in sorted(counts.items()):
        lines.append(f"| {a} | {b} | {v} | {p} | {t} | {m} |")
    return "\n".join(lines)


def write_csv(path: str, rows: list[dict]) -> None:
    fields = [k for k in rows[0] if k != "values"]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def run_suite(
    suite: Suite,
    algorithms: list[str],
    *,
    runs: int,
    evals: int,
    variants: list[bool],
    functions: list[str] | None = None,
    jobs: int = 2,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict]:
    """Run every (variant, function, algorithm, run) and return the raw records."""
    fns = functions or suite.functions
    todo = [
        (suite.name, fn, alg, shifted, seed + r, evals)
        for shifted in variants
        for fn in fns
        for alg in algorithms
        for r in range(runs)
    ]
    records = []
    if jobs <= 1:
        for i, job in enumerate(todo):
            records.append(_run_one(job))
            if progress:
                progress(i + 1, len(todo))
    else:
        with mp.get_context("spawn" if sys.platform == "darwin" else "fork").Pool(jobs) as pool:
            for i, rec in enumerate(pool.imap_unordered(_run_one, todo, chunksize=1)):
                records.append(rec)
                if progress:
                    progress(i + 1, len(todo))
    return records


# ------------------------------------------------------------------------------------------------
class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    pass


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = _HelpFormatter
    p.add_argument("--suite", required=True, choices=sorted(SUITES), help="the benchmark suite (see above)")
    p.add_argument("--runs", type=int, default=10, help="independent runs per algorithm x function")
    p.add_argument(
        "--out",
        default="logs/bench-{suite}.csv",
        help="write the summary rows to this CSV file ({suite} is filled in; its folder is created)",
    )
    p.add_argument("--algorithms", help="comma-separated registry names (default: all registered)")
    p.add_argument("--functions", help="comma-separated subset of the suite's functions")
    p.add_argument("--evals", type=int, help="evaluation budget per run (default: the paper's)")
    p.add_argument(
        "--shifted",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="only the shifted variant (--shifted) or only the plain one (--no-shifted); default both",
    )
    p.add_argument(
        "--peers",
        action="store_true",
        help="also run the same-named algorithms of mealpy and niapy (pip install 'swarmplan[peers]')",
    )
    p.add_argument("--jobs", type=int, default=2, help="worker processes")
    p.add_argument("--seed", type=int, default=0, help="seed of run 0; run r uses seed + r")
    p.add_argument("--raw", help="also write every single run to this CSV file")


def main(args: argparse.Namespace) -> int:
    from swarmplan.optimizers import available
    from swarmplan.runtime.paths import output_file_problem

    suite = SUITES[args.suite]
    # numbers and outputs are checked before the benchmark runs (its results would be lost)
    problems = [
        f"--{k}: must be >= 1, got {getattr(args, k)}" for k in ("runs", "jobs") if getattr(args, k) < 1
    ]
    if args.evals is not None and args.evals < 1:
        problems.append(f"--evals: must be >= 1, got {args.evals}")
    if args.seed < 0:
        problems.append(f"--seed: must be >= 0, got {args.seed}")
    if args.out:
        problems.append(output_file_problem("--out", args.out.replace("{suite}", suite.name)))
    if args.raw:
        problems.append(output_file_problem("--raw", args.raw))
    problems = [p for p in problems if p]
    if problems:
        print(f"error: {problems[0]}", file=sys.stderr)
        return 2
    if suite.name == "cec2013":
        try:
            import opfunu  # noqa: F401
        except ImportError:
            print("the cec2013 suite needs opfunu: pip install opfunu", file=sys.stderr)
            return 2
    known = available() + sorted(PARAM_SETS)
    if args.peers:
        from swarmplan.bench.peers import check_installed

        hint = check_installed()
        if hint:
            print(hint, file=sys.stderr)
            return 2
    if args.algorithms:
        algorithms = [a.strip() for a in args.algorithms.split(",") if a.strip()]
        unknown = [a for a in algorithms if a not in known]
        if unknown:
            print(f"unknown algorithm(s) {', '.join(unknown)}; known: {', '.join(known)}", file=sys.stderr)
            return 2
    elif suite.default_algorithms is not None:
        algorithms = [a for a in suite.default_algorithms if a in known]
    else:
        algorithms = available()
    # each improved algorithm is judged against its base at the pair's settings
    for a in list(algorithms):
        base = PAIRS.get(a, "")
        base = {v: k for k, v in SUITE_ALIASES.get(suite.name, {}).items()}.get(base, base)
        if base and base not in algorithms:
            algorithms.append(base)
    if args.peers:
        from swarmplan.bench.peers import PEERS

        algorithms += [f"peer:{lab}" for a in list(algorithms) for lab, _, _ in PEERS.get(a, [])]
    functions = None
    if args.functions:
        functions = [f.strip() for f in args.functions.split(",") if f.strip()]
        bad = [f for f in functions if f not in suite.functions]
        if bad:
            msg = f"unknown function(s) {', '.join(bad)}; suite has: {', '.join(suite.functions)}"
            print(msg, file=sys.stderr)
            return 2
    if suite.only_shifted:
        variants = [True]
    elif args.shifted is None:
        variants = [False, True] if suite.shiftable else [False]
    elif not suite.shiftable:
        variants = [False]
    else:
        variants = [bool(args.shifted)]
    evals = args.evals or suite.evals
    print(f"suite {suite.name}: {suite.note}")
    print(
        f"d={suite.dim}, evals/run={evals}{'' if evals == suite.evals else f' (paper: {suite.evals})'}, "
        f"runs={args.runs} (paper: {suite.runs}), seeds {args.seed}..{args.seed + args.runs - 1}, "
        f"algorithms: {', '.join(algorithms)}, variants: "
        f"{', '.join('shifted' if v else 'plain' for v in variants)}, jobs={args.jobs}"
    )
    t0 = time.perf_counter()
    last = [0.0]

    def progress(i: int, n: int) -> None:
        now = time.perf_counter()
        if now - last[0] > 10 or i == n:
            last[0] = now
            print(f"  {i}/{n} runs done, {now - t0:.0f} s", file=sys.stderr, flush=True)

    records = run_suite(
        suite,
        algorithms,
        runs=args.runs,
        evals=evals,
        variants=variants,
        functions=functions,
        jobs=args.jobs,
        seed=args.seed,
        progress=progress,
    )
    rows = summarize(suite, records)
    print(format_tables(suite, rows))
    summary = format_verdicts(rows)
    if summary:
        print("\nWilcoxon rank-sum (p < 0.05), improved algorithm vs its base, counts over functions:\n")
        print(summary)
    peers = format_peers(rows)
    if peers:
        print(
            "\nOurs vs same-named peers at equal budget and seeds "
            "(Wilcoxon rank-sum, p < 0.05; + ours better):\n"
        )
        print(peers)
        print("\nOur best (lowest median) vs the best peer of any name (+ ours better):\n")
        print(format_best(rows))
    vs_random = format_vs_random(rows)
    if vs_random:
        print("\nAgainst random search (Wilcoxon rank-sum, two-sided, p < 0.05; + better than random):\n")
        print(vs_random)
    print(f"\ntotal wall time {time.perf_counter() - t0:.0f} s")
    if args.out:
        out = Path(args.out.replace("{suite}", suite.name))
        out.parent.mkdir(parents=True, exist_ok=True)
        write_csv(str(out), rows)
        print(f"wrote {out}")
    if args.raw:
        keys = ("variant", "function", "algorithm", "seed")
        Path(args.raw).parent.mkdir(parents=True, exist_ok=True)
        write_csv(args.raw, sorted(records, key=lambda r: tuple(r[k] for k in keys)))
    return 0
