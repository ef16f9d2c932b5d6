"""The world format (``shared/spec/world-format.md``): a raw mapping -> a typed
:class:`~swarmplan.world.model.World`, with defaults applied and every problem collected.

Each section has its resolver; :func:`parse_world` walks them, runs the cross-field checks
(:mod:`swarmplan.world.checks`) and raises one :class:`WorldError` listing every problem."""

from __future__ import annotations

import copy
import difflib
import math
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan import optimizers
from swarmplan.geometry import bodies
from swarmplan.geometry.rotation import rotation_matrix
from swarmplan.world.airframe import FIXED_WING_KEYS, airframe_keys, fixed_wing_spec
from swarmplan.world.checker import Checker, join, typename
from swarmplan.world.checks import check_placements
from swarmplan.world.comms import resolve_comms, resolve_sensing
from swarmplan.world.meshes import load_mesh
from swarmplan.world.model import (
    MODELS,
    MOTIONS,
    PLANNER_MODES,
    SHAPES,
    THREAT_KINDS,
    AgentSpec,
    Motion,
    Obstacle,
    Peak,
    Threat,
    World,
    WorldError,
)
from swarmplan.world.origin import resolve_origin
from swarmplan.world.planner_config import check_escape, check_global, planner_config
from swarmplan.world.tracker_config import parse_tracker

AGENT_DEFAULTS: dict[str, Any] = {
    "model": "multirotor",
    "radius": 1.5,
    "speed": {"min": 0.0, "max": 15.0, "cruise": 10.0},
    "max_accel": 5.0,
    "min_turn_radius": 20.0,
    "max_climb_angle": 45.0,
    "min_altitude": None,  # m; left out: from the agent (default_min_altitude)
    "separation": None,  # m; left out: the agent's diameter on each axis (default_separation)
}

PLANNER_DEFAULTS: dict[str, Any] = {
    "mode": "reactive",
    "apf": {
        "k_att": 1.0,
        "k_rep": None,  # m^2 (times k_att); left out: 0.5 k_att influence^2 (default_field_scale)
        "influence": None,  # m; left out: from the agents (default_influence)
        "k_agent": None,  # m (times k_att); left out: 0.5 k_att influence (default_field_scale)
        "quadratic_radius": None,  # m: attraction is quadratic inside, conic outside; left out: influence
        "goal_power": 2.0,  # n of the goal-distance factor rho_goal^n in the repulsion
        "k_moving": 2.0,  # weight of the relative-velocity term for moving obstacles
        "horizon": 4.0,  # s: how far ahead moving obstacles and agents are predicted
        "guide": True,  # lead agents round static obstacles (swarmplan.flight.guide); false: bare field
    },
    "stuck": {"window": 3.0, "min_progress": None},  # m; left out: from the agents (default_stuck_progress)
    "optimizer": {"name": "rscdwoa", "population": 30, "iterations": 100, "params": {}},
    "smoothing": {"enabled": True},
}


def default_influence(agents: list[AgentSpec]) -> float:
    """``planner.apf.influence`` left out: ``2 v^2 / a`` (four braking distances from cruise
    speed) of the agent that needs the most room, and at least two of its radii. The field's
    repulsion starts where it leaves room to turn or stop; 40 m for the default agent (10 m/s,
    5 m/s^2), 10 m for a 5 m/s multirotor braking at 5 m/s^2, 0.64 m for a 0.8 m/s lab drone
    braking at 2 m/s^2. A longer range sums the pushes of whole forests and crowds into walls
    that hold agents away from their goals. Each multirotor flies the field scaled to its own
    room within it (``kinematics.field_scales``)."""
    return max((a.field_room for a in agents), default=40.0)


def default_stuck_progress(agents: list[AgentSpec]) -> float:
    """``planner.stuck.min_progress`` left out: the smallest agent's radius (0.5 m for 0.5 m
    multirotors, 5 cm for 5 cm lab drones, which a bar in metres found stuck on every slow approach)."""
    return min((a.radius for a in agents), default=0.5)


def default_field_scale(apf: dict[str, Any]) -> None:
    """Fill ``planner.apf.quadratic_radius``, ``k_rep`` and ``k_agent`` left out, from the
    influence ``rho0``: ``rho0``, ``0.5 k_att rho0^2`` and ``0.5 k_att rho0``. The attraction grows
    as ``k_att d`` (m) and the repulsion as ``k_rep / rho`` (1/m): only these keep the field's shape
    at every size (a wall between an agent and its goal holds it a third of the influence off; two
    agents, in their separation ellipsoids, pass as close against the pull at cruise; a 0.05 m lab
    drone as a 100 km fixed wing). At 10 m: 10 m, 50 and 5; at 40 m the agents' classic 20."""
    rho0, k_att = float(apf["influence"]), float(apf["k_att"])
    scaled = {"quadratic_radius": rho0, "k_rep": 0.5 * k_att * rho0 * rho0, "k_agent": 0.5 * k_att * rho0}
    apf.update({key: value for key, value in scaled.items() if apf.get(key) is None})


def default_min_altitude(params: dict[str, Any]) -> float:
    """``min_altitude`` left out: the height an agent needs to level out above the ground at
    its limits, plus its radius. A multirotor descending at cruise speed brakes to a stop in
    ``v^2 / (2 a)``; a fixed wing diving at its largest climb angle ``g`` pulls out on its
    minimum turn radius in ``R (1 - cos g)``. 11.5 m for the default multirotor (10 m/s,
    5 m/s^2, radius 1.5 m), 0.21 m for a 0.05 m lab drone at 0.8 m/s and 2 m/s^2."""
    if params["model"] == "fixed_wing":
        g = math.radians(float(params["max_climb_angle"]))
        need = float(params["min_turn_radius"]) * (1.0 - math.cos(g))
    else:
        v = float(params["speed"]["cruise"])
        need = v * v / (2.0 * max(float(params["max_accel"]), 1e-9))
    return need + float(params["radius"])


def default_separation(radius: float) -> list[float]:
    """``separation`` left out: the agent's diameter on each axis. The pair's ellipsoid has
    semi-axes ``max(separation) + r_i + r_j``; the agents' bodies touch at half of it, so two
    agents of one size keep one body of air between them at the repulsion's steepest."""
    return [2.0 * float(radius)] * 3


def default_goal_tolerance(agents: list[AgentSpec]) -> float:
    """``sim.goal_tolerance`` left out: the arrival radius the agent that needs the most allows:
    a multirotor its own radius (its body covers the goal), a fixed wing a quarter of its
    minimum turn radius (it cannot hover; it passes over the goal)."""
    need = [a.min_turn_radius / 4.0 if a.model == "fixed_wing" else a.radius for a in agents]
    return max(need, default=2.0)


SIM_DEFAULTS = {"dt": 0.1, "max_time": 120.0, "goal_tolerance": None}  # tolerance: default_goal_tolerance

LOG_DEFAULTS = {"path": "logs/{name}-{seed}.mcap", "foxglove": True, "flush_interval": 1.0}


def _resolve_planner(c: Checker, raw: Any, optimizer_names: list[str] | None) -> dict[str, Any]:
    planner = copy.deepcopy(PLANNER_DEFAULTS)
    if raw is None:
        return planner
    extra_sections = ("global", "escape")  # owned by the planner package; validated there
    if not c.keys(raw, "planner", list(planner) + list(extra_sections)):
        return planner
    planner["mode"] = c.string(raw, "mode", "planner", "reactive", PLANNER_MODES)
    for section in ("apf", "stuck"):
        node = raw.get(section)
        if node is None:
            continue
        if c.keys(node, f"planner.{section}", list(planner[section])):
            for k, dv in PLANNER_DEFAULTS[section].items():
                if dv is None and node.get(k) is None:
                    continue  # derived from the agents once they are known
                if isinstance(dv, bool):
                    planner[section][k] = c.boolean(node, k, f"planner.{section}", dv)
                else:
                    planner[section][k] = c.number(node, k, f"planner.{section}", dv, positive=True)
    opt = raw.get("optimizer")
    if opt is not None and c.keys(opt, "planner.optimizer", ["name", "population", "iterations", "params"]):
        names = optimizer_names or []
        name = c.string(opt, "name", "planner.optimizer", "rscdwoa")
        if name is not None and name != "none" and names and name not in names:
            close = difflib.get_close_matches(name, names, n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            c.add(
                "planner.optimizer.name", f"unknown optimizer '{name}'{hint}; known: none, {', '.join(names)}"
            )
        planner["optimizer"]["name"] = name
        before = len(c.problems)
        for k in ("population", "iterations"):
            v = c.number(
                opt, k, "planner.optimizer", planner["optimizer"][k], lo=2 if k == "population" else 1
            )
            if v is not None and v != int(v):
                c.add(f"planner.optimizer.{k}", f"must be a whole number, got {v:g}")
            planner["optimizer"][k] = int(v) if v is not None else planner["optimizer"][k]
        params = opt.get("params") or {}
        if not isinstance(params, dict):
            c.add("planner.optimizer.params", f"expected a mapping, got {typename(params)}")
            params = {}
        planner["optimizer"]["params"] = dict(params)
        # params are checked with a valid budget only (a bad population is named once, above)
        if name not in (None, "none") and names and name in names and len(c.problems) == before:
            try:
                optimizers.make(name, population=planner["optimizer"]["population"], **params)
            except ValueError as exc:
                c.add("planner.optimizer.params", str(exc))
    sm = raw.get("smoothing")
    if sm is not None and c.keys(sm, "planner.smoothing", ["enabled"]):
        planner["smoothing"]["enabled"] = c.boolean(sm, "enabled", "planner.smoothing", True)
    for section in extra_sections:
        if section in raw:
            if not isinstance(raw[section], dict):
                c.add(f"planner.{section}", f"expected a mapping, got {typename(raw[section])}")
            else:
                planner[section] = copy.deepcopy(raw[section])
    return planner


def _resolve_agent_params(c: Checker, node: dict, path: str, base: dict[str, Any]) -> dict[str, Any]:
    """Merge agent parameter keys of ``node`` over ``base`` (both in world-file form)."""
    out = copy.deepcopy(base)
    if "model" in node:
        out["model"] = c.string(node, "model", path, base["model"], MODELS)
    for k in ("radius", "max_accel", "min_turn_radius", *FIXED_WING_KEYS):  # fixed wings' own: theirs only
        if k in node:
            out[k] = c.number(node, k, path, base.get(k), positive=True)
    if "min_altitude" in node:
        out["min_altitude"] = c.number(node, "min_altitude", path, base["min_altitude"], nonneg=True)
    if "max_climb_angle" in node:
        v = c.number(node, "max_climb_angle", path, base["max_climb_angle"], positive=True)
        if v is not None and v > 90:
            c.add(join(path, "max_climb_angle"), f"must be <= 90 degrees, got {v:g}")
        out["max_climb_angle"] = v
    if "separation" in node:
        v = c.vector_value(node["separation"], join(path, "separation"), 3, nonneg=True)
        out["separation"] = v.tolist() if v is not None else base["separation"]
    if "speed" in node:
        sp = node["speed"]
        if c.keys(sp, join(path, "speed"), ["min", "max", "cruise"]):
            for k in ("min", "max", "cruise"):
                if k in sp:
                    out["speed"][k] = c.number(
                        sp, k, join(path, "speed"), base["speed"][k], nonneg=k != "max", positive=k == "max"
                    )
    return out


def _check_agent_params(c: Checker, a: dict[str, Any], path: str) -> None:
    sp = a["speed"]
    if None in (sp["min"], sp["max"], sp["cruise"]) or sp["max"] <= 0:
        return  # a speed.max <= 0 was reported where it was written
    if sp["min"] > sp["max"]:
        c.add(f"{path}.speed", f"min ({sp['min']:g}) is above max ({sp['max']:g})")
    elif not sp["min"] <= sp["cruise"] <= sp["max"]:
        c.add(
            f"{path}.speed.cruise",
            f"must lie between min ({sp['min']:g}) and max ({sp['max']:g}), got {sp['cruise']:g}",
        )
    if a["model"] == "fixed_wing" and sp["min"] <= 0:
        c.add(f"{path}.speed.min", "a fixed_wing agent needs a speed floor > 0")


def _resolve_motion(c: Checker, m: Any, path: str) -> tuple[dict | None, Motion | None]:
    if not isinstance(m, dict):
        c.add(path, f"expected a mapping, got {typename(m)}")
        return None, None
    kind = c.string(m, "type", path, None, MOTIONS)
    allowed = {
        "linear": ["type", "velocity"],
        "waypoints": ["type", "waypoints", "speed", "loop"],
        "circle": ["type", "center", "radius", "angular_speed"],
    }.get(kind, ["type", "velocity", "waypoints", "speed", "loop", "center", "radius", "angular_speed"])
    c.keys(m, path, allowed)
    if kind == "linear":
        v = c.vector(m, "velocity", path, 3)
        return {"type": kind, "velocity": _lst(v)}, Motion(kind, velocity=v) if v is not None else None
    if kind == "waypoints":
        wps = c.listing(m, "waypoints", path, required=True)
        pts = [c.vector_value(w, f"{path}.waypoints[{i}]", 3) for i, w in enumerate(wps)]
        if not pts and "waypoints" in m:
            c.add(f"{path}.waypoints", "needs at least one waypoint")
        speed = c.number(m, "speed", path, None, positive=True)
        loop = c.boolean(m, "loop", path, False)
        if any(p is None for p in pts) or not pts or speed is None:
            return None, None
        arr = np.array(pts)
        return (
            {"type": kind, "waypoints": arr.tolist(), "speed": speed, "loop": loop},
            Motion(kind, waypoints=arr, speed=speed, loop=loop),
        )
    if kind == "circle":
        center = c.vector(m, "center", path, 3)
        radius = c.number(m, "radius", path, None, positive=True)
        omega = c.number(m, "angular_speed", path, None)
        if center is None or radius is None or omega is None:
            return None, None
        return (
            {"type": kind, "center": center.tolist(), "radius": radius, "angular_speed": omega},
            Motion(kind, center=center, radius=radius, angular_speed=omega),
        )
    return None, None


def _lst(v: np.ndarray | None) -> list | None:
    return None if v is None else v.tolist()


def _resolve_obstacle(c: Checker, o: Any, path: str, base_dir: Path) -> tuple[dict | None, Obstacle | None]:
    if not isinstance(o, dict):
        c.add(path, f"expected a mapping, got {typename(o)}")
        return None, None
    shape = c.string(o, "shape", path, None, SHAPES)
    per_shape = {s.name: [k.name for k in s.keys] for s in bodies.SHAPES}
    per_shape["mesh"] = ["file", "scale"]
    common = ["id", "shape", "position", "rotation", "motion"]
    if shape is None:
        c.keys(o, path, common + sorted({k for v in per_shape.values() for k in v}))
    else:
        c.keys(o, path, common + per_shape[shape])
    oid = c.string(o, "id", path)
    pos = c.vector(o, "position", path, 3)
    rot = c.vector(o, "rotation", path, 3, [0.0, 0.0, 0.0])
    out: dict[str, Any] = {"id": oid, "shape": shape, "position": _lst(pos), "rotation": _lst(rot)}
    kw: dict[str, Any] = {}
    params: dict[str, Any] = {}
    for key in bodies.shape(shape).keys if shape is not None else ():
        args = (o, key.name, path, 3 if key.vector else None)  # a vector's length, a number's default
        params[key.name] = (c.vector if key.vector else c.number)(*args, positive=key.positive, nonneg=True)
        out[key.name] = _lst(params[key.name]) if key.vector else params[key.name]
    kw.update({k: v for k, v in params.items() if k in ("radius", "size", "height")})  # model fields too
    if shape == "mesh":
        file = c.string(o, "file", path)
        scale_raw = o.get("scale", 1.0)
        if isinstance(scale_raw, (int, float)) and not isinstance(scale_raw, bool):
            scale = np.full(3, float(scale_raw))
            if scale_raw <= 0:
                c.add(f"{path}.scale", f"must be > 0, got {scale_raw}")
        else:
            scale = c.vector_value(scale_raw, f"{path}.scale", 3, positive=True)
        out["file"] = file
        out["scale"] = scale_raw
        if file is not None and scale is not None:
            loaded = load_mesh(c, path, file, base_dir, scale)
            if loaded is not None:
                kw["vertices"], kw["faces"] = loaded
    motion = None
    if o.get("motion") is not None:
        out["motion"], motion = _resolve_motion(c, o["motion"], f"{path}.motion")
    if any(v is None for v in (oid, shape, pos, rot, *kw.values(), *params.values())):
        return out, None
    if shape == "mesh" and "vertices" not in kw:
        return out, None
    R = rotation_matrix(rot)
    obst = Obstacle(
        id=oid,
        shape=shape,
        position=pos,
        rotation=R,
        rotation_deg=tuple(rot.tolist()),
        motion=motion,
        params=params if shape != "mesh" else None,
        **kw,
    )
    if shape == "mesh":
        # The log inlines mesh geometry in world coordinates (scale, rotation, position applied).
        out["vertices"] = (kw["vertices"] @ R.T + pos).round(9).tolist()
        out["faces"] = kw["faces"].tolist()
    return out, obst


def _resolve_threat(c: Checker, t: Any, path: str) -> tuple[dict | None, Threat | None]:
    if not c.keys(t, path, ["kind", "position", "r_min", "r_max", "weight", "avoid"]):
        return None, None
    kind = c.string(t, "kind", path, None, THREAT_KINDS)
    pos = c.vector(t, "position", path, 3)
    r_min = c.number(t, "r_min", path, 0.0, nonneg=True)
    r_max = c.number(t, "r_max", path, None, positive=True)
    weight = c.number(t, "weight", path, 1.0, nonneg=True)
    if r_min is not None and r_max is not None and r_min >= r_max:
        c.add(path, f"r_min ({r_min:g}) must be below r_max ({r_max:g})")
    avoid = c.boolean(t, "avoid", path, False)
    if avoid and r_min is not None and r_min <= 0:
        c.add(f"{path}.avoid", "needs a core to keep out of: r_min > 0")
    out = {"kind": kind, "position": _lst(pos), "r_min": r_min, "r_max": r_max, "weight": weight}
    if "avoid" in t:  # written only when given: logs of worlds without the key stay as they were
        out["avoid"] = avoid
    if None in (kind, r_min, r_max, weight, avoid) or pos is None:
        return out, None
    return out, Threat(kind, pos, r_min, r_max, weight, bool(avoid))


def parse_world(
    raw: Any,
    base_dir: str | Path = ".",
    source: str | Path | None = None,
    optimizer_names: list[str] | None = None,
) -> World:
    """Validate and resolve an already-parsed world mapping (see :func:`load_world`)."""
    if optimizer_names is None:
        optimizer_names = optimizers.available()
    base_dir = Path(base_dir)
    label = str(source) if source is not None else "world"
    c = Checker()
    top_keys = ["name", "seed", "bounds", "sim", "terrain", "obstacles", "threats", "agent_defaults",
                "agents", "planner", "log", "tracker", "origin", "comms", "sensing"]  # fmt: skip
    if not c.keys(raw, "", top_keys, required=("name", "bounds", "agents")):
        raise WorldError([p.lstrip(": ") or p for p in c.problems] or ["the file is empty"], label)

    name = c.string(raw, "name", "")
    seed_raw = raw.get("seed", 0)
    if isinstance(seed_raw, bool) or not isinstance(seed_raw, int) or seed_raw < 0:
        c.add("seed", f"expected a whole number >= 0, got {seed_raw!r}")
        seed_raw = 0
    bmin = bmax = None
    if isinstance(raw.get("bounds"), dict) and c.keys(
        raw["bounds"], "bounds", ["min", "max"], ("min", "max")
    ):
        bmin = c.vector(raw["bounds"], "min", "bounds", 3) if "min" in raw["bounds"] else None
        bmax = c.vector(raw["bounds"], "max", "bounds", 3) if "max" in raw["bounds"] else None
        if bmin is not None and bmax is not None and np.any(bmin >= bmax):
            axes = ", ".join("xyz"[i] for i in np.flatnonzero(bmin >= bmax))
            c.add("bounds", f"min is not below max on axis {axes}")
            bmin = bmax = None
    elif raw.get("bounds") is not None and not isinstance(raw.get("bounds"), dict):
        c.add("bounds", f"expected a mapping, got {typename(raw['bounds'])}")

    sim = dict(SIM_DEFAULTS)
    if raw.get("sim") is not None and c.keys(raw["sim"], "sim", list(SIM_DEFAULTS)):
        for k, dv in SIM_DEFAULTS.items():
            if dv is None and raw["sim"].get(k) is None:
                continue  # derived from the agents once they are known
            sim[k] = c.number(raw["sim"], k, "sim", dv, positive=True)

    peaks: list[Peak] = []
    terrain_out = None
    clearance = 0.0
    if raw.get("terrain") is not None and c.keys(raw["terrain"], "terrain", ["peaks", "clearance"]):
        t = raw["terrain"]
        clearance = c.number(t, "clearance", "terrain", 5.0, nonneg=True)
        terrain_out = {"peaks": [], "clearance": clearance}
        for i, pk in enumerate(c.listing(t, "peaks", "terrain")):
            p = f"terrain.peaks[{i}]"
            if not c.keys(pk, p, ["center", "height", "spread"], ("center", "height")):
                continue
            ctr = c.vector(pk, "center", p, 2) if "center" in pk else None
            h = c.number(pk, "height", p, None, nonneg=True) if "height" in pk else None
            spread = c.vector(pk, "spread", p, 2, [1.0, 1.0], positive=True)
            if ctr is not None and h is not None and spread is not None:
                peaks.append(Peak(ctr, h, spread))
                terrain_out["peaks"].append({"center": ctr.tolist(), "height": h, "spread": spread.tolist()})

    obstacles: list[Obstacle] = []
    obstacles_out: list[dict] = []
    seen_ids: dict[str, str] = {}
    for i, o in enumerate(c.listing(raw, "obstacles", "")):
        out, obst = _resolve_obstacle(c, o, f"obstacles[{i}]", base_dir)
        oid = out.get("id") if out else None
        if oid is not None:
            if oid in seen_ids:
                c.add(f"obstacles[{i}].id", f"'{oid}' is already used by {seen_ids[oid]}")
            seen_ids[oid] = f"obstacles[{i}]"
        if out is not None:
            obstacles_out.append(out)
        if obst is not None:
            obstacles.append(obst)

    threats, threats_out = [], []
    for i, t in enumerate(c.listing(raw, "threats", "")):
        out, th = _resolve_threat(c, t, f"threats[{i}]")
        if out is not None:
            threats_out.append(out)
        if th is not None:
            threats.append(th)

    agent_keys = [*AGENT_DEFAULTS, *FIXED_WING_KEYS]
    defaults = copy.deepcopy(AGENT_DEFAULTS)
    if raw.get("agent_defaults") is not None and c.keys(raw["agent_defaults"], "agent_defaults", agent_keys):
        defaults = _resolve_agent_params(c, raw["agent_defaults"], "agent_defaults", defaults)

    agents: list[AgentSpec] = []
    agents_out: list[dict] = []
    agent_ids: dict[str, str] = {}
    agent_list = c.listing(raw, "agents", "", required=False)
    if "agents" in raw and raw["agents"] is not None and isinstance(raw["agents"], list) and not agent_list:
        c.add("agents", "needs at least one agent")
    for i, a in enumerate(agent_list):
        p = f"agents[{i}]"
        if not c.keys(a, p, ["id", "start", "goal"] + agent_keys, ("id", "start", "goal")):
            continue
        aid = c.string(a, "id", p) if "id" in a else None
        if aid is not None:
            if aid in agent_ids:
                c.add(f"{p}.id", f"'{aid}' is already used by {agent_ids[aid]}")
            agent_ids[aid] = p
        start = c.vector(a, "start", p, 3) if "start" in a else None
        goal = c.vector(a, "goal", p, 3) if "goal" in a else None
        params = _resolve_agent_params(c, a, p, defaults)
        if params["separation"] is None and params["radius"] is not None:
            params["separation"] = default_separation(params["radius"])
        if params["min_altitude"] is None and None not in _flat_values({**params, "min_altitude": 0.0}):
            params["min_altitude"] = round(default_min_altitude(params), 6)
        if "speed" in a or "model" in a:  # what the agent inherits is checked once, in agent_defaults
            _check_agent_params(c, params, p)
        params = airframe_keys(params, complete=None not in _flat_values(params))
        resolved = {"id": aid, "start": _lst(start), "goal": _lst(goal), **copy.deepcopy(params)}
        agents_out.append(resolved)
        if aid is None or start is None or goal is None or None in _flat_values(params):
            continue
        agents.append(
            AgentSpec(
                id=aid,
                start=start,
                goal=goal,
                model=params["model"],
                radius=params["radius"],
                speed_min=params["speed"]["min"],
                speed_max=params["speed"]["max"],
                speed_cruise=params["speed"]["cruise"],
                max_accel=params["max_accel"],
                min_turn_radius=params["min_turn_radius"],
                max_climb_angle=math.radians(params["max_climb_angle"]),
                min_altitude=params["min_altitude"],
                separation=np.asarray(params["separation"], dtype=float),
                **fixed_wing_spec(params),
            )
        )
    _check_defaults_alone(c, defaults)

    planner = _resolve_planner(c, raw.get("planner"), optimizer_names)
    if planner["apf"]["influence"] is None:
        planner["apf"]["influence"] = default_influence(agents)
    default_field_scale(planner["apf"])
    planner["stuck"]["min_progress"] = planner["stuck"]["min_progress"] or default_stuck_progress(agents)
    if sim["goal_tolerance"] is None:
        sim["goal_tolerance"] = default_goal_tolerance(agents)
    _check_planner_sections(c, planner)

    log = dict(LOG_DEFAULTS)
    if raw.get("log") is not None and c.keys(raw["log"], "log", list(LOG_DEFAULTS)):
        log["path"] = c.string(raw["log"], "path", "log", LOG_DEFAULTS["path"])
        log["foxglove"] = c.boolean(raw["log"], "foxglove", "log", True)
        log["flush_interval"] = c.number(raw["log"], "flush_interval", "log", 1.0, positive=True)

    # The quadrotor tracker's vehicle and gains (python -m swarmplan.track reads them from /world).
    tracker_cfg, tracker_problems = parse_tracker(raw.get("tracker"), "tracker")
    for problem in tracker_problems:
        path, _, msg = problem.partition(": ")
        c.add(path, msg)

    origin = resolve_origin(c, raw.get("origin"))
    comms_out, comms = resolve_comms(c, raw.get("comms"))
    sensing_out, sensing = resolve_sensing(c, raw.get("sensing"))

    # Geometry checks need a valid frame; run them only when the parts they use are sound.
    check_placements(c, agents, agent_list, obstacles, bmin, bmax, peaks)

    if c.problems:
        raise WorldError(c.problems, label)

    resolved = {
        "name": name,
        "seed": int(seed_raw),
        "bounds": {"min": bmin.tolist(), "max": bmax.tolist()},
        "sim": sim,
        "terrain": terrain_out,
        "obstacles": obstacles_out,
        "threats": threats_out,
        "agent_defaults": defaults,
        "agents": agents_out,
        "log": log,
        "tracker": tracker_cfg.to_dict(),
    }
    for key, value in (("origin", origin), ("comms", comms_out), ("sensing", sensing_out)):
        if value is not None:  # written only when given: logs of worlds without them stay as they were
            resolved[key] = value
    return World(
        name=name,
        seed=int(seed_raw),
        bounds_min=bmin,
        bounds_max=bmax,
        dt=sim["dt"],
        max_time=sim["max_time"],
        goal_tolerance=sim["goal_tolerance"],
        peaks=tuple(peaks),
        terrain_clearance=clearance,
        obstacles=tuple(obstacles),
        threats=tuple(threats),
        agents=tuple(agents),
        planner_config=planner_config(planner),
        log_path=log["path"],
        resolved=resolved,
        source=Path(source) if source is not None else None,
        comms=comms,
        sensing=sensing,
    )


def _flat_values(d: dict) -> list:
    out = []
    for v in d.values():
        out.extend(_flat_values(v) if isinstance(v, dict) else [v])
    return out


def _check_defaults_alone(c: Checker, defaults: dict) -> None:
    _check_agent_params(c, defaults, "agent_defaults")


def _check_planner_sections(c: Checker, planner: dict[str, Any]) -> None:
    """``planner.escape`` and ``planner.global`` (a non-mapping was reported already)."""
    for section, check in (("escape", check_escape), ("global", check_global)):
        if isinstance(planner.get(section, {}), dict):
            try:
                check(planner)
            except WorldError as exc:
                for problem in exc.problems:
                    path, _, msg = problem.partition(": ")
                    c.add(path, msg)
