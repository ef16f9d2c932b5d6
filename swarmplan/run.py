"""``python -m swarmplan.run WORLD [--seed N] [--out PATH] [--optimizer NAME] [--max-time S] [--quiet]``.

Exit status: 0 when every agent arrived without collision, 1 when the run finished
otherwise (or was interrupted), 2 on bad input (nothing is written then).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from swarmplan.planner import make_planner, validate_planner_settings
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


def apply_overrides(world: World, optimizer: str | None, max_time: float | None) -> World:
    changes: dict[str, Any] = {}
    if max_time is not None:
        changes["max_time"] = float(max_time)
    if optimizer is not None:
        planner = dict(world.planner)
        opt = dict(planner["optimizer"], name=optimizer)
        if optimizer != world.planner["optimizer"]["name"]:
            # The world's params are settings of its own algorithm (e.g. rscdwoa's beta): another
            # algorithm runs with its papers' defaults.
            opt["params"] = {}
        planner["optimizer"] = opt
        changes["planner"] = planner
    return world.with_overrides(**changes) if changes else world


def simulate(
    world: World,
    seed: int,
    log_path: Path | None,
    *,
    progress: bool = False,
    stream: TextIO = sys.stderr,
) -> dict[str, Any]:
    """Run ``world`` to its end with ``seed``, recording to ``log_path``; returns the summary.

    The log is finished whatever happens: on Ctrl-C or an exception the summary says
    ``interrupted`` and the exception propagates after the file is closed.
    """
    from swarmplan.recording import McapRecorder
    from swarmplan.sim import Simulation

    optimizer = world.planner["optimizer"]["name"]
    recorder = (
        McapRecorder(
            log_path,
            flush_interval=world.resolved["log"]["flush_interval"],
            foxglove=world.resolved["log"]["foxglove"],
        )
        if log_path is not None
        else None
    )
    sim = Simulation(world, planner=make_planner(world, optimizer), recorder=recorder)
    bar = _Progress(world.max_time, stream) if progress else None
    interrupted = False
    try:
        sim.reset(seed=seed)
        while True:
            result = sim.step()
            if bar is not None:
                bar.update(result.state.t, int(result.state.active.sum()))
            if result.terminated or result.truncated:
                break
    except BaseException:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        summary = sim.summary(interrupted=interrupted) if sim.state is not None else {"interrupted": True}
        if recorder is not None:
            try:
                if sim.state is not None:
                    recorder.write_summary(summary)
            finally:
                recorder.close()
    return summary


class _Progress:
    """A one-line progress bar on a terminal, shown once the run has taken a couple of seconds."""

    def __init__(self, total: float, stream: TextIO):
        self.total = total
        self.stream = stream
        self.start = time.perf_counter()
        self.last = 0.0
        self.shown = False

    def update(self, t: float, flying: int) -> None:
        now = time.perf_counter()
        if now - self.start < 2.0 or now - self.last < 0.2:
            return
        self.last = now
        self.shown = True
        frac = min(1.0, t / self.total)
        width = 30
        fill = int(frac * width)
        rate = t / max(now - self.start, 1e-9)
        self.stream.write(
            f"\r[{'#' * fill}{'.' * (width - fill)}] t={t:7.1f}/{self.total:.0f} s  "
            f"{flying} flying  {rate:6.1f} sim-s/s"
        )
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


def format_summary(summary: dict[str, Any], log_path: Path | None) -> str:
    """The per-agent table printed at the end of a run."""
    head = (
        "agent",
        "arrived",
        "time s",
        "length m",
        "ratio",
        "min clear m",
        "max curv 1/m",
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
                f"{a['max_curvature']:.3f}",
                str(a["collisions"]),
                str(a["stuck_events"]),
                str(a["escapes"]),
            )
        )
    widths = [max(len(h), *(len(r[k]) for r in rows)) for k, h in enumerate(head)]
    line = lambda cells: "  ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True))  # noqa: E731
    out = [line(head), line(["-" * w for w in widths])] + [line(r) for r in rows]
    verdict = "SUCCESS" if summary["success"] else ("INTERRUPTED" if summary["interrupted"] else "FAILED")
    out.append("")
    out.append(
        f"{verdict}: {summary['arrived']}/{summary['agents_total']} arrived, "
        f"{summary['collisions']} collision(s), "
        f"sim {summary['sim_time']:.1f} s in {summary['wall_time']:.2f} s wall "
        f"({summary['sim_time'] / max(summary['wall_time'], 1e-9):.1f} sim-s/s), "
        f"world {summary['world']!r}, seed {summary['seed']}, optimizer {summary['optimizer']}"
    )
    if log_path is not None:
        out.append(f"log: {log_path}")
    return "\n".join(out)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m swarmplan.run", description="Simulate a swarmplan world and log it to MCAP."
    )
    p.add_argument("world", help="world YAML file")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the world's seed)")
    p.add_argument("--out", default=None, help="log file (default: the world's log.path)")
    p.add_argument("--optimizer", default=None, help="escape/smoothing optimizer, or 'none' for pure APF")
    p.add_argument("--max-time", type=float, default=None, help="override sim.max_time (s)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    return p


def check_planner_settings(world: World, source: str) -> None:
    """The planner's own sections of the world file (``planner.escape``, ``planner.global``)."""
    try:
        validate_planner_settings(world)
    except WorldError as exc:
        raise WorldError(exc.problems, source) from None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        from swarmplan import optimizers

        names = optimizers.available()
        if args.optimizer is not None and args.optimizer != "none" and args.optimizer not in names:
            raise WorldError(
                [f"--optimizer: unknown optimizer '{args.optimizer}'; known: none, {', '.join(names)}"],
                "command line",
            )
        if args.max_time is not None and not args.max_time > 0:
            raise WorldError([f"--max-time: must be > 0, got {args.max_time:g}"], "command line")
        if args.seed is not None and args.seed < 0:
            raise WorldError([f"--seed: must be >= 0, got {args.seed}"], "command line")
        world = apply_overrides(load_world(args.world, names), args.optimizer, args.max_time)
        check_planner_settings(world, str(args.world))
        seed = world.seed if args.seed is None else args.seed
        log_path = log_path_for(world, seed, world.planner["optimizer"]["name"], args.out)
    except WorldError as exc:
        print(f"error: {exc.source}: invalid input", file=sys.stderr)
        for p in exc.problems:
            print(f"  {p}", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        summary = simulate(world, seed, log_path, progress=not args.quiet and sys.stderr.isatty())
    except KeyboardInterrupt:
        print(f"\ninterrupted: the log {log_path} was closed with every step so far", file=sys.stderr)
        return EXIT_FAILED
    if not args.quiet:
        print(format_summary(summary, log_path))
    return EXIT_OK if summary["success"] else EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
