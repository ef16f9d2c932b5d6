"""Command line: ``python -m swarmplan.export RUN.mcap --format crazyflie|px4|csv [--agent ID ...]
--out DIR [--check] [--max-deviation M]``.

Turns the flown paths of a run log into what vehicles load (``docs/export.md``):

- ``crazyflie``: per agent a trajectory CSV of 7th-degree pieces (Bitcraze's format, as cflib's
  ``Poly4D`` uploads it), within 0.05 m of the flown path (or a tenth of the agent's
  separation, or ``--max-deviation``), continuous to the acceleration, within the agent's
  speed and acceleration limits and at most 31 pieces (the 4096-byte trajectory memory);
- ``px4``: per agent a QGroundControl ``.plan`` and a ``QGC WPL 110`` ``.waypoints`` list, the
  flown path reduced to waypoints within the goal tolerance (or ``--max-deviation``), in
  geodetic coordinates from the world's ``origin`` (or ``--origin``);
- ``csv``: per agent the flown samples ``t,x,y,z,vx,vy,vz``.

A ``manifest.json`` names every file with its agent's start time and the frame. ``--check`` flies
every export again with the vehicle models of ``track`` and checks the swarm together on the
exported timing (separation, contacts); its report is also written as ``check.json``.

Exit codes: 0 normally; 1 when ``--check`` finds a limit broken (the files are written); 2 for
bad input (a missing, unreadable or cut-short log, a log without agents, an unknown agent, a
geodetic export from a world without ``origin`` and without ``--origin``, a path that cannot be
exported as asked, an output folder that cannot be written), with one line on stderr and
nothing written.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from swarmplan.cli.common import HelpFormatter, output_dir_problem, plain, quiet_on_closed_stdout
from swarmplan.runtime.blas import limit_blas_threads


class InputError(Exception):
    """Bad command-line input: one line for the user, exit 2."""


def build_parser() -> argparse.ArgumentParser:
    from swarmplan.export.files import FORMATS

    ap = argparse.ArgumentParser(
        prog="python -m swarmplan.export",
        description=plain(__doc__ or "").split("\n\n", 1)[1],
        formatter_class=HelpFormatter,
    )
    ap.add_argument("log", help="run log (.mcap) written by python -m swarmplan.run")
    ap.add_argument("--format", required=True, choices=FORMATS, help="what to write")
    ap.add_argument("--agent", metavar="ID", nargs="+", action="extend", default=None,
                    help="only these agents (default: every agent)")  # fmt: skip
    ap.add_argument("--out", metavar="DIR", required=True, help="output folder (created if missing)")
    ap.add_argument(
        "--origin",
        metavar="LAT,LON[,ALT]",
        default=None,
        help="geodetic position of the world's [0, 0, 0] (degrees, m) when the log's world has no origin",
    )
    ap.add_argument("--check", action="store_true", help="fly the exports again and check the swarm")
    ap.add_argument(
        "--max-deviation",
        metavar="M",
        type=float,
        default=None,
        help="largest distance (m) of the export from the flown path (crazyflie: instead of "
        "min(0.05, separation / 10); px4: at most the goal tolerance)",
    )
    return ap


def check_args(args: argparse.Namespace) -> None:
    if not Path(args.log).is_file():
        raise InputError(f"{args.log}: no such file")
    if not os.access(args.log, os.R_OK):
        raise InputError(f"{args.log}: not readable")
    if args.max_deviation is not None and not (math.isfinite(args.max_deviation) and args.max_deviation > 0):
        raise InputError(f"--max-deviation {args.max_deviation:g}: must be a number > 0")
    if args.origin is not None:
        args.origin = parse_origin(args.origin)
    problem = output_dir_problem("--out", args.out)
    if problem:
        raise InputError(problem)


def parse_origin(text: str) -> dict[str, float]:
    """``LAT,LON[,ALT]`` as the world's ``origin`` mapping (checked like the world key)."""
    try:
        parts = [float(v) for v in text.split(",")]
    except ValueError:
        parts = []
    if len(parts) not in (2, 3) or not all(math.isfinite(v) for v in parts):
        raise InputError(f"--origin {text}: expected LAT,LON or LAT,LON,ALT (numbers)")
    if not -90 <= parts[0] <= 90 or not -180 <= parts[1] <= 180:
        raise InputError(f"--origin {text}: latitude must be in [-90, 90], longitude in [-180, 180]")
    return {"lat": parts[0], "lon": parts[1], "alt": parts[2] if len(parts) == 3 else 0.0}


@quiet_on_closed_stdout
def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    limit_blas_threads()
    from swarmplan.export.files import build, run_check, write
    from swarmplan.export.source import ExportError, LimitError
    from swarmplan.replay import RecordingError, load
    from swarmplan.world.tracker_config import parse_tracker

    try:
        check_args(args)
        try:
            rec = load(args.log)
        except RecordingError as exc:
            raise InputError(str(exc)) from None
        try:
            if args.origin is not None:
                rec.world["origin"] = args.origin
            exp = build(rec, args.format, args.agent, args.max_deviation)
        except (ExportError, LimitError) as exc:
            raise InputError(str(exc)) from None
        cfg, problems = parse_tracker(rec.world.get("tracker"), "tracker")
        if args.check and problems:
            raise InputError(f"/world {problems[0]}")
    except InputError as exc:
        print(f"export: {exc}", file=sys.stderr)
        return 2
    result = None
    if args.check:
        result = run_check(rec, exp, cfg)
    try:
        write(exp, args.out)
    except OSError as exc:
        print(f"export: cannot write {args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    models = {p.model for p in exp.plans}
    print(f"{args.format} export of {len(exp.plans)} agent(s) ({', '.join(sorted(models))}) to {args.out}:")
    print("\n".join(exp.lines))
    if result is not None:
        print("\n".join(result.lines()))
        return 0 if result.ok else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
