"""Command line: ``python -m swarmplan.track RUN.mcap [--agent ID] [--out T.mcap] [--plot P.png] [--json]``.

Flies each multirotor agent's recorded trajectory with a quadrotor model under paper 004's
cascaded PID and prints, per agent, the max and RMS tracking error, the peak tilt and thrust,
and whether the reference was flyable (every infeasible stretch is reported). Fixed-wing agents
are flown by a coordinated-turn aircraft (bank limit, airspeed dynamics) under L1 guidance and
an energy loop: max and RMS error, peak bank, and whether the error stays within
max(5 m, 0.05 R_min). The vehicle and
gains come from the ``tracker:`` section of the log's /world message when it has one, else the
documented defaults (``swarmplan/world/tracker_config.py``).

Exit codes: 0 normally; 2 for bad input (missing or unreadable log, unknown agent, bad
``tracker:`` section, unwritable ``--out``, unsupported ``--plot`` extension, a log without any
agent the tracker can fly), with one line on stderr and nothing written. Missing folders of
``--out`` and ``--plot`` are created. A log cut short is tracked up to its last complete chunk,
with a notice on stderr.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from swarmplan.cli.common import (
    HelpFormatter,
    output_file_problem,
    quiet_on_closed_stdout,
    write_failure,
    writer_messages,
)
from swarmplan.runtime.blas import limit_blas_threads
from swarmplan.track.output import PLOT_FORMATS
from swarmplan.world.tracker_config import TrackerConfig, parse_tracker


class InputError(Exception):
    """Bad command-line input: one line for the user, exit 2."""


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m swarmplan.track",
        description="Fly the recorded trajectories of a run log with a vehicle model (multirotors: "
        "a quadrotor under a cascaded PID, paper 004; fixed wings: a coordinated-turn aircraft under "
        "L1 guidance and an energy loop) and report the tracking error.",
        formatter_class=HelpFormatter,
    )
    ap.add_argument("log", help="run log (.mcap) written by python -m swarmplan.run")
    ap.add_argument("--agent", metavar="ID", default=None, help="only this agent (default: every agent)")
    ap.add_argument("--out", metavar="TRACK.mcap", default=None, help="write the tracked flight as a run log")
    ap.add_argument(
        "--plot", metavar="PNG", default=None, help=f"reference vs tracked plot ({', '.join(PLOT_FORMATS)})"
    )
    ap.add_argument("--json", action="store_true", help='print {"agents": {ID: {...}}} instead of a table')
    return ap


def check_args(args: argparse.Namespace) -> None:
    """Everything that can be checked without reading the log."""
    if not Path(args.log).is_file():
        raise InputError(f"{args.log}: no such file")
    if not os.access(args.log, os.R_OK):
        raise InputError(f"{args.log}: not readable")
    if args.out is not None:
        if Path(args.out).suffix.lower() != ".mcap":
            raise InputError(f"--out {args.out}: expected a .mcap file")
        if Path(args.out).resolve() == Path(args.log).resolve():
            raise InputError(f"--out {args.out}: would overwrite the input log")
        problem = output_file_problem("--out", args.out)
        if problem:
            raise InputError(problem)
    if args.plot is not None:
        ext = Path(args.plot).suffix.lower().lstrip(".")
        if ext not in PLOT_FORMATS:
            raise InputError(
                f"--plot {args.plot}: unsupported extension '.{ext}' (use one of: {', '.join(PLOT_FORMATS)})"
                if ext
                else f"--plot {args.plot}: no extension (use one of: {', '.join(PLOT_FORMATS)})"
            )
        problem = output_file_problem("--plot", args.plot)
        if problem:
            raise InputError(problem)


def tracker_config(world: dict) -> TrackerConfig:
    cfg, problems = parse_tracker(world.get("tracker"), "tracker")
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise InputError(f"/world {problems[0]}{more}")
    return cfg


def _fmt_table(result, wall: float) -> list[str]:
    lines = []
    if result.ids:
        lines.append(
            f"{'agent':<10} {'max err m':>9} {'rms err m':>9} {'at t s':>7} {'tilt deg':>8} "
            f"{'thrust N':>8} {'T/W':>5} {'sat s':>6} {'ref ok':>6}"
        )
    for aid in result.ids:
        m = result.agents[aid]
        lines.append(
            f"{aid:<10} {m.max_error_m:9.3f} {m.rms_error_m:9.3f} {m.time_of_max_error_s:7.2f} "
            f"{m.max_tilt_deg:8.1f} {m.max_thrust_n:8.2f} {m.max_thrust_to_weight:5.2f} "
            f"{m.saturated_s:6.2f} {'yes' if m.reference_feasible else 'NO':>6}"
        )
    if result.fixed_wing:
        lines.append(
            f"{'agent':<10} {'max err m':>9} {'rms err m':>9} {'at t s':>7} {'bank deg':>8} "
            f"{'limit m':>8} {'within':>6}  (fixed wing: coordinated turn, L1 + energy loop)"
        )
    for aid, f in result.fixed_wing.items():
        j = f.to_json()
        within = "yes" if j["within_error_limit"] else "NO"
        lines.append(
            f"{aid:<10} {j['max_error_m']:9.3f} {j['rms_error_m']:9.3f} {j['time_of_max_error_s']:7.2f} "
            f"{j['max_bank_deg']:8.1f} {j['error_limit_m']:8.2f} {within:>6}"
        )
    for aid, reason in result.skipped.items():
        lines.append(f"{aid:<10} skipped: {reason}")
    for aid in result.ids:
        m = result.agents[aid]
        if not m.reference_feasible:
            at = ", ".join(f"{t:.2f}" for t in m.infeasible_at[:8]) + (
                " ..." if len(m.infeasible_at) > 8 else ""
            )
            away = m.max_error_away_from_infeasible_m
            lines.append(
                f"WARNING {aid}: reference infeasible for {m.infeasible_s:.2f} s (needs up to "
                f"{m.max_reference_accel:.1f} m/s^2; starts at t = {at} s); max error more than 2 s "
                f"away from those instants: {'-' if away is None else f'{away:.3f} m'}"
            )
    cfg = result.cfg
    if not result.ids:
        lines.append(f"wall {wall:.2f} s")
        return lines
    lines.append(
        f"vehicle: {cfg.mass:g} kg, T/W {cfg.thrust_to_weight:g}, tilt <= {cfg.max_tilt_deg:g} deg, "
        f"drag {cfg.drag:g} N s^2/m^2; PID pos {cfg.position.kp:g}/{cfg.position.ki:g}/{cfg.position.kd:g}, "
        f"att {cfg.attitude.kp:g}, rate {cfg.rate.kp:g}; RK4 dt {cfg.dt:g} s; "
        f"wall {wall:.2f} s"
    )
    return lines


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    limit_blas_threads()
    from swarmplan.replay import RecordingError, load

    try:
        check_args(args)
        try:
            rec = load(args.log)
        except RecordingError as exc:
            raise InputError(str(exc)) from None
        if args.agent is not None and args.agent not in rec.agent_ids:
            raise InputError(f"--agent {args.agent}: no such agent (agents: {', '.join(rec.agent_ids)})")
        if rec.n_steps < 2:
            raise InputError(f"{args.log}: the log has {rec.n_steps} step(s); tracking needs at least two")
        cfg = tracker_config(rec.world)
    except InputError as exc:
        print(f"track: {exc}", file=sys.stderr)
        return 2
    if rec.truncated:
        print(
            f"track: NOTICE: {args.log} was cut short (no summary section/footer, e.g. the run was"
            f" hard-killed); tracking the {rec.n_steps} steps up to its last complete chunk",
            file=sys.stderr,
        )

    from swarmplan.track.output import plot, write_mcap
    from swarmplan.track.tracking import track

    start = time.perf_counter()
    result = track(rec, cfg, args.agent)
    wall = time.perf_counter() - start
    if not result.ids and not result.fixed_wing:  # nothing to fly: no plot, log or table of nothing
        reasons = "; ".join(f"{aid}: {why}" for aid, why in result.skipped.items())
        print(f"track: no agent of {args.log} can be tracked ({reasons})", file=sys.stderr)
        return 2
    for path in (args.out, args.plot):
        if path:  # missing folders are created, as run and replay do
            Path(path).parent.mkdir(parents=True, exist_ok=True)
    complaints = None
    try:
        with writer_messages() as complaints:
            if args.out:
                write_mcap(result, rec, args.out, source=str(args.log))
        if args.plot:
            plot(
                result,
                args.plot,
                title=f"{rec.world.get('name', '')}: tracking ({Path(args.log).name})",
                rec=rec,
            )
    except (RuntimeError, OSError) as exc:
        reason = write_failure(exc, complaints)
        if reason is None:
            raise
        print(f"track: cannot write {args.out if args.out else args.plot}: {reason}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result.to_json()))
    else:
        print("\n".join(_fmt_table(result, wall)))
        if args.out:
            print(f"tracked log: {args.out}")
        if args.plot:
            print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
