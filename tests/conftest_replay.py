"""Synthetic run logs for the replay tests, written with the plain ``mcap`` Writer per the
log contract (shared/spec/log-format.md). Not part of the package."""

from __future__ import annotations

import json
import math

import numpy as np
from mcap.writer import CompressionType, Writer

SCHEMA = json.dumps({"type": "object"}).encode()


def write_log(
    path,
    world: dict,
    states: list[dict],
    obstacle_states: list[dict] | None = None,
    events: list[dict] | None = None,
    optimizer: list[dict] | None = None,
    summary: dict | None = None,
    chunk_size: int = 64 * 1024,
    finish: bool = True,
    flush_every: int = 0,
) -> str:
    """Write a contract log. ``finish=False`` leaves the file like a hard-killed writer."""
    f = open(path, "wb")
    w = Writer(f, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    w.start(profile="", library="swarmplan-tests")
    chans = {}
    for topic in ("/world", "/agents/state", "/obstacles/state", "/events", "/optimizer", "/summary"):
        sid = w.register_schema(name=topic.strip("/").replace("/", "_"), encoding="jsonschema", data=SCHEMA)
        chans[topic] = w.register_channel(topic=topic, message_encoding="json", schema_id=sid)

    def put(topic, msg, t):
        ns = int(round(t * 1e9))
        w.add_message(chans[topic], log_time=ns, publish_time=ns, data=json.dumps(msg).encode())

    put("/world", world, 0.0)
    obst_by_t = {round(m["t"], 9): m for m in obstacle_states or []}
    ev = sorted(events or [], key=lambda e: e["t"])
    opt = sorted(optimizer or [], key=lambda e: e["t"])
    for k, st in enumerate(states):
        t = st["t"]
        while ev and ev[0]["t"] <= t:
            e = ev.pop(0)
            put("/events", e, e["t"])
        while opt and opt[0]["t"] <= t:
            o = opt.pop(0)
            put("/optimizer", o, o["t"])
        put("/agents/state", st, t)
        if round(t, 9) in obst_by_t:
            put("/obstacles/state", obst_by_t[round(t, 9)], t)
        if flush_every and k % flush_every == flush_every - 1 and hasattr(w, "_maybe_finalize_chunk"):
            w._maybe_finalize_chunk()
    for e in ev:
        put("/events", e, e["t"])
    for o in opt:
        put("/optimizer", o, o["t"])
    if summary is not None:
        put("/summary", summary, states[-1]["t"] if states else 0.0)
    if finish:
        w.finish()
    else:
        # flush completed chunks only, like a process killed mid-run
        f.flush()
    f.close()
    return str(path)


def base_world(agents: list[dict], obstacles: list[dict] | None = None, **extra) -> dict:
    """A resolved world dict (every key after defaults) as the recorder writes it."""
    defaults = {
        "model": "multirotor",
        "radius": 0.5,
        "speed": {"min": 0.0, "max": 15.0, "cruise": 10.0},
        "max_accel": 5.0,
        "min_turn_radius": 20.0,
        "max_climb_angle": 45.0,
        "min_altitude": 0.0,
        "separation": [5, 5, 2],
    }
    resolved_agents = [{**defaults, **a} for a in agents]
    obst = []
    for o in obstacles or []:
        o = dict(o)
        o.setdefault("rotation", [0, 0, 0])
        o.setdefault("motion", None)
        obst.append(o)
    world = {
        "name": "synthetic",
        "seed": 3,
        "swarmplan_version": "0.1.0",
        "bounds": {"min": [-50, -50, 0], "max": [50, 50, 50]},
        "sim": {"dt": 0.1, "max_time": 60.0, "goal_tolerance": 0.05},
        "terrain": None,
        "obstacles": obst,
        "threats": [],
        "agent_defaults": defaults,
        "agents": resolved_agents,
        "planner": {
            "apf": {"k_att": 1.0, "k_rep": 50.0, "influence": 40.0, "k_agent": 20.0},
            "stuck": {"window": 3.0, "min_progress": 0.5},
            "optimizer": {"name": "rscdwoa", "population": 30, "iterations": 100, "params": {}},
            "smoothing": {"enabled": True},
        },
        "log": {"path": "logs/{name}-{seed}.mcap"},
    }
    world.update(extra)
    return world


def states_from_arrays(times, ids, positions, velocities=None, modes=None, goals=None) -> list[dict]:
    """positions (A,T,3) -> list of /agents/state messages."""
    positions = np.asarray(positions, float)
    A, T, _ = positions.shape
    if velocities is None:
        velocities = np.zeros_like(positions)
        if T > 1:
            dt = np.diff(times)
            velocities[:, 1:] = np.diff(positions, axis=1) / dt[None, :, None]
    out = []
    for k in range(T):
        agents = []
        for i in range(A):
            agents.append(
                {
                    "id": ids[i],
                    "position": [float(x) for x in positions[i, k]],
                    "velocity": [float(x) for x in velocities[i, k]],
                    "mode": modes[i][k] if modes is not None else "apf",
                    "goal": [float(x) for x in goals[i]] if goals is not None else [0.0, 0.0, 0.0],
                }
            )
        out.append({"t": float(times[k]), "agents": agents})
    return out


def straight_past_sphere_log(
    path, distance: float = 3.0, radius_obst: float = 1.0, radius_agent: float = 0.5
):
    """One agent flying 10 m along x at y = ``distance`` past a sphere at the origin.

    Exact answers: path length 10, min clearance distance - radius_obst - radius_agent,
    arrival at t = 10 s (1 m/s), curvature 0.
    """
    times = np.round(np.arange(0, 101) * 0.1, 10)
    x = -5.0 + times  # 1 m/s
    pos = np.stack([x, np.full_like(x, distance), np.full_like(x, 10.0)], axis=1)[None]
    goal = [5.0, distance, 10.0]
    modes = [["apf"] * 100 + ["arrived"]]
    world = base_world(
        [{"id": "a1", "start": [-5.0, distance, 10.0], "goal": goal, "radius": radius_agent}],
        [{"id": "ball", "shape": "sphere", "radius": radius_obst, "position": [0.0, 0.0, 10.0]}],
    )
    states = states_from_arrays(times, ["a1"], pos, modes=modes, goals=[goal])
    clearance = distance - radius_obst - radius_agent
    summary = {
        "interrupted": False,
        "success": True,
        "wall_time": 0.5,
        "sim_time": 10.0,
        "agents": [
            {
                "id": "a1",
                "arrived": True,
                "arrival_time": 10.0,
                "path_length": 10.0,
                "min_clearance": clearance,
                "max_curvature": 0.0,
                "collisions": 0,
                "escapes": 0,
                "stuck_events": 0,
            }
        ],
    }
    events = [{"t": 10.0, "agent": "a1", "kind": "arrived", "detail": {}}]
    return write_log(path, world, states, events=events, summary=summary), clearance


def circle_positions(times, center, radius, omega, z):
    ang = omega * np.asarray(times)
    return np.stack(
        [center[0] + radius * np.cos(ang), center[1] + radius * np.sin(ang), np.full_like(ang, z)], axis=1
    )


def rich_log(path, n_agents: int = 3, steps: int = 200, finish: bool = True, chunk_size: int = 64 * 1024):
    """Several agents, every obstacle shape (incl. a mesh and a moving sphere), escapes,
    optimizer runs, terrain: exercises every code path of replay."""
    import trimesh

    dt = 0.1
    times = np.round(np.arange(steps) * dt, 10)
    ids = [f"uav{i + 1}" for i in range(n_agents)]
    pos = np.zeros((n_agents, steps, 3))
    goals = []
    modes = []
    for i in range(n_agents):
        y = -20.0 + 40.0 * i / max(1, n_agents - 1)
        s = np.linspace(0, 1, steps)
        pos[i, :, 0] = -40 + 80 * s
        pos[i, :, 1] = y + 5 * np.sin(2 * math.pi * s)
        pos[i, :, 2] = 20 + 3 * s
        goals.append(pos[i, -1].tolist())
        m = ["apf"] * steps
        for k in range(steps // 4, steps // 4 + 15):
            m[k] = "escape"
        for k in range(steps // 2, steps // 2 + 10):
            m[k] = "smoothing"
        m[-1] = "arrived"
        modes.append(m)
    box_mesh = trimesh.creation.box(extents=[4, 4, 4])
    box_mesh.apply_translation([20, 30, 10])
    obstacles = [
        {"id": "ball", "shape": "sphere", "radius": 4.0, "position": [0, 30, 20]},
        {
            "id": "block",
            "shape": "box",
            "size": [6, 4, 30],
            "position": [-20, 35, 15],
            "rotation": [0, 0, 30],
        },
        {"id": "mast", "shape": "cylinder", "radius": 2, "height": 30, "position": [10, -35, 15]},
        {
            "id": "pole",
            "shape": "capsule",
            "radius": 1.5,
            "height": 10,
            "position": [-10, -35, 20],
            "rotation": [90, 0, 0],
        },
        {
            "id": "hangar",
            "shape": "mesh",
            "file": "meshes/box.stl",
            "scale": 1.0,
            "position": [20, 30, 10],
            "vertices": box_mesh.vertices.tolist(),
            "faces": box_mesh.faces.tolist(),
        },
        {
            "id": "intruder",
            "shape": "sphere",
            "radius": 3.0,
            "position": [30, -45, 25],
            "motion": {"type": "linear", "velocity": [-2, 0, 0]},
        },
    ]
    world = base_world(
        [{"id": ids[i], "start": pos[i, 0].tolist(), "goal": goals[i]} for i in range(n_agents)],
        obstacles,
        terrain={"peaks": [{"center": [0, 0], "height": 8, "spread": [15, 15]}], "clearance": 2},
        threats=[{"kind": "radar", "position": [0, 0, 0], "r_min": 5, "r_max": 30, "weight": 0.3}],
    )
    states = states_from_arrays(times, ids, pos, modes=modes, goals=goals)
    obst_states = [
        {
            "t": float(t),
            "obstacles": [{"id": "intruder", "position": [30 - 2 * t, -45, 25], "orientation": [0, 0, 0, 1]}],
        }
        for t in times
    ]
    events, opt = [], []
    for i, aid in enumerate(ids):
        t_esc = float(times[steps // 4])
        events += [
            {"t": t_esc - dt, "agent": aid, "kind": "stuck", "detail": {}},
            {"t": t_esc, "agent": aid, "kind": "escape_start", "detail": {}},
            {"t": float(times[steps // 4 + 15]), "agent": aid, "kind": "escape_end", "detail": {}},
            {"t": float(times[-1]), "agent": aid, "kind": "arrived", "detail": {}},
        ]
        for purpose, t0 in (("escape", t_esc), ("smoothing", float(times[steps // 2]))):
            conv = list(100.0 / (1 + np.arange(30)) + i)
            opt.append(
                {
                    "t": t0,
                    "agent": aid,
                    "algorithm": "rscdwoa",
                    "purpose": purpose,
                    "evaluations": 900,
                    "iterations": 30,
                    "best_cost": conv[-1],
                    "wall_ms": 12.5,
                    "convergence": conv,
                }
            )
    summary = {
        "interrupted": False,
        "success": True,
        "wall_time": 1.0,
        "sim_time": float(times[-1]),
        "agents": [],
    }
    return (
        write_log(
            path,
            world,
            states,
            obst_states,
            events,
            opt,
            summary if finish else None,
            finish=finish,
            chunk_size=chunk_size,
        ),
        pos,
        ids,
    )
