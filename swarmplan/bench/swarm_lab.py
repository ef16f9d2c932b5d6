"""The literature's lab scenarios of ``bench swarm`` (``--scenarios lab``), beside their published
figures.

Each scenario of :data:`~swarmplan.bench.swarm_scenarios.LAB_SCENARIOS` is flown at its sizes
(:data:`~swarmplan.bench.swarm_scenarios.LAB_SIZES`) and seeds with swarmplan's default planner and
with pure APF, contacts measured as for the standard scenarios. Per scenario x size x system:
arrived; collision-free runs (%); contact pairs; minimum surface separation; the mean arrival
time over the agents home and the time every agent was home (the last arrival; "travel time"),
means over the seeds; escapes. The published figures of a scenario family (RMADER's circle,
mit-acl/rmader, 10 agents, no communication delay: collision-free runs and mean travel time)
follow its table. Writes ``swarm-lab.csv`` (one row per run) and ``swarm-lab.md`` to the output
folder, never to the docs.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from swarmplan.bench.swarm_report import Row
from swarmplan.bench.swarm_runs import run_swarmplan
from swarmplan.bench.swarm_scenarios import LAB_SIZES, PUBLISHED

TRAVEL_TARGET = 5.0
"""s: the 10-agent circle's travel time to beat (ahead of EGO-Swarm's 5.64 s, at 100 % safety)."""


def _family(name: str) -> str:
    return "rmader_circle" if name.startswith("rmader_circle") else name


def _mean(xs: list[float]) -> float:
    xs = [x for x in xs if math.isfinite(x)]
    return float(np.mean(xs)) if xs else math.nan


def _t(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}" if math.isfinite(x) else "none arrived"


def lab_table(rows: list[Row]) -> str:
    """Markdown: one line per scenario x size x system, then the published figures of each
    scenario family flown."""
    groups: dict[tuple[str, int, str], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.scenario, r.agents, r.system), []).append(r)
    lines = [
        "| scenario | N | system | arrived | collision-free runs | contact pairs | min sep (m) "
        "| mean arrival (s) | travel time: last arrival (s) | escapes |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (name, n, system), g in groups.items():
        free = 100.0 * sum(r.collisions == 0 for r in g) / len(g)
        lines.append(
            f"| {name} | {n} | {system} | {sum(r.arrived for r in g)}/{n * len(g)} | {free:.0f} % | "
            f"{sum(r.collisions for r in g)} | {min(r.min_separation for r in g):.2f} | "
            f"{_t(_mean([r.mean_arrival for r in g]))} | {_t(_mean([r.last_arrival for r in g]))} | "
            f"{sum(r.escapes for r in g)} |"
        )
    flown = {(_family(r.scenario), r.agents) for r in rows}
    for key, (source, figures) in PUBLISHED.items():
        if key not in flown:
            continue
        lines += ["", f"Published, {key[0]} with {key[1]} agents ({source}):", "",
                  "| system | collision-free runs | mean travel time (s) |", "|---|---|---|"]  # fmt: skip
        lines += [f"| {system} | {free:g} % | {travel:.2f} |" for system, free, travel in figures]
    return "\n".join(lines)


def lab_verdicts(rows: list[Row]) -> list[str]:
    """The lab rows' targets, each with its figure and met / NOT met."""
    home = sum(r.arrived for r in rows)
    total = sum(r.agents for r in rows)
    contacts = sum(r.collisions for r in rows)
    ok = home == total and contacts == 0
    out = [f"- every agent home, no contact, at every altitude and size: {home}/{total}, {contacts} pairs: "
           f"{'met' if ok else 'NOT met'}"]  # fmt: skip
    for name in dict.fromkeys(r.scenario for r in rows):
        if _family(name) != "rmader_circle":
            continue
        g = [r for r in rows if r.scenario == name and r.agents == 10 and r.system == "planner"]
        if not g:
            continue
        travel = _mean([r.last_arrival for r in g]) if all(r.arrived == r.agents for r in g) else math.nan
        met = math.isfinite(travel) and travel <= TRAVEL_TARGET
        out.append(f"- {name}, 10 agents, default planner: travel time {_t(travel)} s "
                   f"<= {TRAVEL_TARGET:g} s: {'met' if met else 'NOT met'}")  # fmt: skip
    return out


def run_lab(names: list[str], seeds: int, out: Path) -> list[Row]:
    """Fly the lab scenarios ``names`` at their sizes over ``seeds`` seeds (default planner and
    pure APF); print and write the table to ``out``."""
    rows: list[Row] = []
    print(
        "scenario agents system seed: arrived collisions min_sep mean_arrival last_arrival escapes",
        flush=True,
    )
    for name in names:
        for n in LAB_SIZES[name]:
            for seed in range(seeds):
                for system in ("planner", "apf"):
                    row, _ = run_swarmplan(name, n, seed, system)
                    rows.append(row)
                    print(
                        f"{name} {n} {system} {seed}: {row.arrived}/{n} {row.collisions} "
                        f"{row.min_separation:.2f} {row.mean_arrival:.2f} {row.last_arrival:.2f} "
                        f"{row.escapes}",
                        flush=True,
                    )
    with open(out / "swarm-lab.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        w.writeheader()
        for r in rows:
            w.writerow(asdict(r))
    table = lab_table(rows)
    verdicts = lab_verdicts(rows)
    command = f"python -m swarmplan.bench swarm --scenarios {','.join(names)} --seeds {seeds}"
    text = "\n".join(["# The literature's lab scenarios", "", f"`{command}`", "", table, "", "Targets:", "",
                      *verdicts, ""])  # fmt: skip
    (out / "swarm-lab.md").write_text(text)
    print(table)
    print("\n".join(verdicts))
    print(f"wrote {out / 'swarm-lab.csv'} and {out / 'swarm-lab.md'}")
    return rows
