"""``python -m swarmplan.compare WORLD --optimizers woa,rscdwoa,ba,iba_abc,cfo,mcfo --seeds 10``.

Runs the world once per (optimizer, seed) on the sweep engine (:mod:`swarmplan.sweep`: a
LocalCluster of ``--workers`` worker processes, or the Dask scheduler at ``--scheduler``) — one
MCAP log per run in ``--out-dir``/runs, the rows in ``--out-dir``/results.csv — and prints a
table in the style of the papers: success rate, flown path length, mean curvature, arrival
time, planning time (and the best global-plan cost in ``mode: global``), each as mean ± std
over the seeds, with a Wilcoxon rank-sum verdict (scipy ``ranksums``) against the first
optimizer: ``+`` significantly better than it, ``-`` significantly worse, ``=`` no
significant difference (p >= ``--alpha``). A cell without a value reads ``n/a`` and a note
under the table says why (e.g. no plan cost in the reactive mode, which makes no global plan).

Path length, curvature and arrival time are averaged over the agents that arrived (a run
where none arrived contributes nothing to them); planning time is the wall time of the
run's optimizer calls (the global plans in ``mode: global``, escapes and smoothing otherwise).
For studies over several worlds and parameter grids use ``python -m swarmplan.sweep``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

from swarmplan.cli.common import HelpFormatter, output_dir_problem, plain, quiet_on_closed_stdout
from swarmplan.cli.sweep import WORKERS_HELP, default_workers
from swarmplan.runtime.blas import limit_blas_threads
from swarmplan.sweep.report import table, table_notes, verdict  # noqa: F401 - part of this module's API


def format_table(rows: list[dict[str, Any]], names: list[str], alpha: float = 0.05) -> str:
    """The papers' table of ``rows`` (sweep rows), one line per optimizer of ``names``."""
    return table(rows, names, alpha)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m swarmplan.compare",
        description=plain(__doc__.split("\n\n", 1)[1]),
        formatter_class=HelpFormatter,
    )
    p.add_argument("world", help="world YAML file")
    p.add_argument(
        "--optimizers", default="woa,rscdwoa,ba,iba_abc,cfo,mcfo", help="comma-separated; first = reference"
    )
    p.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per optimizer")
    p.add_argument("--out-dir", default="logs/compare", help="where the logs go ('none' for no logs)")
    p.add_argument("--workers", "--jobs", type=int, default=default_workers(), help=WORKERS_HELP)
    p.add_argument("--scheduler", default=None, help="address of a running Dask scheduler instead")
    p.add_argument("--alpha", type=float, default=0.05, help="significance level of the rank-sum test")
    return p


def _line(r: dict[str, Any]) -> str:
    if r["status"] != "ok":
        return f"{r['optimizer']:>9} seed {r['seed']:>3}: ERROR {r['error']}"
    length = r["path_length_mean"]
    return (
        f"{r['optimizer']:>9} seed {r['seed']:>3}: {'ok ' if r['success'] else 'FAIL'} "
        f"{r['arrived']}/{r['agents']} arrived, length {'-' if math.isnan(length) else f'{length:.1f}'} m, "
        f"planning {r['planning_ms']:.0f} ms, wall {r['wall_time']:.1f} s"
    )


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    limit_blas_threads()
    from swarmplan.sweep.engine import make_client, run_tasks
    from swarmplan.sweep.spec import SpecError, parse_spec

    names = [n.strip() for n in args.optimizers.split(",") if n.strip()]
    problems = []
    if args.seeds < 1:
        problems.append(f"--seeds: must be >= 1, got {args.seeds}")
    if args.workers < 1:
        problems.append(f"--workers: must be >= 1, got {args.workers}")
    if not 0 < args.alpha < 1:
        problems.append(f"--alpha: must be in (0, 1), got {args.alpha:g}")
    from swarmplan.sweep.engine import scheduler_problem

    for problem in (
        scheduler_problem(args.scheduler),
        output_dir_problem("--out-dir", args.out_dir) if args.out_dir != "none" else None,
    ):
        if problem:
            problems.append(problem)
    if not names:
        problems.append("--optimizers: give at least one")
    world = Path(args.world)
    if names:
        # A one-world study: the sweep spec validates the optimizers and the world (as it will run).
        raw = {"name": "compare", "worlds": [world.name], "optimizers": names, "seeds": max(1, args.seeds)}
        try:
            spec = parse_spec(raw, base_dir=world.parent, source="command line")
        except SpecError as exc:
            problems += [p.replace("optimizers:", "--optimizers:", 1) for p in exc.problems]
    if problems:
        for p in problems:
            print(f"error: {p}", file=sys.stderr)
        return 2
    tmp = tempfile.TemporaryDirectory(prefix="swarmplan-compare-") if args.out_dir == "none" else None
    out_dir = Path(tmp.name if tmp is not None else args.out_dir)
    try:
        client = make_client(args.workers, args.scheduler)
    except (OSError, TimeoutError) as exc:
        print(f"error: --scheduler: cannot reach {args.scheduler!r}: {exc}", file=sys.stderr)
        return 2
    try:
        rows, _ = run_tasks(
            spec.tasks(),
            out_dir,
            [],
            client,
            progress=False,
            on_row=lambda r: print(_line(r), file=sys.stderr),
        )
    finally:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None and args.scheduler is None:
            cluster.close()
        if tmp is not None:
            tmp.cleanup()
    print(f"world {args.world}, {args.seeds} seed(s) per optimizer (seeds 0..{args.seeds - 1})")
    print(format_table(rows, names, args.alpha))
    for note in table_notes(rows, names, args.alpha):
        print(f"note: {note}")
    if tmp is None:
        print(f"rows: {out_dir / 'results.csv'}, logs: {out_dir / 'runs'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
