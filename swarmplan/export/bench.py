"""Exports of random worlds, checked: ``python -m swarmplan.bench export [--worlds N] [--seed S]
[--class lab|field|fixed_wing|all] [--out DIR]``.

Draws the worlds of ``python -m swarmplan.bench reach`` (the same world ``k`` of a class for the
same seed), flies each with the default planner into a log, exports every agent of it and flies
the exports again with ``--check`` (``docs/export.md``): Crazyflie trajectories for the
multirotor classes (``lab``: the Crazyflie's own scale), PX4 missions for every class (at an
origin of 0 N 0 E: the geodesy does not change the check), and the flown samples (``csv``:
the flight itself flown again, what the other formats are measured against). Prints per class
and format:

- worlds exported (a Crazyflie trajectory that cannot fit is refused, with what would fit) and
  worlds whose check passed (no deviation beyond its limit, no contact, no separation lost),
  also among the clean flights, whose flight itself had no contact and no near miss (never
  inside a separation ellipsoid: an export flies the flown path, so a contact or a lost
  separation there is the flight's);
- the worlds flown again with no contact and no separation lost (of all, and of the clean
  flights); the worlds with a contact in
  the check, with a separation lost, and with a vehicle farther from its export than the
  check's limit;
- Crazyflie: the largest deviation from the flown path over its bound, the most pieces, the
  largest speed and acceleration over their limits and the largest jump of the acceleration at
  a joint; PX4: the largest deviation of a mission from the flown path over its bound and the
  most waypoints.

A sample of the classes, not a timed test. Writes ``export.json`` (one record per world and
format) and ``export.md`` (the table) to ``--out``; ``--logs DIR`` keeps the flown logs (a
log already there is exported without flying its world again).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

from swarmplan.bench.random_worlds import CLASSES, sample_problems
from swarmplan.bench.reach import fly, world_of
from swarmplan.replay import load
from swarmplan.world.tracker_config import parse_tracker

from .files import build, run_check
from .source import ExportError, LimitError

ORIGIN = {"lat": 0.0, "lon": 0.0, "alt": 0.0}
"""Where the random worlds' missions are placed on the Earth."""


def formats_of(kind: str) -> tuple[str, ...]:
    """The flown samples (the flight itself flown again), Crazyflie trajectories for
    multirotors, missions for every class."""
    return ("csv", "px4") if kind == "fixed_wing" else ("csv", "crazyflie", "px4")


def export_world(raw: dict[str, Any], folder: Path) -> dict[str, Any]:
    """Fly one world into a log in ``folder``, export and check it in every format of its class."""
    log = folder / f"{raw['name']}.mcap"
    if not log.exists():
        fly(raw, log=log)
    rec = load(str(log))
    rec.world["origin"] = ORIGIN
    cfg, _ = parse_tracker(rec.world.get("tracker"), "tracker")
    kind = raw["name"].split("-")[1]
    out: dict[str, Any] = {
        "name": raw["name"],
        "agents": len(rec.agent_ids),
        "flight_contacts": sum(int(a.get("collisions", 0)) for a in (rec.summary or {}).get("agents", [])),
        "flight_near_misses": sum(
            int(a.get("near_misses", 0)) for a in (rec.summary or {}).get("agents", [])
        ),
    }
    for fmt in formats_of(kind):
        try:
            exp = build(rec, fmt)
        except (ExportError, LimitError) as exc:
            out[fmt] = {"refused": str(exc)}
            continue
        result = run_check(rec, exp, cfg)
        entry: dict[str, Any] = {
            "ok": result.ok,
            "contacts": len(result.contacts),
            "separation_entries": result.separation_entries,
            "separation_lost": result.separation_lost,
            "deviation_over_limit": max(a.max_deviation / a.limit for a in result.agents),
        }
        agents = exp.manifest["agents"]
        if fmt == "crazyflie":
            entry.update(
                deviation_over_bound=max(a["max_deviation_m"] / a["accuracy_m"] for a in agents),
                pieces=max(a["pieces"] for a in agents),
                speed_over_limit=max(a["max_speed"] / a["speed_limit"] for a in agents),
                accel_over_limit=max(a["max_accel"] / a["accel_limit"] for a in agents),
                accel_jump=max(a["joint_jumps"]["accel_m_s2"] for a in agents),
            )
        elif fmt == "px4":
            entry.update(
                deviation_over_bound=max(a["max_deviation_m"] / a["bound_m"] for a in agents),
                waypoints=max(a["waypoints"] for a in agents),
            )
        out[fmt] = entry
    return out


def table(kind: str, fmt: str, records: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures of one class and format."""
    done = [r[fmt] for r in records if fmt in r and "refused" not in r[fmt]]
    clean = [
        r[fmt]
        for r in records
        if fmt in r
        and "refused" not in r[fmt]
        and r["flight_contacts"] == 0
        and r.get("flight_near_misses", 0) == 0
    ]
    worst = lambda key: max((e[key] for e in done if key in e), default=None)  # noqa: E731
    return {
        "class": kind,
        "format": fmt,
        "worlds": len(records),
        "exported": len(done),
        "ok": sum(e["ok"] for e in done),
        "clean_flights": len(clean),
        "ok_of_clean": sum(e["ok"] for e in clean),
        "safe_of_clean": sum(e["contacts"] == 0 and e["separation_lost"] == 0 for e in clean),
        "safe": sum(e["contacts"] == 0 and e["separation_lost"] == 0 for e in done),
        "with_contact": sum(e["contacts"] > 0 for e in done),
        "separation_lost": sum(e["separation_lost"] > 0 for e in done),
        "deviation_broken": sum(e["deviation_over_limit"] > 1.0 for e in done),
        "deviation_over_bound": worst("deviation_over_bound"),
        "check_deviation_over_limit": worst("deviation_over_limit"),
        "pieces": worst("pieces"),
        "speed_over_limit": worst("speed_over_limit"),
        "accel_over_limit": worst("accel_over_limit"),
        "accel_jump": worst("accel_jump"),
        "waypoints": worst("waypoints"),
    }


def _f(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def markdown(tables: list[dict[str, Any]]) -> str:
    lines = [
        "| class | format | exported | check passed | passed, clean flights "
        "| no contact, separation kept | the same, clean flights | with contact "
        "| separation lost | check deviation broken | deviation / bound | check deviation / limit "
        "| pieces | speed / limit | accel / limit | accel jump m/s² | waypoints |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for t in tables:
        lines.append(
            f"| {t['class']} | {t['format']} | {t['exported']}/{t['worlds']} | {t['ok']}/{t['exported']} | "
            f"{t['ok_of_clean']}/{t['clean_flights']} | {t['safe']}/{t['exported']} | "
            f"{t['safe_of_clean']}/{t['clean_flights']} | {t['with_contact']} | "
            f"{t['separation_lost']} | "
            f"{t['deviation_broken']} | "
            f"{_f(t['deviation_over_bound'])} | {_f(t['check_deviation_over_limit'])} | {_f(t['pieces'])} | "
            f"{_f(t['speed_over_limit'])} | {_f(t['accel_over_limit'])} | {_f(t['accel_jump'], 5)} | "
            f"{_f(t['waypoints'])} |"
        )
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--worlds", type=int, default=10, help="worlds per class")
    parser.add_argument("--seed", type=int, default=0, help="seed of the worlds (as bench reach)")
    parser.add_argument("--class", dest="kind", default="lab", help="lab, field, fixed_wing or all")
    parser.add_argument("--out", default="logs/bench-export", help="folder of the tables")
    parser.add_argument("--logs", metavar="DIR", default=None,
                        help="keep the flown logs here (one already there is not flown again)")  # fmt: skip


def check_arguments(args: argparse.Namespace) -> list[str]:
    problems = sample_problems(args.worlds, args.seed, args.kind)
    for name, value in (("--out", args.out), ("--logs", args.logs)):
        if value is not None and Path(value).exists() and not Path(value).is_dir():
            problems.append(f"{name}: {value} is a file, expected a folder")
    return problems


def main(args: argparse.Namespace) -> int:
    kinds = list(CLASSES) if args.kind == "all" else [args.kind]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    records: dict[str, list[dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.logs) if args.logs else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for kind in kinds:
            records[kind] = []
            for k in range(args.worlds):
                rec = export_world(world_of(kind, args.seed, k), folder)
                records[kind].append(rec)
                parts = [
                    f"{fmt} "
                    + ("refused" if "refused" in rec[fmt] else "ok" if rec[fmt]["ok"] else "LIMIT BROKEN")
                    for fmt in formats_of(kind)
                ]
                print(f"{kind} {k}: {rec['agents']} agents, flight contacts {rec['flight_contacts']}; "
                      + ", ".join(parts), flush=True)  # fmt: skip
    tables = [table(kind, fmt, records[kind]) for kind in kinds for fmt in formats_of(kind)]
    text = markdown(tables)
    command = (
        f"python -m swarmplan.bench export --worlds {args.worlds} --seed {args.seed} --class {args.kind}"
    )
    (out / "export.md").write_text(f"# Exports of random worlds, checked\n\n`{command}`\n\n{text}\n")
    (out / "export.json").write_text(
        json.dumps({"command": command, "tables": tables, "worlds": records}, indent=1)
    )
    print(text)
    print(f"wrote {out / 'export.md'}, {out / 'export.json'}")
    return 0
