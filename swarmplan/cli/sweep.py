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
import signal
import sys
import time
from pathlib import Path

from swarmplan.cli.common import HelpFormatter, output_dir_problem, quiet_on_closed_stdout
from swarmplan.sweep.spec import SpecError, load_spec

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def default_workers() -> int:
    """Worker processes of a local cluster unless told otherwise: one per core."""
    return os.cpu_count() or 1


WORKERS_HELP = f"worker processes of the local cluster (default: one per core, {default_workers()} here)"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m swarmplan.sweep",
        description="Run a Monte-Carlo study (worlds x optimizers x seeds x overrides) on dask.distributed.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("spec", help="sweep spec YAML (see docs/sweeps.md)")
    p.add_argument("--workers", type=int, default=default_workers(), help=WORKERS_HELP)
    p.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler (e.g. tcp://head:8786)"
    )
    p.add_argument("--out", default=None, help="output folder (default: logs/sweeps/{name})")
    p.add_argument("--resume", action="store_true", help="skip the runs whose log is complete")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    problems = []
    if args.workers < 1:
        problems.append(f"--workers: must be >= 1, got {args.workers}")
    from swarmplan.sweep.engine import scheduler_problem

    for problem in (scheduler_problem(args.scheduler), args.out and output_dir_problem("--out", args.out)):
        if problem:
            problems.append(problem)
    try:
        spec = load_spec(args.spec)
    except SpecError as exc:
        problems += [f"{exc.source}: {p}" for p in exc.problems]
    if not problems and args.out is None:
        problem = output_dir_problem("--out", f"logs/sweeps/{spec.name}")
        if problem:
            problems.append(problem.replace("--out", "output folder", 1))
    if problems:
        for p in problems:
            print(f"error: {p}", file=sys.stderr)
        return EXIT_BAD_INPUT

    from swarmplan.sweep.engine import complete_results, dashboard_line, make_client, run_tasks
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
    started_at = time.time()
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
        # a second Ctrl-C must not cut the shutdown short (workers would be left behind)
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None and args.scheduler is None:
                cluster.close()
        finally:
            signal.signal(signal.SIGINT, previous)
    wall = time.perf_counter() - start
    if interrupted:
        complete_results(out_dir, tasks, spec.override_keys, started_at)
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
