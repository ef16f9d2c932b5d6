"""Command line: ``python -m swarmplan.replay RUN.mcap [options]``.

Prints what the run was, the metrics recomputed from the recorded states and whether
they agree with the recorded ``/summary``; optionally the state at a time, plots and an
animation. Exit codes: 0 normally, 1 with ``--strict`` when metrics disagree with the
summary, 2 on bad input (a file that cannot be read, an unknown agent, an output path that
cannot be written or has an unsupported extension, a non-positive ``--fps``), with one line
on stderr. Output paths and numbers are checked before the log is read; missing parent
folders of output files are created, as ``swarmplan.run`` does for its log.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from swarmplan.cli.common import HelpFormatter, comms_line, quiet_on_closed_stdout
from swarmplan.replay.metrics import AgentMetrics, Tolerances, compare_with_summary, compute_metrics
from swarmplan.replay.recording import Recording, RecordingError, load
from swarmplan.runtime.paths import output_file_problem


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m swarmplan.replay",
        description="Replay a swarmplan run log: run overview, recomputed metrics, plots, animation.",
        formatter_class=HelpFormatter,
    )
    ap.add_argument("log", help="run log (.mcap)")
    ap.add_argument(
        "--at", type=float, default=None, metavar="T", help="print the state at time T (nearest step)"
    )
    ap.add_argument("--agent", metavar="ID", help="only this agent")
    ap.add_argument("--events", action="store_true", help="list the recorded events")
    ap.add_argument("--plot", metavar="PNG", help="3D view of the run")
    ap.add_argument("--plot-2d", metavar="PNG", help="top view of the run")
    ap.add_argument("--curvature", metavar="PNG", help="curvature along each path vs time")
    ap.add_argument("--convergence", metavar="PNG", help="optimizer convergence curves")
    ap.add_argument("--animate", metavar="GIF|MP4", help="animated playback (.gif, or .mp4 with ffmpeg)")
    ap.add_argument("--fps", type=float, default=10.0, help="animation frames per second")
    ap.add_argument("--max-frames", type=int, default=150, help="animation frame cap")
    ap.add_argument("--speed", type=float, default=None, help="animation sim-seconds per video second")
    ap.add_argument("--strict", action="store_true", help="exit 1 when metrics disagree with /summary")
    return ap


IMAGE_OPTIONS = ("plot", "plot_2d", "curvature", "convergence")
ANIMATION_EXTENSIONS = (".gif", ".mp4")


def _option(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _image_extensions() -> list[str]:
    from matplotlib.backend_bases import FigureCanvasBase

    return sorted("." + e for e in FigureCanvasBase.get_supported_filetypes())


def check_arguments(args: argparse.Namespace) -> str | None:
    """The first problem with the command line's outputs and numbers, as one line, or None."""
    for dest in IMAGE_OPTIONS:
        path = getattr(args, dest)
        if path is None:
            continue
        ext = Path(path).suffix.lower()
        known = _image_extensions()
        if Path(path).is_dir():
            return f"{_option(dest)} {path}: is a directory, not a file"
        if ext not in known:
            return (
                f"{_option(dest)} {path}: unsupported image type {ext or '(no extension)'!r};"
                f" use one of {', '.join(known)}"
            )
        problem = output_file_problem(_option(dest), path)
        if problem:
            return problem
    if args.animate is not None:
        ext = Path(args.animate).suffix.lower()
        if Path(args.animate).is_dir():
            return f"--animate {args.animate}: is a directory, not a file"
        if ext not in ANIMATION_EXTENSIONS:
            return (
                f"--animate {args.animate}: unsupported animation type {ext or '(no extension)'!r};"
                " use .gif or .mp4"
            )
        problem = output_file_problem("--animate", args.animate)
        if problem:
            return problem
    if not (math.isfinite(args.fps) and args.fps > 0):
        return f"--fps: must be a positive number, got {args.fps:g}"
    if args.max_frames < 1:
        return f"--max-frames: must be >= 1, got {args.max_frames}"
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0):
        return f"--speed: must be a positive number, got {args.speed:g}"
    if args.at is not None and not math.isfinite(args.at):
        return f"--at: must be a finite time, got {args.at:g}"
    return None


def _prepare(path: str) -> str:
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return path


def _f(v, fmt="{:.2f}", none="-") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return none
    return fmt.format(v)


def describe(rec: Recording) -> list[str]:
    w = rec.world
    planner = w.get("planner") or {}
    opt = planner.get("optimizer") or {}
    lines = []
    opt_name = (rec.summary or {}).get("optimizer") or opt.get("name", "?")
    budget = f" (pop {opt.get('population', '?')}, iter {opt.get('iterations', '?')})"
    if opt_name == "none":  # pure APF: no optimizer runs, no budget
        budget = ""
    lines.append(
        f"run: {w.get('name', '?')}  seed {w.get('seed', '?')}  optimizer {opt_name}{budget}"
        f"  swarmplan {w.get('swarmplan_version', '?')}"
    )
    size = os.path.getsize(rec.file)
    n_obst = len(rec.obstacles)
    n_mov = len(rec.moving_obstacles)
    t0 = rec.times[0] if rec.n_steps else 0.0
    t1 = rec.times[-1] if rec.n_steps else 0.0
    lines.append(
        f"file: {rec.file} ({size / 1e6:.2f} MB)  {rec.n_steps} steps, t = {t0:.2f} .. {t1:.2f} s"
        f" (dt {rec.dt:.3g} s, duration {rec.duration:.2f} s)"
    )
    b = w.get("bounds") or {}
    n_peaks = len((w.get("terrain") or {}).get("peaks") or [])
    lines.append(
        f"world: {rec.n_agents} agents, {n_obst} obstacles ({n_mov} moving), "
        f"{len(w.get('threats') or [])} threats, terrain peaks {n_peaks}, "
        f"bounds {b.get('min')} .. {b.get('max')}"
    )
    kinds: dict[str, int] = {}
    for e in rec.events:
        kinds[e.kind] = kinds.get(e.kind, 0) + 1
    ev = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) or "none"
    lines.append(f"events: {ev};  optimizer runs: {len(rec.optimizer_runs)}")
    if rec.truncated:
        lines.append(
            "NOTICE: this file was cut short (no summary section/footer, e.g. the run was hard-killed);"
            f" replaying the {rec.n_steps} steps up to its last complete chunk."
        )
    if rec.comms:  # the ages each agent acted on, read from /comms (the counts from its last message)
        ages = [a["age"] for m in rec.comms for a in m.get("agents", []) if a.get("age") is not None]
        lines.append(comms_line(rec.comms[-1], max(ages, default=0.0), float(np.mean(ages)) if ages else 0.0))
    s = rec.summary
    if s is None:
        lines.append("recorded /summary: none")
    else:
        lines.append(
            f"recorded /summary: success {s.get('success')}  interrupted {s.get('interrupted')}"
            f"  sim_time {_f(s.get('sim_time'))} s  wall_time {_f(s.get('wall_time'))} s"
        )
        if s.get("interrupted"):
            lines.append("NOTICE: the run was interrupted; the log holds every step up to the interruption.")
    return lines


def _turn(m: AgentMetrics) -> str:
    """Max curvature and its limit for a fixed wing; '-' for a multirotor, whose turn limit is
    the lateral acceleration (it may turn the tighter the slower it flies: a hovering one's
    millimetre steps make any turn a curvature in the hundreds)."""
    if m.lateral_accel_limit is not None:
        return f"{'-':>8} {'-':>7}"
    return f"{m.max_curvature:>8.4f} {_f(m.curvature_limit, '{:.4f}'):>7}"


def metrics_table(metrics: list[AgentMetrics]) -> list[str]:
    head = (
        f"{'agent':<10} {'arrived':>7} {'t_arr':>8} {'path_m':>9} {'min_clear':>9} {'closest':<12}"
        f" {'max_curv':>8} {'limit':>7} {'lat_acc':>7} {'a_max':>5}"
        f" {'cusps':>5} {'coll':>4} {'esc':>3} {'stuck':>5}"
    )
    threats = any(m.threat_time is not None for m in metrics)
    if threats:
        head += f" {'threat_s':>8} {'core_s':>6} {'closest':>7}"
    out = [head]
    for m in metrics:
        out.append(
            f"{m.id:<10} {('yes' if m.arrived else 'no'):>7} {_f(m.arrival_time):>8} {m.path_length:>9.2f}"
            f" {_f(m.min_clearance, '{:.3f}'):>9} {str(m.closest_body or '-'):<12} {_turn(m)}"
            f" {m.max_lateral_accel:>7.2f}"
            f" {_f(m.lateral_accel_limit, '{:.2f}'):>5}"
            f" {m.cusps:>5} {m.collisions:>4} {m.escapes:>3} {m.stuck_events:>5}"
            + (
                f" {_f(m.threat_time, '{:.1f}'):>8} {_f(m.threat_core_time, '{:.1f}'):>6}"
                f" {_f(m.threat_closest, '{:.1f}'):>7}"
                if threats
                else ""
            )
            + ("  TURN LIMIT BROKEN" if m.curvature_violation else "")
        )
        if m.collisions:
            out.append(f"{'':<10} collided with: {', '.join(m.collision_bodies)}")
        if m.threat_core_time:
            out.append(f"{'':<10} WARNING: {m.threat_core_time:.1f} s inside a threat's core (r_min)")
    return out


def state_at(rec: Recording, t: float, agents: list[int]) -> list[str]:
    k = rec.step_at(t)
    out = [f"state at t = {rec.times[k]:.3f} s (step {k}, nearest to {t:g})"]
    for i in agents:
        p, v = rec.positions[i, k], rec.velocities[i, k]
        dist = float(np.linalg.norm(p - rec.goals[i]))
        out.append(
            f"  {rec.agent_ids[i]:<10} mode {rec.modes[i, k]:<9} pos [{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}]"
            f"  vel [{v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f}] |v| {np.linalg.norm(v):.2f} m/s"
            f"  to goal {dist:.2f} m"
        )
    for oid in rec.obstacle_tracks:
        pos, q = rec.obstacle_poses(oid, np.array([rec.times[k]]))
        out.append(
            f"  obstacle {oid}: pos [{pos[0, 0]:.2f}, {pos[0, 1]:.2f}, {pos[0, 2]:.2f}]"
            f"  quat [{', '.join(f'{x:.3f}' for x in q[0])}]"
        )
    return out


def _write_outputs(rec: Recording, args: argparse.Namespace, agent_ids: list[str] | None) -> list[str]:
    outputs: list[str] = []
    if args.plot or args.plot_2d or args.curvature or args.convergence:
        from swarmplan.replay import analysis_plots, plots

        if args.plot:
            outputs.append(plots.save(plots.plot_3d(rec, agents=agent_ids), _prepare(args.plot)))
        if args.plot_2d:
            outputs.append(plots.save(plots.plot_top(rec, agents=agent_ids), _prepare(args.plot_2d)))
        if args.curvature:
            fig = analysis_plots.plot_curvature(rec, agents=agent_ids)
            outputs.append(plots.save(fig, _prepare(args.curvature)))
        if args.convergence:
            fig = analysis_plots.plot_convergence(rec, agents=agent_ids)
            outputs.append(plots.save(fig, _prepare(args.convergence)))
    if args.animate:
        from swarmplan.replay.animate import animate

        outputs.append(
            animate(
                rec,
                _prepare(args.animate),
                fps=args.fps,
                max_frames=args.max_frames,
                speed=args.speed,
                agents=agent_ids,
                progress=sys.stderr.isatty(),  # no bar in a captured log (as run)
            )
        )
    return outputs


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    problem = check_arguments(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    t_start = time.perf_counter()
    try:
        rec = load(args.log)
    except RecordingError as exc:  # its message starts with the file's name: say it once
        reason = str(exc).removeprefix(f"{args.log}: ")
        print(f"error: cannot read {args.log}: {reason}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as exc:
        print(f"error: cannot read {args.log}: {exc}", file=sys.stderr)
        return 2
    load_s = time.perf_counter() - t_start
    if rec.n_steps == 0:
        for line in describe(rec):
            print(line)
        print("no /agents/state steps recorded: nothing to replay")
        return 0
    if args.agent is not None:
        try:
            sel = [rec.agent_index(args.agent)]
        except KeyError as exc:
            print(f"error: {exc.args[0]}", file=sys.stderr)
            return 2
    else:
        sel = list(range(rec.n_agents))

    for line in describe(rec):
        print(line)
    print(f"(loaded in {load_s * 1000:.0f} ms)")
    print()
    metrics = compute_metrics(rec)
    shown = [metrics[i] for i in sel]
    print("metrics recomputed from the recorded states:")
    for line in metrics_table(shown):
        print("  " + line)
    print()
    disagreements: list[str] = []
    if rec.summary is None:
        print("no /summary recorded: nothing to compare with")
    else:
        disagreements, n = compare_with_summary(rec, shown, Tolerances())
        if args.agent is not None:
            disagreements = [d for d in disagreements if d.startswith(f"{args.agent}:")]
        if not disagreements:
            print(f"agreement with /summary: OK ({n} values compared within tolerance)")
        else:
            print(f"agreement with /summary: {len(disagreements)} DISAGREEMENT(S) ({n} values compared):")
            for d in disagreements:
                print(f"  - {d}")

    if args.events:
        print()
        print("events:")
        for e in rec.events:
            if args.agent is not None and e.agent != args.agent:
                continue
            print(f"  t={e.t:8.2f}  {str(e.agent):<10} {e.kind:<13} {e.detail}")
    if args.at is not None:
        print()
        for line in state_at(rec, args.at, sel):
            print(line)

    agent_ids = [rec.agent_ids[i] for i in sel] if args.agent is not None else None
    try:
        outputs = _write_outputs(rec, args, agent_ids)
    except OSError as exc:  # checked up front; a disk filling up or a race still ends here
        print(f"error: cannot write {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    for path in outputs:
        print(f"wrote {path}")
    if args.strict and disagreements:
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
