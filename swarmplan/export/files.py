"""An export from a run log: every file of one format for the chosen agents, a manifest, and
(``--check``) the check of the exports flown again. Nothing is written here: :func:`build`
returns the files' texts, :func:`write` puts them in place all at once."""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.replay import Recording
from swarmplan.replay.geometry import terrain_height
from swarmplan.track.crazyflie import Crazyflie
from swarmplan.track.fixed_wing import aircraft_of, error_limit
from swarmplan.world.tracker_config import TrackerConfig

from . import clearance, crazyflie, mission
from .check import CheckResult, Plan, check
from .source import ExportError, FlownPath, check_log, flown_path, select_agents, tolerance_of

FORMATS = ("crazyflie", "px4", "csv")
FRAME = "world frame: x east, y north, z up (right-handed), metres; times in seconds from the run's t = 0"


@dataclass
class Export:
    files: dict[str, str]  # file name -> text
    manifest: dict[str, Any]
    plans: list[Plan]
    lines: list[str] = field(default_factory=list)  # what the export reports per agent
    checked: CheckResult | None = None


def file_stem(agent_id: str, taken: set[str]) -> str:
    """A file name for an agent id (characters outside [A-Za-z0-9_.-] become '_'), unique."""
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", agent_id).strip(".") or "agent"
    base, k = stem, 2
    while stem.lower() in taken:
        stem, k = f"{base}_{k}", k + 1
    taken.add(stem.lower())
    return stem


FIXED_WING_WAYPOINT_SHARE = 1.0 / 8.0
"""A fixed wing's waypoints lie within this share of its tracking bound e = max(5 m, 0.05 R_min)
of its flown path. On a turn of radius R the reduction's chords are then at most
c = sqrt(8 R e / 8) = sqrt(R e) long, and each waypoint turns the polyline by c / R: an aircraft
that can turn no tighter than R and starts its turn only at the waypoint leaves the polyline by
about c^2 / (2 R) = e / 2, so it flies every turn within its bound (with half the bound for the
chords, sqrt(4 R e) long, it leaves them by about 2 e)."""


def _mission_bound(rec: Recording, path: FlownPath, max_deviation: float | None) -> float:
    """How far the waypoints may reduce the flown path: the goal tolerance or ``max_deviation``;
    for a fixed wing also at most ``FIXED_WING_WAYPOINT_SHARE`` of its tracking bound
    max(5 m, 0.05 R_min), so that it can fly the polyline's corners within that bound."""
    bound = tolerance_of(rec.world)
    if max_deviation is not None:
        bound = min(bound, max_deviation)
    if path.limits.model == "fixed_wing":
        bound = min(bound, FIXED_WING_WAYPOINT_SHARE * error_limit(aircraft_of(rec.world, path.limits.id)))
    return bound


def build(
    rec: Recording, fmt: str, agents: list[str] | None = None, max_deviation: float | None = None
) -> Export:
    """Every file of format ``fmt`` for ``agents`` (default: all). Raises
    :class:`~swarmplan.export.source.ExportError` for a log or request it cannot serve and
    :class:`~swarmplan.export.source.LimitError` for a path that cannot be exported as asked."""
    if fmt not in FORMATS:
        raise ExportError(f"--format {fmt}: unknown format (one of {', '.join(FORMATS)})")
    check_log(rec)
    ids = select_agents(rec, agents)
    origin = mission.origin_of(rec.world) if fmt == "px4" else rec.world.get("origin")
    paths = [flown_path(rec, aid) for aid in ids]
    files: dict[str, str] = {}
    entries: list[dict[str, Any]] = []
    plans: list[Plan] = []
    lines: list[str] = []
    taken: set[str] = {"manifest", "check"}
    # The swarm's Crazyflie trajectories start together: from the longest lead of them.
    lead = (
        max((crazyflie.ends_of(p, crazyflie.accuracy_for(p, max_deviation))[0] for p in paths), default=0.0)
        if fmt == "crazyflie"
        else 0.0
    )
    for path in paths:
        stem = file_stem(path.limits.id, taken)
        if fmt == "crazyflie":
            entry, plan, line = _crazyflie(path, stem, files, max_deviation, lead)
        elif fmt == "px4":
            entry, plan, line = _px4(rec, path, stem, files, origin, _mission_bound(rec, path, max_deviation))
        else:
            entry, plan, line = _csv(path, stem, files, _mission_bound(rec, path, max_deviation))
        entries.append(entry)
        plans.append(plan)
        lines.append(line)
    manifest = {
        "format": fmt,
        "source": os.path.basename(rec.file),
        "world": rec.world.get("name"),
        "seed": rec.world.get("seed"),
        "frame": {
            "axes": FRAME,
            "origin": origin,
            "bounds": rec.world.get("bounds"),
        },
        "start_together": "every agent starts its file at start_time after a common start",
        "agents": entries,
    }
    if fmt == "crazyflie":
        manifest["crazyflie"] = {
            "piece_bytes": crazyflie.PIECE_BYTES,
            "memory_bytes": crazyflie.MEMORY_BYTES,
            "max_pieces": crazyflie.MAX_PIECES,
            "yaw": "0 rad throughout",
        }
    return Export(files, manifest, plans, lines)


def _crazyflie(
    path: FlownPath, stem: str, files: dict[str, str], max_deviation: float | None, lead: float
) -> tuple[dict[str, Any], Plan, str]:
    lim = path.limits
    if lim.model != "multirotor":
        raise ExportError(
            f"agent {lim.id}: a {lim.model} agent cannot fly a Crazyflie trajectory (multirotors only)"
        )
    accuracy = crazyflie.accuracy_for(path, max_deviation)
    fit = crazyflie.fit(path, accuracy, lead=lead)
    poly = fit.poly
    name = f"{stem}.csv"
    files[name] = crazyflie.csv_text(poly)
    # The high-level commander's ticks from the trajectory's start to its end.
    dt = Crazyflie().commander_dt
    t = dt * np.arange(int(np.ceil(poly.duration / dt - 1e-9)) + 1)
    plan = Plan(
        lim.id,
        lim.model,
        lim.radius,
        lim.separation,
        path.start_time - fit.lead + t,
        poly.evaluate(t)[:, :3],
        accuracy,
        poly.evaluate(t, 1)[:, :3],
        poly.evaluate(t, 2)[:, :3],
        jerk=poly.evaluate(t, 3)[:, :3],
        vehicle="crazyflie",
    )
    jumps = poly.joint_jumps()
    entry = {
        "id": lim.id,
        "file": name,
        # From rest a lead before the first recorded step: the common start is the swarm's
        # longest lead before the log's t = 0 (every trajectory of the export has that lead).
        "start_time": path.start_time,
        "log_start_time": round(path.start_time - fit.lead, 6),
        "duration": round(poly.duration, 6),
        "pieces": poly.n_pieces,
        "bytes": poly.nbytes,
        "start": [round(float(v), 6) for v in poly.evaluate(np.zeros(1))[0, :3]],
        "end": [round(float(v), 6) for v in poly.evaluate(np.array([poly.duration]))[0, :3]],
        "accuracy_m": accuracy,
        "max_deviation_m": round(fit.max_deviation, 5),
        "max_speed": round(fit.max_speed, 4),
        "speed_limit": lim.speed_max,
        "max_accel": round(fit.max_accel, 4),
        "accel_limit": lim.max_accel,
        "max_jerk": round(fit.max_jerk, 2),
        "jerk_limit": round(crazyflie.jerk_limit(path), 2),
        "joint_jumps": {
            "position_m": float(jumps[0]),
            "velocity_m_s": float(jumps[1]),
            "accel_m_s2": float(jumps[2]),
        },
    }
    line = (
        f"{lim.id:<12} {name:<16} {poly.n_pieces:3d} pieces ({poly.nbytes} B) {poly.duration:7.2f} s  "
        f"dev {fit.max_deviation:.4f}/{accuracy:g} m  speed {fit.max_speed:.3f}/{lim.speed_max:g}  "
        f"accel {fit.max_accel:.3f}/{lim.max_accel:g}  "
        f"jerk {fit.max_jerk:.0f}/{crazyflie.jerk_limit(path):.0f}"
    )
    return entry, plan, line


def _mission(rec: Recording, path: FlownPath, bound: float) -> mission.Mission:
    """The agent's mission within ``bound`` of its flown path, each leg also within what the
    path's clearance allows there (:func:`clearance.leg_allowance`, ``terrain_test``): the legs
    keep the agent's radius plus its acceptance radius (the room the vehicle takes round a
    waypoint) from every body, the ground and the terrain, or where the flown path came closer,
    as close as it came."""
    lim = path.limits
    margin = mission.acceptance_radius_of(lim)
    allow = clearance.leg_allowance(rec, lim.id, path.times, path.positions, lim.radius, margin)
    fits = clearance.terrain_test(rec.world, path.positions, lim.radius, margin)
    return mission.mission_of(path, bound, allow, fits)


def _px4(
    rec: Recording, path: FlownPath, stem: str, files: dict[str, str], origin: dict[str, float], bound: float
) -> tuple[dict[str, Any], Plan, str]:
    lim = path.limits
    m = _mission(rec, path, bound)
    ground = float(terrain_height(rec.world, m.waypoints[:1, :2])[0])
    its, home = mission.items(m, origin, ground)
    files[f"{stem}.plan"] = mission.plan_text(m, its, home)
    files[f"{stem}.waypoints"] = mission.wpl_text(its, home)
    times, pos = mission.timed(m)
    plan = Plan(lim.id, lim.model, lim.radius, lim.separation, path.start_time + times, pos, bound,
                path_only=True)  # fmt: skip
    entry = {
        "id": lim.id,
        "file": f"{stem}.plan",
        "waypoint_list": f"{stem}.waypoints",
        "start_time": path.start_time,
        "duration": round(float(times[-1]), 6),
        "waypoints": len(m.waypoints),
        "items": len(its),
        "bound_m": bound,
        "max_deviation_m": round(m.max_deviation, 5),
        "home": home,
        "acceptance_radius_m": m.acceptance_radius(),
        "loiter_radius_m": m.loiter_radius() if m.fixed_wing else None,
    }
    line = (
        f"{lim.id:<12} {stem + '.plan':<16} {len(m.waypoints):4d} waypoints {len(its):4d} items "
        f"{float(times[-1]):8.2f} s  dev {m.max_deviation:.4f}/{bound:g} m"
    )
    return entry, plan, line


def _csv(path: FlownPath, stem: str, files: dict[str, str], bound: float) -> tuple[dict[str, Any], Plan, str]:
    lim = path.limits
    t = path.times
    vel = np.gradient(path.positions, t, axis=0) if len(t) > 2 else np.zeros_like(path.positions)
    rows = ["t,x,y,z,vx,vy,vz"]
    for k in range(len(t)):
        rows.append(",".join(repr(round(float(v), 9)) for v in (t[k], *path.positions[k], *vel[k])))
    files[f"{stem}.csv"] = "\n".join(rows) + "\n"
    plan = Plan(lim.id, lim.model, lim.radius, lim.separation, t, path.positions, bound)
    entry = {"id": lim.id, "file": f"{stem}.csv", "start_time": path.start_time, "duration": path.duration,
             "samples": len(t)}  # fmt: skip
    return entry, plan, f"{lim.id:<12} {stem + '.csv':<16} {len(t):5d} samples {path.duration:8.2f} s"


def run_check(rec: Recording, exp: Export, cfg: TrackerConfig) -> CheckResult:
    result = check(rec, exp.plans, cfg)
    exp.checked = result
    exp.files["check.json"] = json.dumps(result.to_json(), indent=2) + "\n"
    return result


def write(exp: Export, out: str | Path) -> None:
    """Write every file into ``out`` at once: into a temporary folder beside it, then renamed into
    place (a new folder whole; into an existing one file by file, each replaced atomically)."""
    out = Path(out)
    files = dict(exp.files)
    files["manifest.json"] = json.dumps(exp.manifest, indent=2) + "\n"
    parent = out.parent if str(out.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out.name}.export-"))
    try:
        for name, text in files.items():
            with open(tmp / name, "w", encoding="utf-8") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
        if not out.exists():
            os.rename(tmp, out)
            return
        for name in files:
            os.replace(tmp / name, out / name)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
