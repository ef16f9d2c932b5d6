"""Run a sweep's tasks on ``dask.distributed`` and collect one row per run.

The client side plans the tasks, skips the finished ones on ``--resume``, submits the rest
and appends each row to ``results.csv`` as it arrives (an interrupted sweep keeps every
finished row and log). Each task runs in a worker process and writes its own MCAP log; the
row is computed from the run's summary and its ``/optimizer`` messages, so a finished log
alone is enough to rebuild its row.

A worker that dies takes its running task with it; the scheduler gives the task to another
worker (Dask counts the deaths, ``distributed.scheduler.allowed-failures``) and the new
attempt overwrites nothing it should not: a log only gets its final name once the run is over.
"""

from __future__ import annotations

import csv
import math
import os
import signal
import sys
import threading
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.runtime.blas import limit_blas_threads
from swarmplan.sweep.adapter import build_world, read_log, run_world
from swarmplan.sweep.spec import Task

#: results.csv columns; the override keys go after ``seed``.
HEAD = ["world", "optimizer", "seed"]
METRICS = [
    "status",
    "success",
    "agents",
    "arrived",
    "collisions",
    "sim_time",
    "wall_time",
    "escapes",
    "escape_ms_median",
    "path_length_mean",
    "path_ratio_mean",
    "curvature_mean",
    "arrival_time_mean",
    "planning_ms",
    "plan_cost",
    "optimizer_runs",
    "log",
    "error",
]
#: Columns that measure the machine, not the run: they differ between two runs of the same task.
TIMING = ("wall_time", "escape_ms_median", "planning_ms")


def columns(override_keys: Iterable[str]) -> list[str]:
    return [*HEAD, *override_keys, *METRICS]


def _mean(xs: list[float]) -> float:
    xs = [float(x) for x in xs if x is not None]
    return float(np.mean(xs)) if xs else math.nan


def metrics_row(summary: dict[str, Any], optimizer_runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The metric columns of a finished run, from its ``/summary`` and ``/optimizer`` messages.

    Length, ratio, curvature and arrival time are means over the agents that arrived (NaN when
    none did); ``escape_ms_median`` is over every escape of every agent; ``planning_ms`` is the
    wall time of all the run's optimizer calls; ``plan_cost`` the mean best cost of its global
    plans (NaN in the reactive mode, which makes none); ``optimizer_runs`` how many optimizer
    calls it made (escapes, smoothing, global plans: 0 when it flew pure APF throughout).
    """
    agents = summary["agents"]
    arrived = [a for a in agents if a["arrived"]]
    escape_ms = [x for a in agents for x in a.get("escape_planning_ms", [])]
    global_runs = [m for m in optimizer_runs if m.get("purpose") == "global"]
    return {
        "status": "ok",
        "success": bool(summary["success"]),
        "agents": int(summary["agents_total"]),
        "arrived": int(summary["arrived"]),
        "collisions": int(summary["collisions"]),
        "sim_time": float(summary["sim_time"]),
        "wall_time": float(summary["wall_time"]),
        "escapes": int(sum(a["escapes"] for a in agents)),
        "escape_ms_median": float(np.median(escape_ms)) if escape_ms else math.nan,
        "path_length_mean": _mean([a["path_length"] for a in arrived]),
        "path_ratio_mean": _mean([a["length_ratio"] for a in arrived]),
        "curvature_mean": _mean([a["mean_curvature"] for a in arrived]),
        "arrival_time_mean": _mean([a["arrival_time"] for a in arrived]),
        "planning_ms": float(sum(m["wall_ms"] for m in optimizer_runs)),
        "plan_cost": _mean([m["best_cost"] for m in global_runs]),
        "optimizer_runs": len(optimizer_runs),
        "error": "",
    }


def task_row(task: Task, metrics: dict[str, Any], log: str) -> dict[str, Any]:
    row: dict[str, Any] = {"world": task.world, "optimizer": task.optimizer, "seed": task.seed}
    row.update(dict(task.overrides))
    row.update(metrics)
    row["log"] = log
    return row


def error_row(task: Task, message: str, log: str = "") -> dict[str, Any]:
    metrics = {k: math.nan for k in METRICS}
    metrics.update(status="error", success=False, error=message)
    for k in ("agents", "arrived", "collisions", "escapes", "optimizer_runs"):
        metrics[k] = ""
    return task_row(task, metrics, log)


def log_name(task: Task) -> str:
    """The log's path relative to the output folder."""
    return f"runs/{task.run_id}.mcap"


def run_task(task: Task, out_dir: str) -> dict[str, Any]:
    """Worker side: build the world, run it, return its row. Never raises for a failing run:
    the exception becomes an ``error`` row (with the log so far, when the run had started)."""
    limit_blas_threads()  # workers share the cores: small matrices on one BLAS thread
    final = Path(out_dir) / log_name(task)
    final.parent.mkdir(parents=True, exist_ok=True)
    # A unique name per attempt: a retried task (its worker died) never shares a file with the
    # attempt that died, and a log only gets its final name once the run is over.
    part = final.with_name(f"{final.name}.{uuid.uuid4().hex[:8]}.part")
    try:
        world = build_world(task.world_path, task.optimizer, task.overrides)
        summary = run_world(world, task.seed, part)
    except Exception as exc:  # noqa: BLE001 - every failure of a run is reported in its row
        log = ""
        if part.exists():
            os.replace(part, final)
            log = log_name(task)
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())
        return error_row(task, msg[:500], log)
    os.replace(part, final)
    _summary, optimizer_runs = read_log(final)
    return task_row(task, metrics_row(summary, optimizer_runs), log_name(task))


def finished_row(task: Task, out_dir: Path) -> dict[str, Any] | None:
    """The row of a task whose log is complete and is the log of this very task; else None."""
    log = out_dir / log_name(task)
    if not log.is_file():
        return None
    summary, optimizer_runs = read_log(log)
    if summary is None or summary.get("interrupted") or "agents" not in summary:
        return None
    if summary.get("seed") != task.seed or summary.get("optimizer") != task.optimizer:
        return None
    return task_row(task, metrics_row(summary, optimizer_runs), log_name(task))


# ----------------------------------------------------------------------------- results.csv


def _cell(v: Any) -> str:
    if isinstance(v, float):  # 12 significant digits: 20.292, not 20.291999999999998
        return "" if math.isnan(v) else f"{v:.12g}"
    if isinstance(v, (list, dict)):
        import json

        return json.dumps(v)
    return str(v)


class ResultsFile:
    """results.csv, appended row by row (flushed) so that a killed sweep keeps every row."""

    def __init__(self, path: Path, cols: list[str], rows: list[dict[str, Any]]):
        self.path = path
        self.cols = cols
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(cols)
            for r in rows:
                w.writerow([_cell(r.get(c, "")) for c in cols])
        os.replace(tmp, path)
        self.f = open(path, "a", newline="", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self.w = csv.writer(self.f)

    def append(self, row: dict[str, Any]) -> None:
        self.w.writerow([_cell(row.get(c, "")) for c in self.cols])
        self.f.flush()

    def close(self) -> None:
        self.f.close()


def read_results(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# ----------------------------------------------------------------------------- running


def scheduler_problem(address: str | None) -> str | None:
    """Why ``address`` is not a Dask scheduler address (``tcp://host:port`` or ``host:port``), or None."""
    if not address:
        return None
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls", "ws", "wss"):
            _host, port = parse_host_port(location)
            if not 0 < int(port) < 65536:
                raise ValueError(f"port {port} out of range 1..65535")
    except (ValueError, TypeError) as exc:
        return f"--scheduler {address}: not a scheduler address ({exc}); e.g. tcp://head:8786"
    return None


def make_client(workers: int | None, scheduler: str | None):  # noqa: ANN201 - distributed.Client
    """A client of the scheduler at ``scheduler``, or of a new LocalCluster of ``workers`` processes."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler, timeout="20s")
    # The workers start with SIGINT ignored (a started Python keeps an inherited SIG_IGN): a Ctrl-C
    # in the terminal reaches the whole process group, and only this process should answer it,
    # by closing the cluster, instead of every worker printing its own traceback.
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main_thread else None
    try:
        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,  # the simulator is single-threaded Python: one run per process
            processes=True,
            silence_logs=logging.ERROR,
            dashboard_address=":0",  # a free port (printed): no warning when 8787 is taken
        )
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous)
    client = Client(cluster)
    # a worker the nanny restarts later is a fresh process: the plugin ignores SIGINT there too
    client.register_plugin(_quiet_worker_plugin(), name="swarmplan-quiet-workers")
    return client


def _quiet_worker_plugin():  # noqa: ANN202 - a distributed.WorkerPlugin
    """A worker plugin: the worker ignores SIGINT and keeps quiet about a scheduler that goes away.

    A Ctrl-C in a terminal reaches the whole process group; the sweep's own process answers it
    (it closes the cluster and keeps every finished row), the workers must not each print a
    traceback. Workers started with the cluster inherit an ignored SIGINT; the plugin covers
    the ones a nanny restarts later. When the cluster closes under a busy worker, its heartbeat
    to the scheduler fails and ``distributed.worker`` logs an ERROR with a traceback: a worker's
    own log is only about its connection (a run's failure comes back as its row's ``error``, a
    worker's death is reported by the scheduler), so it is raised to CRITICAL. (Defined here,
    sent to the workers by value.)
    """
    from distributed.diagnostics.plugin import WorkerPlugin

    class QuietWorker(WorkerPlugin):
        def setup(self, worker) -> None:  # noqa: ANN001 - distributed.Worker
            import logging
            import signal
            import threading

            logging.getLogger("distributed.worker").setLevel(logging.CRITICAL)
            logging.getLogger("distributed.core").setLevel(logging.CRITICAL)
            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return QuietWorker()


def complete_results(out_dir: Path, tasks: list[Task], override_keys: list[str], since: float) -> int:
    """After an interrupted sweep: append to results.csv the row of every run whose log was
    completed since ``since`` (a time.time()) but whose row never reached the client (the
    interruption came between the two). Returns the number of rows added."""
    path = out_dir / "results.csv"
    if not path.is_file():
        return 0
    listed = {r.get("log", "") for r in read_results(path)}
    added = []
    for t in tasks:
        log = out_dir / log_name(t)
        if log_name(t) in listed or not log.is_file() or log.stat().st_mtime < since:
            continue
        try:
            row = finished_row(t, out_dir)
        except Exception:  # noqa: BLE001 - a log that cannot be read has no row
            row = None
        if row is not None:
            added.append(row)
    if added:
        cols = columns(override_keys)
        with open(path, "a", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            for row in added:
                w.writerow([_cell(row.get(c, "")) for c in cols])
    return len(added)


def dashboard_line(client) -> str:  # noqa: ANN001
    try:
        import bokeh  # noqa: F401
    except ImportError:
        return (
            f"dashboard: {client.dashboard_link} (served once bokeh is installed: pip install 'bokeh>=3.1')"
        )
    return f"dashboard: {client.dashboard_link}"


def run_tasks(
    tasks: list[Task],
    out_dir: Path,
    override_keys: list[str],
    client,  # noqa: ANN001 - distributed.Client
    *,
    resume: bool = False,
    progress: bool = True,
    stream=sys.stderr,  # noqa: ANN001
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> tuple[list[dict[str, Any]], int]:
    """Run ``tasks`` on ``client``; (rows in task order, number of runs skipped by ``resume``).

    results.csv in ``out_dir`` is rewritten at the start (the rows kept by ``resume``), grows by
    one line per finished run and is rewritten in task order at the end.
    """
    from distributed import as_completed
    from tqdm import tqdm

    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "runs").mkdir(exist_ok=True)
    for stale in (out_dir / "runs").glob("*.part"):  # attempts of an interrupted sweep
        stale.unlink(missing_ok=True)
    rows: dict[int, dict[str, Any]] = {}
    if resume:
        for t in tasks:
            r = finished_row(t, out_dir)
            if r is not None:
                rows[t.index] = r
    skipped = len(rows)
    cols = columns(override_keys)
    results = ResultsFile(out_dir / "results.csv", cols, [rows[i] for i in sorted(rows)])
    todo = [t for t in tasks if t.index not in rows]
    by_key: dict[str, Task] = {}
    futures = []
    # Keys unique to this sweep: the scheduler would hand a second sweep of the same runs (into
    # another folder) the first one's results.
    token = uuid.uuid4().hex[:8]
    for t in todo:
        key = f"swarmplan-{token}-{t.run_id}"
        by_key[key] = t
        futures.append(client.submit(run_task, t, str(out_dir.resolve()), key=key, pure=False))
    failed = sum(r["status"] != "ok" for r in rows.values())
    bar = tqdm(
        total=len(tasks), initial=skipped, unit="run", file=stream, disable=not progress, dynamic_ncols=True
    )
    bar.set_postfix_str(f"failed {failed}")
    try:
        for fut in as_completed(futures):
            t = by_key[fut.key]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: the task's workers kept dying
                row = error_row(t, " ".join(f"{type(exc).__name__}: {exc}".split())[:500])
            rows[t.index] = row
            results.append(row)
            if on_row is not None:
                on_row(row)
            failed += row["status"] != "ok"
            bar.update(1)
            bar.set_postfix_str(f"failed {failed}")
    finally:
        bar.close()
        results.close()
        for f in futures:
            if not f.done():
                f.cancel()
    for stale in (out_dir / "runs").glob("*.part"):  # attempts whose worker died
        stale.unlink(missing_ok=True)
    ordered = [rows[i] for i in sorted(rows)]
    ResultsFile(out_dir / "results.csv", cols, ordered).close()
    return ordered, skipped
