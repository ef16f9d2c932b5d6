"""``python -m swarmplan.compare WORLD --optimizers woa,rscdwoa,ba,iba_abc,cfo,mcfo --seeds 10``.

Runs the world once per (optimizer, seed) — one MCAP log per run in ``--out-dir``, over
``--jobs`` processes — and prints a table in the style of the papers: success rate, flown
path length, mean curvature, arrival time, planning time and the best planning cost, each
as mean ± std over the seeds, with a Wilcoxon rank-sum verdict (scipy ``ranksums``)
against the first optimizer: ``+`` significantly better than it, ``-`` significantly worse,
``=`` no significant difference (p >= ``--alpha``), on path length and on planning cost.

Path length, curvature and arrival time are averaged over the agents that arrived (a run
where none arrived contributes nothing to them); planning time is the wall time of the
run's optimizer calls (the global plans in ``mode: global``, escapes and smoothing otherwise).
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.world import WorldError, load_world


class _Collect:
    """Recorder proxy that keeps the ``/optimizer`` messages and forwards everything."""

    def __init__(self, inner: Any | None):
        self.inner = inner
        self.optimizer: list[dict[str, Any]] = []

    def write_optimizer(self, msg: dict[str, Any]) -> None:
        self.optimizer.append(msg)
        if self.inner is not None:
            self.inner.write_optimizer(msg)

    def __getattr__(self, name: str) -> Any:
        if self.inner is None:
            return lambda *a, **k: None
        return getattr(self.inner, name)


def run_one(world_path: str, optimizer: str, seed: int, out_dir: str | None) -> dict[str, Any]:
    """One run of ``world_path`` with ``optimizer`` and ``seed``; the row the table needs."""
    from swarmplan import optimizers
    from swarmplan.planner import make_planner
    from swarmplan.recording import McapRecorder
    from swarmplan.run import apply_overrides
    from swarmplan.sim import Simulation

    world = apply_overrides(load_world(world_path, optimizers.available()), optimizer, None)
    log = None
    inner = None
    if out_dir is not None:
        log = Path(out_dir) / f"{world.name}-{optimizer}-{seed}.mcap"
        log.parent.mkdir(parents=True, exist_ok=True)
        inner = McapRecorder(
            log,
            flush_interval=world.resolved["log"]["flush_interval"],
            foxglove=world.resolved["log"]["foxglove"],
        )
    rec = _Collect(inner)
    sim = Simulation(world, planner=make_planner(world, optimizer), recorder=rec)
    try:
        sim.reset(seed=seed)
        while True:
            r = sim.step()
            if r.terminated or r.truncated:
                break
        summary = sim.summary()
        if inner is not None:
            inner.write_summary(summary)
    finally:
        if inner is not None:
            inner.close()
    arrived = [a for a in summary["agents"] if a["arrived"]]
    global_runs = [m for m in rec.optimizer if m["purpose"] == "global"]
    mean = lambda xs: float(np.mean(xs)) if xs else math.nan  # noqa: E731
    return {
        "optimizer": optimizer,
        "seed": seed,
        "success": bool(summary["success"]),
        "arrived": summary["arrived"],
        "agents": summary["agents_total"],
        "collisions": summary["collisions"],
        "length": mean([a["path_length"] for a in arrived]),
        "curvature": mean([a["mean_curvature"] for a in arrived]),
        "arrival": mean([a["arrival_time"] for a in arrived]),
        "planning_ms": float(sum(m["wall_ms"] for m in rec.optimizer)),
        "cost": mean([m["best_cost"] for m in global_runs]),
        "wall_s": summary["wall_time"],
        "log": None if log is None else str(log),
    }


def _ms(xs: list[float], fmt: str = "{:.1f}") -> str:
    xs = [x for x in xs if math.isfinite(x)]
    if not xs:
        return "-"
    return f"{fmt.format(np.mean(xs))} ± {fmt.format(np.std(xs))}"


def verdict(base: list[float], other: list[float], alpha: float) -> str:
    """'+' (other significantly lower = better), '-' (higher), '=' by the Wilcoxon rank-sum test."""
    from scipy.stats import ranksums

    a = [x for x in base if math.isfinite(x)]
    b = [x for x in other if math.isfinite(x)]
    if len(a) < 2 or len(b) < 2:
        return "n/a"
    p = float(ranksums(b, a).pvalue)
    if p >= alpha or np.median(a) == np.median(b):
        return f"= (p={p:.2g})"
    return f"{'+' if np.median(b) < np.median(a) else '-'} (p={p:.2g})"


def format_table(rows: list[dict[str, Any]], names: list[str], alpha: float = 0.05) -> str:
    by = {n: [r for r in rows if r["optimizer"] == n] for n in names}
    head = ("optimizer", "success", "length m", "curvature 1/m", "arrival s", "planning ms", "plan cost",
            f"length vs {names[0]}", f"cost vs {names[0]}")  # fmt: skip
    out_rows = []
    for n in names:
        rs = by[n]
        ref = by[names[0]]

        def col(k: str, rs: list = rs) -> list:
            return [r[k] for r in rs]

        ok = sum(r["success"] for r in rs)
        out_rows.append(
            (
                n,
                f"{ok}/{len(rs)}",
                _ms(col("length")),
                _ms(col("curvature"), "{:.4f}"),
                _ms(col("arrival")),
                _ms(col("planning_ms"), "{:.0f}"),
                _ms(col("cost"), "{:.4g}"),
                "(reference)" if n == names[0] else verdict(col("length", ref), col("length"), alpha),
                "(reference)" if n == names[0] else verdict(col("cost", ref), col("cost"), alpha),
            )
        )
    widths = [max(len(h), *(len(r[k]) for r in out_rows)) for k, h in enumerate(head)]
    line = lambda cells: "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)) + " |"  # noqa: E731
    return "\n".join([line(head), line(["-" * w for w in widths])] + [line(r) for r in out_rows])


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m swarmplan.compare", description=__doc__.split("\n\n")[1])
    p.add_argument("world", help="world YAML file")
    p.add_argument(
        "--optimizers", default="woa,rscdwoa,ba,iba_abc,cfo,mcfo", help="comma-separated; first = reference"
    )
    p.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per optimizer")
    p.add_argument("--out-dir", default="logs/compare", help="where the logs go ('none' for no logs)")
    p.add_argument("--jobs", type=int, default=2, help="parallel processes")
    p.add_argument("--alpha", type=float, default=0.05, help="significance level of the rank-sum test")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from swarmplan import optimizers

    names = [n.strip() for n in args.optimizers.split(",") if n.strip()]
    unknown = [n for n in names if n not in optimizers.available()]
    problems = [
        f"--optimizers: unknown optimizer '{n}'; known: {', '.join(optimizers.available())}" for n in unknown
    ]
    if args.seeds < 1:
        problems.append(f"--seeds: must be >= 1, got {args.seeds}")
    if not names:
        problems.append("--optimizers: give at least one")
    try:
        from swarmplan.run import check_planner_settings

        check_planner_settings(load_world(args.world, optimizers.available()), str(args.world))
    except WorldError as exc:
        problems += [f"{exc.source}: {p}" for p in exc.problems]
    if problems:
        for p in problems:
            print(f"error: {p}", file=sys.stderr)
        return 2
    out_dir = None if args.out_dir == "none" else args.out_dir
    jobs = [(args.world, n, s, out_dir) for n in names for s in range(args.seeds)]
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = [pool.submit(run_one, *j) for j in jobs]
        for f in futures:
            r = f.result()
            rows.append(r)
            print(
                f"{r['optimizer']:>9} seed {r['seed']:>3}: {'ok ' if r['success'] else 'FAIL'} "
                f"{r['arrived']}/{r['agents']} arrived, length {r['length']:.1f} m, "
                f"planning {r['planning_ms']:.0f} ms, wall {r['wall_s']:.1f} s",
                file=sys.stderr,
            )
    print(f"world {args.world}, {args.seeds} seed(s) per optimizer (seeds 0..{args.seeds - 1})")
    print(format_table(rows, names, args.alpha))
    return 0


if __name__ == "__main__":
    sys.exit(main())
