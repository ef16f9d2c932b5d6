"""Shared helpers for the core tests: world builders, running a simulation to its end,
reading logs back, and the independent log audit.

The audit of a log (:func:`audit`) always recomputes everything from the recorded states with
the package's own replay (``swarmplan.replay``: it shares no code with the simulator) and
compares it with the recorded ``/summary``. Where the shared checker ``check_log.py`` exists
(not part of the package: found through the environment variable ``SWARMPLAN_CHECK_LOG`` or at
``<repo>/../shared/tools/check_log.py``) it audits the log too. On CI (``CI=true``) a missing
checker is a failure, never a skip.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from swarmplan.world import World, parse_world

REPO = Path(__file__).resolve().parents[1]
_CHECK_LOG_MODULE = None


def on_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def check_log_candidates() -> list[Path]:
    """Where ``check_log.py`` is looked for, in order: $SWARMPLAN_CHECK_LOG, then beside the repo."""
    out = []
    env = os.environ.get("SWARMPLAN_CHECK_LOG")
    if env:
        out.append(Path(env).expanduser())
    out.append((REPO / ".." / "shared" / "tools" / "check_log.py").resolve())
    return out


def find_check_log() -> Path | None:
    for p in check_log_candidates():
        if p.is_file():
            return p
    return None


def _missing_check_log() -> str:
    return "shared/tools/check_log.py not found (set SWARMPLAN_CHECK_LOG); searched " + ", ".join(
        str(p) for p in check_log_candidates()
    )


def check_log_module(required: bool = True):
    """The ``check_log`` module imported from its file.

    When it cannot be found: None if not ``required``; otherwise the test is skipped, or fails
    on CI, where every audit must run.
    """
    global _CHECK_LOG_MODULE
    if _CHECK_LOG_MODULE is not None:
        return _CHECK_LOG_MODULE
    path = find_check_log()
    if path is None:
        if on_ci():
            pytest.fail(f"CI=true but {_missing_check_log()}")
        if required:
            pytest.skip(_missing_check_log())
        return None
    spec = importlib.util.spec_from_file_location("swarmplan_check_log", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    _CHECK_LOG_MODULE = mod
    return mod


def replay_audit(log_path: Path, allow_failure: bool = False) -> tuple[list[str], list[str], dict[str, Any]]:
    """The package's independent audit: metrics recomputed from the recorded states by
    ``swarmplan.replay`` (no simulator code), compared with the recorded ``/summary``.

    Problems: every disagreement with the summary, every collision, a missing summary and,
    unless ``allow_failure``, every agent that did not arrive. Same shape as ``check_log.check``.
    """
    from swarmplan.replay import compare_with_summary, compute_metrics, load

    rec = load(log_path)
    problems: list[str] = []
    notes = ["file was cut short: read by streaming"] if rec.truncated else []
    if rec.n_steps == 0:
        return [f"{log_path}: no /agents/state steps"], notes, {}
    metrics = compute_metrics(rec)
    if rec.summary is None:
        problems.append("no /summary recorded")
    else:
        disagreements, _n = compare_with_summary(rec, metrics)
        problems += [f"replay vs /summary: {d}" for d in disagreements]
    for m in metrics:
        if m.collisions:
            problems.append(f"replay: agent {m.id} collided with {', '.join(m.collision_bodies)}")
        if not m.arrived and not allow_failure:
            problems.append(f"replay: agent {m.id} did not arrive ({m.final_goal_distance:.2f} m from goal)")
    clear = [m.min_obstacle_clearance for m in metrics if m.min_obstacle_clearance is not None]
    stats = {
        "steps": rec.n_steps,
        "agents": rec.n_agents,
        "arrived": sum(m.arrived for m in metrics),
        "collisions": sum(m.collisions for m in metrics),
        "min_obstacle_clearance": min(clear) if clear else None,
        "sim_time": float(rec.times[-1]),
    }
    return problems, notes, stats


def audit(log_path: Path, allow_failure: bool = False) -> tuple[list[str], list[str], dict[str, Any]]:
    """(problems, notes, stats) of a log: replay's audit always, ``check_log.check`` in addition
    where the checker exists (on CI it must). Where both ran, their counts of arrivals and
    collisions must agree; ``stats`` are replay's."""
    problems, notes, stats = replay_audit(log_path, allow_failure)
    mod = check_log_module(required=False)
    if mod is None:
        notes.append(f"audited by swarmplan.replay only: {_missing_check_log()}")
        return problems, notes, stats
    c_problems, c_notes, c_stats = mod.check(str(log_path), allow_failure)
    problems += [f"check_log: {p}" for p in c_problems]
    notes += [f"check_log: {n}" for n in c_notes]
    for key in ("agents", "arrived"):
        if key in c_stats and c_stats[key] != stats.get(key):
            problems.append(f"replay and check_log disagree on {key}: {stats.get(key)} vs {c_stats[key]}")
    if c_stats.get("collisions") is not None and (c_stats["collisions"] == 0) != (stats["collisions"] == 0):
        problems.append(
            f"replay and check_log disagree on collisions: {stats['collisions']} vs {c_stats['collisions']}"
        )
    return problems, notes, stats


# ----------------------------------------------------------------------------- worlds


def base_world(**top: Any) -> dict[str, Any]:
    """A small valid raw world (one multirotor in an empty 100 m box); ``top`` replaces keys."""
    raw: dict[str, Any] = {
        "name": "t",
        "seed": 0,
        "bounds": {"min": [0, 0, 0], "max": [100, 100, 50]},
        "sim": {"dt": 0.1, "max_time": 60, "goal_tolerance": 2.0},
        "agent_defaults": {
            "model": "multirotor",
            "radius": 1.0,
            "speed": {"min": 0, "max": 12, "cruise": 8},
            "max_accel": 4,
            "min_altitude": 5,
            "separation": [4, 4, 2],
        },
        "agents": [{"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]}],
        # the field's gains and the escapes' lengths of a 10 m field (a 5 m/s, 5 m/s² agent), as the
        # tests that build on this world were written for; left out they scale with the agent
        "planner": {
            "optimizer": {"name": "none"},
            "apf": {"k_rep": 50.0, "quadratic_radius": 10.0},
            "escape": {"margin": 1.0, "fcl_margin": 0.3},
        },
        "log": {"foxglove": False},
    }
    raw.update(copy.deepcopy(top))
    return raw


def crossing_with_drone(max_time: float = 3.0) -> dict[str, Any]:
    """Two agents crossing while a drone (a sphere on a straight line) cuts between them: the
    smallest world with a mover, every per-step channel and a few seconds of log."""
    return base_world(
        sim={"dt": 0.1, "max_time": max_time, "goal_tolerance": 2.0},
        obstacles=[
            {
                "id": "drone",
                "shape": "sphere",
                "radius": 2,
                "position": [70, 90, 20],
                "motion": {"type": "linear", "velocity": [0, -5, 0]},
            }
        ],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "b", "start": [50, 10, 20], "goal": [50, 90, 25]},
        ],
    )


def obstacles_of(
    raw: list[dict[str, Any]], start: tuple[float, float, float], goal: tuple[float, float, float]
) -> list:
    """The parsed obstacles of ``raw`` in a 100 m box centred on the origin (one agent flying
    ``start`` -> ``goal``, which must be clear of them)."""
    return parse_world(
        {
            "name": "t",
            "bounds": {"min": [-50, -50, -50], "max": [50, 50, 50]},
            "obstacles": raw,
            "agents": [{"id": "a", "start": list(start), "goal": list(goal)}],
        }
    ).obstacles


def make_world(raw: dict[str, Any], base_dir: Path | str = ".") -> World:
    return parse_world(copy.deepcopy(raw), base_dir=base_dir)


def run_to_end(
    world: World,
    seed: int | None = None,
    log_path: Path | None = None,
    planner: Any = None,
    foxglove: bool = False,
) -> tuple[Any, dict[str, Any], list]:
    """Run ``world`` until terminated/truncated; returns (simulation, summary, per-step positions).

    With ``log_path`` the run is recorded by :class:`McapRecorder` (summary included).
    """
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import run_episode
    from swarmplan.sim import Simulation

    rec = McapRecorder(log_path, foxglove=foxglove) if log_path is not None else None
    sim = Simulation(world, planner=planner)
    positions: list = []

    class _Positions:
        def on_reset(self, result):
            positions.append(result.state.position.copy())

        def on_step(self, result):
            positions.append(result.state.position.copy())

    seed = sim.world.seed if seed is None else seed
    summary = run_episode(sim, seed, observers=[_Positions()], recorder=rec)
    return sim, summary, positions


def default_planner(world: World) -> Any:
    """The package's refinement planner with the world's optimizer (rscdwoa when that is 'none')."""
    from swarmplan.planner import make_planner

    name = world.planner["optimizer"]["name"]
    return make_planner(world, "rscdwoa" if name == "none" else name)


# ----------------------------------------------------------------------------- logs


def read_log(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """{topic: [(log_time_ns, decoded JSON or raw bytes)]} read with the indexed MCAP reader."""
    from mcap.reader import make_reader

    out: dict[str, list[tuple[int, Any]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            data = json.loads(message.data) if channel.message_encoding == "json" else bytes(message.data)
            out.setdefault(channel.topic, []).append((message.log_time, data))
    return out


def log_positions(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(agent ids, times (T,), positions (T, N, 3)) from a log's ``/agents/state``."""
    states = [d for _, d in read_log(path)["/agents/state"]]
    ids = [a["id"] for a in states[0]["agents"]]
    t = np.array([s["t"] for s in states])
    p = np.array([[a["position"] for a in s["agents"]] for s in states])
    return ids, t, p


def events_of(path: Path, kind: str | None = None) -> list[dict[str, Any]]:
    ev = [d for _, d in read_log(path).get("/events", [])]
    return [e for e in ev if kind is None or e["kind"] == kind]


def describe_failure(summary: dict[str, Any], log_path: Path | None = None) -> str:
    """A precise account of what went wrong in a run, for assertion messages."""
    lines = [
        f"world {summary.get('world')!r} seed {summary.get('seed')}: "
        f"{summary.get('arrived')}/{summary.get('agents_total')} arrived, "
        f"{summary.get('collisions')} collision(s), t={summary.get('sim_time')}"
    ]
    for a in summary.get("agents", []):
        if not a["arrived"] or a["collisions"]:
            lines.append(
                f"  agent {a['id']}: final_mode={a['final_mode']} collided_with={a['collided_with']} "
                f"min_clearance={a['min_clearance']} stuck={a['stuck_events']} "
                f"emergency_stops={a['emergency_stops']}"
            )
    if log_path is not None and Path(log_path).exists():
        for e in events_of(log_path):
            if e["kind"] in ("collision", "timeout", "failed"):
                lines.append(f"  event t={e['t']}: {e['agent']} {e['kind']} {e['detail']}")
        ids, _t, p = log_positions(log_path)
        final = ", ".join(f"{i}={np.round(p[-1, k], 2).tolist()}" for k, i in enumerate(ids))
        lines.append(f"  final positions: {final}")
    return "\n".join(lines)


def without_guide(world: World) -> World:
    """``world`` flying the bare potential field (``planner.apf.guide: false``), without its
    guide round static obstacles (``swarmplan.flight.guide``): the field's own local minima
    (the trap worlds), on which the escape planner is tested. With the guide (the default)
    pure APF gets out of them itself."""
    from swarmplan.io.runner import apply_overrides

    return apply_overrides(world, None, None, guide=False)


def random_shapes(rng: np.random.Generator, count: int) -> list[dict[str, Any]]:
    """``count`` world-format obstacles cycling through sphere, box, cylinder and capsule, placed
    and sized at random in a 40 m cube; two in three rotated."""
    raw = []
    for k in range(count):
        shape = ("sphere", "box", "cylinder", "capsule")[k % 4]
        o: dict[str, Any] = {"id": f"o{k}", "shape": shape, "position": rng.uniform(-20, 20, 3).tolist()}
        if shape == "box":
            o["size"] = rng.uniform(1, 8, 3).tolist()
        else:
            o["radius"] = float(rng.uniform(0.5, 4))
        if shape in ("cylinder", "capsule"):
            o["height"] = float(rng.uniform(1, 10))
        if k % 3:  # a third keep the identity
            o["rotation"] = rng.uniform(-90, 90, 3).tolist()
        raw.append(o)
    return raw


def fly_metered(sim: Any, seed: int) -> Any:
    """``sim`` reset with ``seed`` and flown to its end; its ``ContactMeter`` (contacts measured
    from the positions, swept between steps)."""
    from swarmplan.bench.swarm_runs import ContactMeter

    sim.reset(seed=seed)
    meter = ContactMeter(sim.params.radius)
    while True:
        p0 = sim.state.position.copy()
        r = sim.step()
        meter.update(p0, sim.state.position)
        if r.terminated or r.truncated:
            return meter


def flight_draw_settings() -> dict:
    """hypothesis settings for tests whose every example is a whole flight: deterministic draws
    (the suite's outcome does not change from run to run) and no shrinking (a seed shrinks to
    nothing useful; the caps do, but each step is a whole flight)."""
    from hypothesis import HealthCheck, Phase

    return dict(
        deadline=None,
        derandomize=True,
        database=None,
        phases=(Phase.explicit, Phase.generate),
        suppress_health_check=[HealthCheck.too_slow],
    )
