"""``python -m swarmplan.run WORLD [--seed N] [--out PATH] [--optimizer NAME] [--no-guide] [--max-time S]
[--quiet] [--live [--port N] [--speed X]]``.

``--live`` serves the run on 127.0.0.1 (Foxglove WebSocket protocol) while it is logged, paced
to real time (``--speed``: a multiple of it, 0 as fast as it runs).

Exit status: 0 when every agent arrived without collision, 1 when the run finished
otherwise (or was interrupted: Ctrl-C or SIGTERM close the log with a summary that says so),
2 on bad input, including a log path that cannot be written (nothing is written then).
"""

from __future__ import annotations

import argparse
import difflib
import socket
import sys
from pathlib import Path
from typing import Any

from swarmplan import optimizers
from swarmplan.cli.common import (
    HelpFormatter,
    comms_line,
    quiet_on_closed_stdout,
    write_failure,
    writer_messages,
)
from swarmplan.io.compile_notice import CompileNotice, said_marker
from swarmplan.io.runner import LiveView, apply_overrides, simulate
from swarmplan.runtime.blas import limit_blas_threads
from swarmplan.sim.threats import exposure_warnings
from swarmplan.world import World, WorldError, load_world

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


def log_path_for(world: World, seed: int, optimizer: str, out: str | None) -> Path:
    """Where the log goes: ``--out`` or the world's ``log.path`` template (relative to the cwd)."""
    template = out if out is not None else world.log_path
    try:
        return Path(template.format(name=world.name, seed=seed, optimizer=optimizer))
    except (KeyError, IndexError, ValueError) as exc:
        raise WorldError(
            [f"log.path: bad template {template!r} ({exc}); use {{name}}, {{seed}}, {{optimizer}}"]
        ) from None


def check_writable(path: Path, label: str) -> None:
    """Fail before any work when the log cannot be written (a directory, no such place, no rights)
    or is not named as an MCAP file: replay, track and the Foxglove app recognise a log by its
    ``.mcap`` extension, and an MCAP file named ``.txt`` would be opened as text."""
    if path.is_dir():
        raise WorldError([f"{label}: cannot write the log {str(path)!r}: it is a directory"], "command line")
    if path.suffix.lower() != ".mcap":
        raise WorldError(
            [f"{label}: the log {str(path)!r} is an MCAP file: give it the .mcap extension"], "command line"
        )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("ab"):  # appends nothing: an existing file is left as it is until the run
            pass
    except OSError as exc:
        raise WorldError(
            [f"{label}: cannot write the log {str(path)!r}: {exc.strerror or exc}"], "command line"
        ) from None


TURN_RULES = (
    (True, "fixed wing: curvature over 1.05 / min_turn_radius"),
    (False, "multirotor: lateral acceleration over 1.05 max_accel"),
)
"""(fixed wing or not, the rule its broken turn limit is): a table names only the rules of the
models whose limit was broken."""


def _fixed_wing(a: dict[str, Any]) -> bool:
    """A summary entry of a fixed wing (its turn limit is a curvature, not an acceleration)."""
    return a.get("lateral_accel_limit") is None


def _curvature(a: dict[str, Any]) -> tuple[str, str]:
    """(max curvature, its limit) for a fixed wing; '-' for a multirotor: it may turn the tighter
    the slower it flies (a hovering one's steps of millimetres make any turn a curvature in the
    hundreds), so its turn limit is the lateral acceleration beside it."""
    if not _fixed_wing(a):
        return "-", "-"
    limit = a.get("curvature_limit")
    return f"{a['max_curvature']:.3g}", "-" if limit is None else f"{limit:.3g}"


def _lateral(a: dict[str, Any]) -> str:
    """Max lateral acceleration beside the multirotor's max_accel; '!' marks a broken turn limit."""
    flag = " !" if a.get("curvature_violation") else ""
    if _fixed_wing(a):  # its limit is the curvature
        return ("-" if a.get("max_lateral_accel") is None else f"{a['max_lateral_accel']:.2f}") + flag
    return f"{a['max_lateral_accel']:.2f}/{a['lateral_accel_limit']:.2f}{flag}"


def format_summary(summary: dict[str, Any], log_path: Path | None, compiled: bool = False) -> str:
    """The per-agent table printed at the end of a run (``compiled``: its wall time includes
    compiling the kernels, which the speed figure says)."""
    head = (
        "agent",
        "arrived",
        "time s",
        "length m",
        "ratio",
        "min clear m",
        "max curv 1/m",
        "curv limit 1/m",
        "lat acc m/s2",
        "cusps",
        "collisions",
        "stuck",
        "escapes",
    )
    rows = []
    for a in summary["agents"]:
        rows.append(
            (
                a["id"],
                "yes" if a["arrived"] else f"no ({a['final_mode']})",
                "-" if a["arrival_time"] is None else f"{a['arrival_time']:.1f}",
                f"{a['path_length']:.1f}",
                "-" if a["length_ratio"] is None else f"{a['length_ratio']:.3f}",
                "-" if a["min_clearance"] is None else f"{a['min_clearance']:.2f}",
                *_curvature(a),
                _lateral(a),
                str(a.get("cusps", 0)),
                str(a["collisions"]),
                str(a["stuck_events"]),
                str(a["escapes"]),
            )
        )
    if any("threat_time" in a for a in summary["agents"]):  # the world has threats
        head += ("threat s", "core s", "closest m")
        rows = [
            (*r, f"{a['threat_time']:.1f}", f"{a['threat_core_time']:.1f}", _closest(a))
            for r, a in zip(rows, summary["agents"], strict=True)
        ]
    widths = [max(len(h), *(len(r[k]) for r in rows)) for k, h in enumerate(head)]
    line = lambda cells: "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True))  # noqa: E731
    out = [line(head), line(["-" * w for w in widths])] + [line(r) for r in rows]
    broken = [a for a in summary["agents"] if a.get("curvature_violation")]
    if broken:
        rules = [rule for fixed, rule in TURN_RULES if any(_fixed_wing(a) == fixed for a in broken)]
        out.append(f"TURN LIMIT BROKEN (!): {', '.join(a['id'] for a in broken)} ({'; '.join(rules)})")
    out += exposure_warnings(summary)
    if "comms" in summary:
        c = summary["comms"]
        out.append(comms_line(c, c["oldest_age_max"], c["oldest_age_mean"]))
    verdict = "SUCCESS" if summary["success"] else ("INTERRUPTED" if summary["interrupted"] else "FAILED")
    out.append("")
    out.append(
        f"{verdict}: {summary['arrived']}/{summary['agents_total']} arrived, "
        f"{summary['collisions']} collision(s), "
        f"sim {summary['sim_time']:.1f} s in {summary['wall_time']:.2f} s wall "
        f"({summary['sim_time'] / max(summary['wall_time'], 1e-9):.1f} sim-s/s"
        + (", compiling included" if compiled else "")
        + "), "
        f"world {summary['world']!r}, seed {summary['seed']}, optimizer {summary['optimizer']}"
    )
    if log_path is not None:
        out.append(f"log: {log_path}")
    return "\n".join(out)


def _closest(a: dict[str, Any]) -> str:
    if a.get("threat_closest") is None:
        return "-"
    return f"{a['threat_closest']:.1f} ({a['threat_closest_to']})"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m swarmplan.run",
        description="Simulate a swarmplan world and log it to MCAP.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("world", help="world YAML file")
    p.add_argument("--seed", type=int, default=None, help="random seed; unset: the world's seed")
    p.add_argument("--out", default=None, help="log file; unset: the world's log.path")
    p.add_argument(
        "--optimizer",
        default=None,
        help="escape/smoothing optimizer, or 'none' for pure APF; unset: the world's",
    )
    p.add_argument(
        "--no-guide",
        action="store_true",
        help="fly the bare potential field: no guide round static obstacles "
        "(planner.apf.guide: false); unset: the world's",
    )
    p.add_argument("--max-time", type=float, default=None, help="override the world's sim.max_time (s)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument(
        "--live",
        action="store_true",
        help="also serve the run live on 127.0.0.1 (Foxglove WebSocket protocol: in Foxglove, "
        "Open connection, Foxglove WebSocket, ws://127.0.0.1:PORT); the log is written as well",
    )
    p.add_argument(
        "--port", type=int, default=None, help="with --live: the port (unset: 8765; 0: a free one)"
    )
    p.add_argument(
        "--speed",
        type=float,
        default=None,
        help="with --live: times real time (unset: 1; 0: as fast as it runs)",
    )
    return p


def live_view(args: argparse.Namespace) -> LiveView | None:
    """The live view the options ask for (None without --live); problems as a WorldError."""
    if not args.live:
        given = [name for name in ("port", "speed") if getattr(args, name) is not None]
        if given:
            raise WorldError([f"--{given[0]}: only with --live"], "command line")
        return None
    port = LiveView.port if args.port is None else args.port
    speed = 1.0 if args.speed is None else args.speed
    if not 0 <= port <= 65535:
        raise WorldError([f"--port: must be 0-65535, got {port}"], "command line")
    if not speed >= 0 or speed == float("inf"):
        raise WorldError([f"--speed: must be >= 0 and finite, got {speed:g}"], "command line")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((LiveView.host, port))
        except OSError as exc:
            raise WorldError(
                [f"--port: cannot serve on {LiveView.host}:{port}: {exc.strerror or exc}"], "command line"
            ) from None
    return LiveView(port=port, speed=speed)


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    limit_blas_threads()
    try:
        names = optimizers.available()
        if args.optimizer is not None and args.optimizer != "none" and args.optimizer not in names:
            close = difflib.get_close_matches(args.optimizer, ["none", *names], n=1, cutoff=0.6)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise WorldError(
                [f"--optimizer: unknown optimizer '{args.optimizer}'{hint}; known: none, {', '.join(names)}"],
                "command line",
            )
        if args.max_time is not None and not args.max_time > 0:
            raise WorldError([f"--max-time: must be > 0, got {args.max_time:g}"], "command line")
        if args.seed is not None and args.seed < 0:
            raise WorldError([f"--seed: must be >= 0, got {args.seed}"], "command line")
        live = live_view(args)
        world = apply_overrides(
            load_world(args.world, names), args.optimizer, args.max_time, False if args.no_guide else None
        )
        seed = world.seed if args.seed is None else args.seed
        log_path = log_path_for(world, seed, world.planner_config.optimizer.name, args.out)
        check_writable(log_path, "--out" if args.out is not None else "log.path")
    except WorldError as exc:
        print(f"error: {exc.source}: invalid input", file=sys.stderr)
        for p in exc.problems:
            print(f"  {p}", file=sys.stderr)
        return EXIT_BAD_INPUT
    complaints = None
    notice = None if args.quiet else CompileNotice(marker=said_marker())
    try:
        with writer_messages() as complaints:
            summary = simulate(
                world,
                seed,
                log_path,
                progress=not args.quiet and sys.stderr.isatty(),
                stop_on_signals=True,
                live=live,
                notices=notice or False,
            )
    except (RuntimeError, OSError) as exc:
        reason = write_failure(exc, complaints)
        if reason is not None:  # e.g. no space left: the log ends where writing failed
            print(f"error: {log_path}: cannot write the log ({reason})", file=sys.stderr)
            return EXIT_BAD_INPUT
        if live is None or "bind" not in str(exc):
            raise
        print(f"error: command line: invalid input\n  --port: cannot serve: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        summary = {"interrupted": True}
    if summary["interrupted"]:
        print(f"\ninterrupted: the log {log_path} was closed with every step so far", file=sys.stderr)
        return EXIT_FAILED
    if not args.quiet:
        print(format_summary(summary, log_path, compiled=notice is not None and notice.compiled))
    return EXIT_OK if summary["success"] else EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
