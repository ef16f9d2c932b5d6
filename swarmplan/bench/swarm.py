"""Dense swarms on the field's standard scenarios, side by side with ORCA-3D.

``python -m swarmplan.bench swarm [--sizes 16,64,256,512] [--seeds K] [--peers orca] [--out DIR]
[--quick] [--docs DIR]`` flies every scenario of :mod:`swarmplan.bench.swarm_scenarios` (sphere,
circle, crossing, doorway (up to 64 agents), sphere_pillars, forest) at every size and seed with
swarmplan's default planner and with pure APF (``--optimizer none``), and, with ``--peers orca``,
ORCA-3D (RVO2-3D through the ``jt-pyrvo23d`` package: ``pip install -e '.[orca]'``) on the
obstacle-free ones with the same radius, speeds and dt and the preferred velocity towards the goal
(an agent stops within the goal tolerance, as swarmplan's do).

Per scenario x size x system (means over the seeds, with the worst seed where it matters):
arrived/N; collisions: pairs of agents whose centres came closer than the sum of their radii,
measured the same way for every system from the positions of consecutive steps (swept between
them); minimum separation (surface to surface); mean path length over the straight line; time of
the last arrival; real-time factor of the stepping loop (simulated over wall seconds, start-up and
the first step excluded; the same work for every system: each one's step and stopping rule, not the
benchmark's measurements), and swarmplan's with the writing of its MCAP log (a peer writes none);
escapes. Each run's horizon is three times the longest straight-line flight at cruise speed plus 30 s.

Writes ``swarm.csv`` (one row per run), ``swarm-benchmarks.md`` with the table and one picture
per scenario (``swarm-<scenario>.png``, flown paths) to ``--out``; with ``--docs DIR`` the page and
its pictures go to DIR instead (``--docs docs`` rewrites the shipped docs/swarm-benchmarks.md).
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import math
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from swarmplan.bench.swarm_report import Row
from swarmplan.bench.swarm_runs import ContactMeter, run_swarmplan, straight_lengths
from swarmplan.bench.swarm_scenarios import (
    LAB_SCENARIOS,
    MAX_AGENTS,
    OBSTACLE_FREE,
    SCENARIOS,
    scenario_world,
)
from swarmplan.runtime.compiled import COMPILED_FROM

SYSTEMS = ("planner", "apf", "orca")


def run_orca(name: str, agents: int, seed: int, separation: float | None = None) -> Row:
    """One run of ORCA-3D on the same world: radius, maximum speed and dt of the agents, the
    preferred velocity towards the goal at cruise speed (slowed to stop on it), an agent stops
    for good within the goal tolerance. Neighbours as RVO2-3D's sphere example (15 m, 10, 10 s).
    With ``separation`` (m), ORCA's radius is the agents' plus half of it (ORCA keeps centres
    two of its radii apart: the bodies that far apart); contacts are counted on the bodies."""
    import rvo23d

    world = scenario_world(name, agents, seed)
    a0 = world.agents[0]
    kept = a0.radius + (0.0 if separation is None else 0.5 * separation)
    sim = rvo23d.PyRVOSimulator(world.dt, 15.0, 10, 10.0, kept, a0.speed_max)
    start = np.array([a.start for a in world.agents], dtype=float)
    goal = np.array([a.goal for a in world.agents], dtype=float)
    for p in start:
        sim.addAgent(tuple(float(v) for v in p))
    n = len(start)
    pos = start.copy()
    arrival = np.full(n, np.nan)
    path = np.zeros(n)
    meter = ContactMeter(np.full(n, a0.radius))
    cruise, amax, tol = a0.speed_cruise, a0.max_accel, world.goal_tolerance
    t, wall, steps = 0.0, 0.0, 0
    while t < world.max_time - 1e-9 and np.isnan(arrival).any():
        clock = time.perf_counter()
        e = goal - pos
        d = np.linalg.norm(e, axis=1)
        speed = np.minimum(cruise, np.sqrt(2.0 * amax * d))
        pref = np.where(np.isnan(arrival)[:, None], e / np.maximum(d, 1e-9)[:, None] * speed[:, None], 0.0)
        for i in range(n):
            sim.setAgentPrefVelocity(i, (float(pref[i, 0]), float(pref[i, 1]), float(pref[i, 2])))
        sim.doStep()
        new = np.array([sim.getAgentPosition(i) for i in range(n)], dtype=float)
        done = np.isnan(arrival) & (np.linalg.norm(goal - new, axis=1) <= tol)  # its stopping rule
        steps += 1
        if steps > 1:
            wall += time.perf_counter() - clock
        t = steps * world.dt
        meter.update(pos, new)
        path += np.where(np.isnan(arrival), np.linalg.norm(new - pos, axis=1), 0.0)
        pos = new
        arrival[done] = t
    arrived = np.isfinite(arrival)
    straight = straight_lengths(world)
    ratio = float(np.mean(path[arrived] / np.maximum(straight[arrived], 1e-9))) if arrived.any() else math.nan
    last = float(np.nanmax(arrival)) if arrived.any() else math.nan
    rtf = (t - world.dt) / wall if wall > 0 else math.nan
    return Row(name, agents, "orca", seed, int(arrived.sum()), len(meter.pairs), meter.min_gap, ratio, last,
               t, wall, rtf, 0)  # fmt: skip


def _parse_sizes(text: str) -> list[int] | None:
    try:
        sizes = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        return None
    return sizes if sizes and all(s >= 2 for s in sizes) else None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sizes",
        default=None,
        help="swarm sizes, comma-separated (each >= 2; default 16,64,256,512, with --delays 64)",
    )
    parser.add_argument("--seeds", type=int, default=3, help="seeds per scenario and size")
    parser.add_argument(
        "--scenarios",
        default=",".join(SCENARIOS),
        help="scenarios, comma-separated; 'lab' (or lab scenario names: "
        + ", ".join(LAB_SCENARIOS)
        + ") flies the literature's lab scenarios at their own sizes, beside their published "
        "figures, into --out only",
    )
    parser.add_argument("--peers", default="", help="peer systems to fly beside swarmplan: orca")
    parser.add_argument(
        "--out",
        default="logs/bench-swarm",
        help="folder of the CSV (one row per run), the page and its pictures",
    )
    parser.add_argument("--quick", action="store_true", help="16 agents, one seed (a smoke test)")
    parser.add_argument(
        "--delays",
        help="communication delays in s, comma-separated: fly RMADER's circle and the sphere on what each "
        "agent hears (the world's comms), beside the published figures, instead of the scenarios",
    )
    parser.add_argument(
        "--loss", default="0", help="with --delays: message losses, comma-separated, each in [0, 1)"
    )
    parser.add_argument(
        "--rate", type=float, default=20.0, help="with --delays: broadcasts per agent and second"
    )
    parser.add_argument(
        "--separation",
        type=float,
        help="the separation every agent keeps from the others, m, in place of the scenarios' 1 m "
        "(ORCA-3D: its radius is the agents' plus half of it); the page goes to --out only",
    )
    parser.add_argument(
        "--docs",
        metavar="DIR",
        help="write swarm-benchmarks.md and its pictures to DIR instead of --out (docs: the shipped page)",
    )


def _parse_numbers(text: str | None, lo: float, hi: float) -> list[float] | None:
    try:
        values = [float(v) for v in (text or "").split(",") if v.strip()]
    except ValueError:
        return None
    return values if values and all(lo <= v < hi for v in values) else None


def check_arguments(args: argparse.Namespace) -> list[str]:
    problems = []
    if args.sizes is None:
        args.sizes = "64" if args.delays is not None else "16,64,256,512"
    if args.delays is not None:
        if _parse_numbers(args.delays, 0.0, math.inf) is None:
            problems.append(f"--delays: expected numbers >= 0 (s) separated by commas, got {args.delays!r}")
        if _parse_numbers(args.loss, 0.0, 1.0) is None:
            problems.append(f"--loss: expected numbers in [0, 1) separated by commas, got {args.loss!r}")
        if not (args.rate > 0 and math.isfinite(args.rate)):
            problems.append(f"--rate: must be > 0, got {args.rate:g}")
    if _parse_sizes(args.sizes) is None:
        problems.append(f"--sizes: expected whole numbers >= 2 separated by commas, got {args.sizes!r}")
    if args.seeds < 1:
        problems.append(f"--seeds: must be >= 1, got {args.seeds}")
    named = args.scenarios.split(",")
    unknown = [s for s in named if s not in SCENARIOS and s not in LAB_SCENARIOS and s != "lab"]
    if unknown:
        known = ", ".join([*SCENARIOS, "lab", *LAB_SCENARIOS])
        problems.append(f"--scenarios: unknown {', '.join(unknown)} (known: {known})")
    peers = [p for p in args.peers.split(",") if p]
    if any(p != "orca" for p in peers):
        problems.append(f"--peers: only 'orca' is known, got {args.peers!r}")
    elif peers and importlib.util.find_spec("rvo23d") is None:
        problems.append("--peers orca: ORCA-3D is not installed (pip install -e '.[orca]')")
    if args.separation is not None:
        if not (args.separation >= 0 and math.isfinite(args.separation)):
            problems.append(f"--separation: must be a number >= 0 (m), got {args.separation:g}")
        if args.docs is not None or args.delays is not None:
            problems.append("--separation: flies the scenarios into --out only (not with --docs or --delays)")
    for flag in ("out", "docs"):
        if getattr(args, flag) is None:
            continue
        path = Path(getattr(args, flag))
        if path.exists() and not path.is_dir():
            problems.append(f"--{flag}: {path} is a file, expected a folder")
    return problems


def main(args: argparse.Namespace) -> int:
    sizes = [16] if args.quick else _parse_sizes(args.sizes)
    seeds = 1 if args.quick else args.seeds
    chosen = [n for s in args.scenarios.split(",") for n in (LAB_SCENARIOS if s == "lab" else [s])]
    scenarios = [n for n in dict.fromkeys(chosen) if n in SCENARIOS]
    lab = [n for n in dict.fromkeys(chosen) if n in LAB_SCENARIOS]
    orca = "orca" in args.peers.split(",")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.delays is not None:
        from swarmplan.bench.swarm_comms import run_comms

        delays, losses = _parse_numbers(args.delays, 0.0, math.inf), _parse_numbers(args.loss, 0.0, 1.0)
        run_comms(sizes, seeds, delays, losses, args.rate, out, args.docs)
        return 0
    if lab:
        from swarmplan.bench.swarm_lab import run_lab

        run_lab(lab, seeds, out)
    if not scenarios:
        return 0
    # Start-up out of the figures: every compiled kernel a run may call (field, checks, escape
    # and smoothing costs, movers) loaded once, by runs whose rows are not kept, at the swarm
    # size from which the step's geometry runs compiled (smaller worlds never load it: where
    # every size flown is smaller, at the largest of them).
    for warm in ("sphere_pillars", "forest"):
        run_swarmplan(warm, min(COMPILED_FROM, max(sizes)), 0, "planner")
    rows: list[Row] = []
    pictures: dict[str, tuple[int, np.ndarray]] = {}
    print(
        "scenario agents system seed: arrived collisions min_sep path_ratio last_arrival rtf escapes",
        flush=True,
    )
    for name in scenarios:
        for n in sizes:
            if n > MAX_AGENTS.get(name, n):
                continue
            for seed in range(seeds):
                systems = ["planner", "apf"] + (["orca"] if orca and name in OBSTACLE_FREE else [])
                for system in systems:
                    if system == "orca":
                        row = run_orca(name, n, seed, args.separation)
                    else:
                        keep = system == "planner" and seed == 0 and n == min(max(sizes), 64)
                        row, paths = run_swarmplan(
                            name, n, seed, system, keep_paths=keep, separation=args.separation
                        )
                        if keep:
                            pictures[name] = (n, paths)
                    rows.append(row)
                    print(
                        f"{name} {n} {system} {seed}: {row.arrived}/{n} {row.collisions} "
                        f"{row.min_separation:.2f} {row.path_ratio:.3f} {row.last_arrival:.1f} "
                        f"{row.rtf:.1f} {row.escapes}",
                        flush=True,
                    )
    with open(out / "swarm.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        w.writeheader()
        for r in rows:
            w.writerow(asdict(r))
    table = summary_table(rows)
    verdicts = done_verdicts(rows)
    print(table)
    print("\n".join(verdicts))
    from swarmplan.bench.swarm_report import write_docs

    page = out if args.docs is None else Path(args.docs)
    write_docs(page, rows, table, verdicts, pictures, sizes, seeds, orca, args.docs, args.separation)
    print(f"wrote {out / 'swarm.csv'} and {page / 'swarm-benchmarks.md'}")
    return 0


def _groups(rows: list[Row]) -> dict[tuple[str, int, str], list[Row]]:
    out: dict[tuple[str, int, str], list[Row]] = {}
    for r in rows:
        out.setdefault((r.scenario, r.agents, r.system), []).append(r)
    return out


def summary_table(rows: list[Row]) -> str:
    """Markdown table: one line per scenario x size x system, over its seeds."""
    lines = [
        "| scenario | N | system | arrived | collisions | min sep (m) | path / straight "
        "| last arrival (s) | real-time factor | with its log | escapes |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (name, n, system), g in _groups(rows).items():
        arrived = sum(r.arrived for r in g)
        last = [r.last_arrival for r in g if math.isfinite(r.last_arrival)]
        ratios = [r.path_ratio for r in g if math.isfinite(r.path_ratio)]
        # Path over straight line and the last arrival exist only where someone arrived.
        ratio_text = f"{np.mean(ratios):.3f}" if ratios else "none arrived"
        last_text = f"{max(last):.1f}" if last else "none arrived"
        lines.append(
            f"| {name} | {n} | {system} | {arrived}/{n * len(g)} | {sum(r.collisions for r in g)} | "
            f"{min(r.min_separation for r in g):.2f} | {ratio_text} | "
            f"{last_text} | {np.mean([r.rtf for r in g]):.1f} | {_logged_text(g)} | "
            f"{sum(r.escapes for r in g)} |"
        )
    return "\n".join(lines)


def _logged_text(rows: list[Row]) -> str:
    """The mean real-time factor with the log's writing, or '-' for a system that writes none."""
    logged = [r.rtf_logged for r in rows]
    return f"{np.mean(logged):.1f}" if all(math.isfinite(v) for v in logged) else "-"


def done_verdicts(rows: list[Row]) -> list[str]:
    """The benchmark's targets, each with its figure and met / NOT met."""
    g = _groups(rows)
    out = []
    ours = [r for r in rows if r.system != "orca"]
    home = sum(r.arrived for r in ours)
    total = sum(r.agents for r in ours)
    contacts = sum(r.collisions for r in ours)
    ok = home == total and contacts == 0
    out.append(
        f"- every agent home, no contact (planner and pure APF): {home}/{total}, {contacts} pairs: "
        f"{'met' if ok else 'NOT met'}"
    )
    slow = []
    for (name, n, system), rs in g.items():
        if system != "planner" or (name, n, "apf") not in g:
            continue
        ratio = np.mean([r.rtf for r in rs]) / np.mean([r.rtf for r in g[(name, n, "apf")]])
        if ratio < 0.5:
            slow.append(f"{name}/{n} {ratio:.2f}")
    out.append("- default planner >= 0.5x pure APF's real-time factor everywhere: "
               + ("met" if not slow else "NOT met (" + ", ".join(slow) + ")"))  # fmt: skip
    for n, check_last in ((64, True), (512, False)):
        key_a, key_o = ("sphere", n, "apf"), ("sphere", n, "orca")
        if key_a not in g or key_o not in g:
            continue
        rtf_a = np.mean([r.rtf for r in g[key_a]])
        rtf_o = np.mean([r.rtf for r in g[key_o]])
        out.append(f"- sphere {n}: pure APF real-time factor {rtf_a:.1f} vs ORCA {rtf_o:.1f}: "
                   f"{'met' if rtf_a >= rtf_o else 'NOT met'} "
                   f"(with its log: {_logged_text(g[key_a])})")  # fmt: skip
        if check_last:
            la = max(r.last_arrival for r in g[key_a])
            lo = max(r.last_arrival for r in g[key_o])
            verdict = "met" if la <= 1.5 * lo else "NOT met"
            out.append(f"- sphere {n}: last arrival {la:.1f} s vs ORCA's {lo:.1f} s "
                       f"(at most 1.5x: {1.5 * lo:.1f} s): {verdict}")  # fmt: skip
            ratio = np.mean([r.path_ratio for r in g[key_a]])
            out.append(f"- sphere {n}: pure APF's mean path {ratio:.3f} x the straight line <= 1.25: "
                       f"{'met' if ratio <= 1.25 else 'NOT met'}")  # fmt: skip
    return out
