"""Whether every reachable goal is reached: random valid worlds of each class, flown to the end.

``python -m swarmplan.bench reach [--worlds N] [--seed S] [--class lab|field|fixed_wing|all]
[--out DIR] [--workers K] [--logs]`` draws ``N`` worlds per class from
:mod:`swarmplan.bench.random_worlds` (world ``k`` of a class from the generator seeded with
``(S, class, k)``: the first worlds are the same whatever ``N``), flies each with swarmplan's
default planner and its own seed, and prints per class:

- worlds with every agent home (an agent is home once it reached its goal tolerance);
- collisions (the simulation's own contacts with bodies, the ground, the bounds and agents) and
  the worlds that had any;
- limit breaks: agents whose flown path breaks their model (``curvature_violation`` of the run's
  summary: a multirotor's lateral acceleration over 1.05 ``max_accel``, a fixed wing's curvature
  over 1.05 / ``min_turn_radius``), with the worst ratio to the limit seen;
- the agents not home, by cause, read from the run's events and final state, first that applies:
  ``collision``; ``gave up`` (mode ``failed``); ``held`` (its last escape planning ended in a
  holding pattern); ``escape abandoned`` (its last escape segment was abandoned);
  ``short of goal`` (ended within a quarter of its straight line from the goal: it stopped or
  hovered near it); ``stuck`` (found stuck on the way); ``timeout`` (still on its way);
- the agents not home by what their events last said held them (``held_by``: the ground, the
  bounds, a body, an agent, or none within the field's reach);
- the median, over the agents home, of the flown path over the straight line and of the arrival
  time over the straight line's time at cruise speed.

Writes ``reach.md`` (the tables) and ``reach.json`` (one record per world, with every agent not
home: its cause, final distance to the goal, the goal's height and what held it; with every agent
that collided, arrived or not: what it struck) to ``--out``, and every world
that did not get every agent home without collision or limit break as
``failures/<name>.yaml`` there, a world file ``python -m swarmplan.run`` flies again (its own
seed inside); ``--logs`` also records those runs' MCAP logs beside them.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.bench.random_worlds import CLASSES, random_world, sample_problems

CAUSES = ("collision", "gave up", "held", "escape abandoned", "short of goal", "stuck", "timeout")
"""Why an agent is not home, in the order they are tested."""


def world_of(kind: str, seed: int, k: int) -> dict[str, Any]:
    """World ``k`` of class ``kind`` for the bench's ``seed``: a world mapping, its own seed ``k``."""
    rng = np.random.default_rng([seed, CLASSES.index(kind), k])
    raw = random_world(kind, rng, name=f"reach-{kind}-{seed}-{k}")
    raw["seed"] = k
    return raw


class _Events:
    """The events of a run, per agent id."""

    def __init__(self) -> None:
        self.by_agent: dict[str, list[Any]] = {}

    def _add(self, events: Any) -> None:
        for e in events:
            if getattr(e, "kind", None) is not None and e.agent is not None:
                self.by_agent.setdefault(e.agent, []).append(e)

    def on_reset(self, result: Any) -> None:
        self._add(result.records)

    def on_step(self, result: Any) -> None:
        self._add(result.events)


def cause_of(agent: dict[str, Any], events: list[Any], distance: float) -> str:
    """Why an agent of a run's summary is not home (see :data:`CAUSES`)."""
    if agent["collisions"] > 0 or agent["final_mode"] == "collided":
        return "collision"
    if agent["final_mode"] == "failed":
        return "gave up"
    planning = [e for e in events if e.kind in ("hold", "escape_start", "escape_end", "escape_deferred")]
    if planning and planning[-1].kind == "hold":
        return "held"
    ends = [e for e in events if e.kind == "escape_end"]
    if ends and ends[-1].detail.get("abandoned"):
        return "escape abandoned"
    if distance <= 0.25 * agent["straight_line"]:
        return "short of goal"
    if agent["stuck_events"] > 0:
        return "stuck"
    return "timeout"


def fly(raw: dict[str, Any], log: Path | None = None) -> dict[str, Any]:
    """Fly one world mapping with the default planner and its own seed; one record of the run."""
    from swarmplan.io.runner import run_episode
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    world = parse_world(raw)
    sim = Simulation(world)
    events = _Events()
    clock = time.perf_counter()
    recorder = None
    if log is not None:
        from swarmplan.io.recording import McapRecorder

        recorder = McapRecorder(log)
    summary = run_episode(sim, world.seed, observers=[events], recorder=recorder)
    wall = time.perf_counter() - clock
    goal = np.array([a.goal for a in world.agents])
    distance = np.linalg.norm(sim.state.position - goal, axis=1)
    agents = []
    for i, (a, spec) in enumerate(zip(summary["agents"], world.agents, strict=True)):
        cruise = spec.speed_cruise
        straight = a["straight_line"]
        if spec.model == "fixed_wing":
            limit_ratio = a["max_curvature"] / a["curvature_limit"]
        else:
            limit_ratio = a["max_lateral_accel"] / a["lateral_accel_limit"]
        rec = {
            "id": a["id"],
            "home": a["arrived"],
            "collisions": a["collisions"],
            "limit_break": a["curvature_violation"],
            "limit_ratio": round(float(limit_ratio), 4),
            "path_ratio": a["length_ratio"] if a["arrived"] else None,
            "time_ratio": round(a["arrival_time"] / (straight / cruise), 4) if a["arrived"] else None,
        }
        if a["collisions"]:  # also an arrived agent struck where it waits
            rec["collided_with"] = a["collided_with"]
        if not a["arrived"]:
            mine = events.by_agent.get(a["id"], [])
            held = [e.detail["held_by"] for e in mine if isinstance(e.detail.get("held_by"), dict)]
            rec.update(
                cause=cause_of(a, mine, float(distance[i])),
                held_by=held[-1] if held else None,
                distance_to_goal=round(float(distance[i]), 4),
                goal_height=round(float(spec.goal[2]), 4),
                radius=spec.radius,
                stuck_events=a["stuck_events"],
                escapes=a["escapes"],
            )
        agents.append(rec)
    return {
        "name": world.name,
        "agents": agents,
        "bodies": len(world.obstacles),
        "movers": sum(o.moving for o in world.obstacles),
        "goal_tolerance": world.goal_tolerance,
        "sim_time": summary["sim_time"],
        "wall": round(wall, 3),
    }


def passed(record: dict[str, Any]) -> bool:
    """Every agent home, no collision, no limit break."""
    return all(a["home"] and a["collisions"] == 0 and not a["limit_break"] for a in record["agents"])


def _task(args: tuple[str, int, int]) -> tuple[str, int, dict[str, Any]]:
    kind, seed, k = args
    return kind, k, fly(world_of(kind, seed, k))


def class_table(kind: str, records: list[dict[str, Any]]) -> dict[str, Any]:
    """The per-class figures of a list of world records."""
    agents = [a for r in records for a in r["agents"]]
    causes = {c: sum(a.get("cause") == c for a in agents) for c in CAUSES}
    path = [a["path_ratio"] for a in agents if a["path_ratio"] is not None]
    times = [a["time_ratio"] for a in agents if a["time_ratio"] is not None]
    return {
        "class": kind,
        "worlds": len(records),
        "all_home": sum(all(a["home"] for a in r["agents"]) for r in records),
        "agents": len(agents),
        "home": sum(a["home"] for a in agents),
        "collisions": sum(a["collisions"] for a in agents),
        "worlds_with_collision": sum(any(a["collisions"] for a in r["agents"]) for r in records),
        "limit_breaks": sum(a["limit_break"] for a in agents),
        "worst_limit_ratio": max((a["limit_ratio"] for a in agents), default=0.0),
        "causes": causes,
        "held_by": _held_counts(agents),
        "median_path_ratio": float(np.median(path)) if path else None,
        "median_time_ratio": float(np.median(times)) if times else None,
        "passed": sum(passed(r) for r in records),
    }


def _held_counts(agents: list[dict[str, Any]]) -> dict[str, int]:
    """Agents not home by what their events last said held them (``held_by.by``; ``unsaid``
    when no event of theirs said)."""
    out: dict[str, int] = {}
    for a in agents:
        if not a["home"]:
            by = (a.get("held_by") or {}).get("by", "unsaid")
            out[by] = out.get(by, 0) + 1
    return dict(sorted(out.items()))


def _fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def markdown(tables: list[dict[str, Any]]) -> str:
    """The tables: one line per class, then the agents not home by cause."""
    lines = [
        "| class | worlds | every agent home | agents home | collisions (worlds) | limit breaks "
        "| worst turn/accel over limit | median path / straight | median time / straight |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in tables:
        lines.append(
            f"| {t['class']} | {t['worlds']} | {t['all_home']}/{t['worlds']} | {t['home']}/{t['agents']} | "
            f"{t['collisions']} ({t['worlds_with_collision']}) | {t['limit_breaks']} | "
            f"{_fmt(t['worst_limit_ratio'])} | {_fmt(t['median_path_ratio'], 3)} | "
            f"{_fmt(t['median_time_ratio'], 3)} |"
        )
    lines += ["", "Agents not home, by cause:", "", "| class | " + " | ".join(CAUSES) + " |",
              "|---|" + "---|" * len(CAUSES)]  # fmt: skip
    for t in tables:
        lines.append(f"| {t['class']} | " + " | ".join(str(t["causes"][c]) for c in CAUSES) + " |")
    lines += ["", "Agents not home, by what their events last said held them (`held_by`):", ""]
    for t in tables:
        held = ", ".join(f"{by} {n}" for by, n in t["held_by"].items()) or "none"
        lines.append(f"- {t['class']}: {held}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--worlds", type=int, default=30, help="worlds per class")
    parser.add_argument("--seed", type=int, default=0, help="seed of the worlds")
    parser.add_argument("--class", dest="kind", default="all", help="lab, field, fixed_wing or all")
    parser.add_argument(
        "--out", default="logs/bench-reach", help="folder of the tables and the failing worlds"
    )
    parser.add_argument("--workers", type=int, default=1, help="worlds flown at once (processes)")
    parser.add_argument("--logs", action="store_true", help="record the failing worlds' MCAP logs too")


def check_arguments(args: argparse.Namespace) -> list[str]:
    problems = sample_problems(args.worlds, args.seed, args.kind)
    if args.workers < 1:
        problems.append(f"--workers: must be >= 1, got {args.workers}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        problems.append(f"--out: {out} is a file, expected a folder")
    return problems


def main(args: argparse.Namespace) -> int:
    import yaml

    kinds = list(CLASSES) if args.kind == "all" else [args.kind]
    tasks = [(kind, args.seed, k) for kind in kinds for k in range(args.worlds)]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, dict[int, dict[str, Any]]] = {kind: {} for kind in kinds}
    failures = out / "failures"
    for kind in kinds:  # the failing worlds of an earlier run of these classes go
        for old in failures.glob(f"reach-{kind}-*"):
            old.unlink()

    def show(kind: str, k: int, rec: dict[str, Any]) -> None:
        home = sum(a["home"] for a in rec["agents"])
        causes = sorted({a["cause"] for a in rec["agents"] if not a["home"]})
        print(
            f"{kind} {k}: {home}/{len(rec['agents'])} home, {sum(a['collisions'] for a in rec['agents'])} "
            f"collisions, {sum(a['limit_break'] for a in rec['agents'])} limit breaks, "
            f"{rec['sim_time']:.1f} sim-s in {rec['wall']:.1f} s"
            + (f" ({', '.join(causes)})" if causes else ""),
            flush=True,
        )

    if args.workers > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
            for kind, k, rec in pool.imap_unordered(_task, tasks):
                results[kind][k] = rec
                show(kind, k, rec)
    else:
        for task in tasks:
            kind, k, rec = _task(task)
            results[kind][k] = rec
            show(kind, k, rec)
    tables = []
    for kind in kinds:
        records = [results[kind][k] for k in range(args.worlds)]
        tables.append(class_table(kind, records))
        for k, rec in enumerate(records):
            if passed(rec):
                continue
            failures.mkdir(exist_ok=True)
            raw = world_of(kind, args.seed, k)
            path = failures / f"{raw['name']}.yaml"
            path.write_text(yaml.safe_dump(raw, sort_keys=False, default_flow_style=None))
            if args.logs:
                fly(raw, log=failures / f"{raw['name']}.mcap")
    table = markdown(tables)
    command = f"python -m swarmplan.bench reach --worlds {args.worlds} --seed {args.seed} --class {args.kind}"
    (out / "reach.md").write_text(f"# Every reachable goal: random worlds\n\n`{command}`\n\n{table}\n")
    (out / "reach.json").write_text(
        json.dumps({"command": command, "tables": tables, "worlds": results}, indent=1) + "\n"
    )
    print(table)
    print(
        f"wrote {out / 'reach.md'}, {out / 'reach.json'}" + (f" and {failures}/" if failures.exists() else "")
    )
    return 0
