"""``python -m swarmplan.sweep SPEC.yaml [--workers N] [--scheduler ADDRESS] [--out DIR] [--resume]``.

Runs every (world, optimizer, seed, override combination) of a spec on dask.distributed — a
LocalCluster of ``--workers`` processes by default, or the cluster whose scheduler is at
``--scheduler`` — and writes ``results.csv`` (one row per run), ``runs/`` (one MCAP log per
run) and ``report.md`` (tables, Wilcoxon verdicts, box plots) in ``--out``.

Exit status: 0 when every run finished (whatever its success), 1 when some run raised (its
row says ``error``) or the sweep was interrupted, 2 on a bad spec (nothing is run).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from swarmplan.sweep.spec import SpecError, load_spec

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m swarmplan.sweep",
        description="Run a Monte-Carlo study (worlds x optimizers x seeds x overrides) on dask.distributed.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("spec", help="sweep spec YAML (see docs/sweeps.md)")
    p.add_argument(
        "--workers", type=int, default=os.cpu_count() or 1, help="worker processes of the local cluster"
    )
    p.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler (e.g. tcp://head:8786)"
    )
    p.add_argument("--out", default=None, help="output folder (default: logs/sweeps/{name})")
    p.add_argument("--resume", action="store_true", help="skip the runs whose log is complete")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    problems = []
    if args.workers < 1:
        problems.append(f"--workers: must be >= 1, got {args.workers}")
    try:
        spec = load_spec(args.spec)
    except SpecError as exc:
        problems += [f"{exc.source}: {p}" for p in exc.problems]
    if problems:
        for p in problems:
            print(f"error: {p}", file=sys.stderr)
        return EXIT_BAD_INPUT

    from swarmplan.sweep.engine import dashboard_line, make_client, run_tasks
    from swarmplan.sweep.report import write_report

    out_dir = Path(args.out if args.out is not None else f"logs/sweeps/{spec.name}")
    tasks = spec.tasks()
    combos = len(tasks) // max(1, len(spec.worlds) * len(spec.optimizers) * len(spec.seeds))
    print(
        f"sweep {spec.name}: {len(spec.worlds)} world(s) x {len(spec.optimizers)} optimizer(s) x "
        f"{len(spec.seeds)} seed(s) x {combos} override combination(s) = {len(tasks)} runs -> {out_dir}",
        file=sys.stderr,
    )
    start = time.perf_counter()
    try:
        client = make_client(args.workers, args.scheduler)
    except (OSError, TimeoutError) as exc:
        print(f"error: --scheduler: cannot reach {args.scheduler!r}: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    interrupted = False
    try:
        n_workers = len(client.scheduler_info()["workers"])
        print(f"scheduler: {client.scheduler.address}, {n_workers} worker(s)", file=sys.stderr)
        print(dashboard_line(client), file=sys.stderr)
        rows, skipped = run_tasks(
            tasks, out_dir, spec.override_keys, client, resume=args.resume, progress=not args.no_progress
        )
    except KeyboardInterrupt:
        interrupted = True
    finally:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None and args.scheduler is None:
            cluster.close()
    wall = time.perf_counter() - start
    if interrupted:
        print(
            f"\ninterrupted after {wall:.1f} s: every finished row is in {out_dir / 'results.csv'}; "
            "run again with --resume to finish",
            file=sys.stderr,
        )
        return EXIT_FAILED
    ran = len(rows) - skipped
    errors = sum(r["status"] != "ok" for r in rows)
    notes = [
        f"{len(rows)} runs ({skipped} kept from an earlier sweep, {ran} run now), {errors} error(s); "
        f"{wall:.1f} s wall on {n_workers} worker(s). Rows: `results.csv`; logs: `runs/`."
    ]
    report = write_report(
        out_dir, spec.name, rows, list(spec.optimizers), spec.override_keys, spec.alpha, notes
    )
    print(f"{notes[0]}\nreport: {report}", file=sys.stderr)
    return EXIT_FAILED if errors else EXIT_OK
