"""World files: load, validate and resolve a YAML world into typed, immutable objects.

The contract is ``shared/spec/world-format.md``. Validation collects *every* problem with
its path (``agents[1].start: inside obstacle 'tower'``) and suggests the nearest key for
typos; :class:`WorldError` carries the list. The resolved world (defaults applied, mesh
geometry loaded) is also kept as a plain dict for the log's ``/world`` channel.
"""

from __future__ import annotations

import copy
import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

SHAPES = ("sphere", "box", "cylinder", "capsule", "mesh")
MOTIONS = ("linear", "waypoints", "circle")
MODELS = ("multirotor", "fixed_wing")
THREAT_KINDS = ("radar", "missile", "artillery", "weather")
PLANNER_MODES = ("reactive", "global")


class WorldError(Exception):
    """A world file with problems; ``problems`` lists every one as ``path: message``."""

    def __init__(self, problems: list[str], source: str = "world"):
        self.problems = list(problems)
        self.source = source
        super().__init__(f"{source}: {len(problems)} problem(s)\n" + "\n".join(f"  {p}" for p in problems))


# ----------------------------------------------------------------------------- typed world


@dataclass(frozen=True)
class Motion:
    type: str
    velocity: np.ndarray | None = None  # linear
    waypoints: np.ndarray | None = None  # waypoints (k, 3), path starts at the obstacle's position
    speed: float = 0.0
    loop: bool = False
    center: np.ndarray | None = None  # circle
    radius: float = 0.0
    angular_speed: float = 0.0


@dataclass(frozen=True)
class Obstacle:
    id: str
    shape: str
    position: np.ndarray  # centre at t = 0 (mesh: origin of the mesh frame)
    rotation: np.ndarray  # 3x3 matrix, R = Rz(yaw) Ry(pitch) Rx(roll)
    rotation_deg: tuple[float, float, float]
    radius: float = 0.0
    size: np.ndarray | None = None  # box full extents
    height: float = 0.0  # cylinder full height; capsule straight section
    vertices: np.ndarray | None = None  # mesh vertices in the local frame, scale applied
    faces: np.ndarray | None = None
    motion: Motion | None = None

    @property
    def moving(self) -> bool:
        return self.motion is not None

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about ``position`` containing the whole shape."""
        if self.shape == "sphere":
            return self.radius
        if self.shape == "box":
            return float(np.linalg.norm(self.size) / 2)
        if self.shape == "cylinder":
            return math.hypot(self.radius, self.height / 2)
        if self.shape == "capsule":
            return self.radius + self.height / 2
        return float(np.max(np.linalg.norm(self.vertices, axis=1)))


@dataclass(frozen=True)
class Peak:
    center: np.ndarray  # (2,)
    height: float
    spread: np.ndarray  # (2,)


@dataclass(frozen=True)
class Threat:
    kind: str
    position: np.ndarray
    r_min: float
    r_max: float
    weight: float


@dataclass(frozen=True)
class AgentSpec:
    id: str
    start: np.ndarray
    goal: np.ndarray
    model: str
    radius: float
    speed_min: float
    speed_max: float
    speed_cruise: float
    max_accel: float
    min_turn_radius: float
    max_climb_angle: float  # radians
    min_altitude: float
    separation: np.ndarray  # (3,)


@dataclass(frozen=True)
class World:
    name: str
    seed: int
    bounds_min: np.ndarray
    bounds_max: np.ndarray
    dt: float
    max_time: float
    goal_tolerance: float
    peaks: tuple[Peak, ...]
    terrain_clearance: float
    obstacles: tuple[Obstacle, ...]
    threats: tuple[Threat, ...]
    agents: tuple[AgentSpec, ...]
    planner: dict[str, Any]
    log_path: str
    resolved: dict[str, Any] = field(repr=False)  # the /world message (before seed/version)
    source: Path | None = None

    @property
    def static_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if not o.moving)

    @property
    def moving_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if o.moving)

    def terrain_height(self, xy: np.ndarray) -> np.ndarray:
        """Terrain height z(x, y) of world-format eq. (sum of Gaussian peaks); 0 without terrain."""
        xy = np.asarray(xy, dtype=float)
        z = np.zeros(xy.shape[:-1])
        for pk in self.peaks:
            u = (xy[..., 0] - pk.center[0]) / pk.spread[0]
            v = (xy[..., 1] - pk.center[1]) / pk.spread[1]
            z = z + pk.height * np.exp(-(u * u) - v * v)
        return z

    def terrain_gradient(self, xy: np.ndarray) -> np.ndarray:
        """(dz/dx, dz/dy) of the terrain at ``xy`` (..., 2)."""
        xy = np.asarray(xy, dtype=float)
        g = np.zeros(xy.shape)
        for pk in self.peaks:
            u = (xy[..., 0] - pk.center[0]) / pk.spread[0]
            v = (xy[..., 1] - pk.center[1]) / pk.spread[1]
            e = pk.height * np.exp(-(u * u) - v * v)
            g[..., 0] += -2 * u / pk.spread[0] * e
            g[..., 1] += -2 * v / pk.spread[1] * e
        return g

    def with_overrides(self, **changes: Any) -> World:
        """A copy with some top-level fields replaced (e.g. ``max_time``); ``resolved`` follows."""
        import dataclasses

        resolved = copy.deepcopy(self.resolved)
        if "max_time" in changes:
            resolved["sim"]["max_time"] = changes["max_time"]
        if "planner" in changes:
            resolved["planner"] = copy.deepcopy(changes["planner"])
        if "seed" in changes:
            resolved["seed"] = changes["seed"]
        return dataclasses.replace(self, resolved=resolved, **changes)


# ----------------------------------------------------------------------------- defaults

AGENT_DEFAULTS: dict[str, Any] = {
    "model": "multirotor",
    "radius": 1.5,
    "speed": {"min": 0.0, "max": 15.0, "cruise": 10.0},
    "max_accel": 5.0,
    "min_turn_radius": 20.0,
    "max_climb_angle": 45.0,
    "min_altitude": 5.0,
    "separation": [5.0, 5.0, 2.0],
}

PLANNER_DEFAULTS: dict[str, Any] = {
    "mode": "reactive",
    "apf": {
        "k_att": 1.0,
        "k_rep": 50.0,
        "influence": 40.0,
        "k_agent": 20.0,
        "quadratic_radius": 10.0,  # m: attraction is quadratic inside, conic outside
        "goal_power": 2.0,  # n of the goal-distance factor rho_goal^n in the repulsion
        "k_moving": 2.0,  # weight of the relative-velocity term for moving obstacles
        "horizon": 4.0,  # s: how far ahead moving obstacles and agents are predicted
    },
    "stuck": {"window": 3.0, "min_progress": 0.5},
    "optimizer": {"name": "rscdwoa", "population": 30, "iterations": 100, "params": {}},
    "smoothing": {"enabled": True},
}

SIM_DEFAULTS = {"dt": 0.1, "max_time": 120.0, "goal_tolerance": 2.0}
LOG_DEFAULTS = {"path": "logs/{name}-{seed}.mcap", "foxglove": True, "flush_interval": 1.0}


# ----------------------------------------------------------------------------- validation helpers


class _Checker:
    """Collects problems while walking the raw YAML tree."""

    def __init__(self) -> None:
        self.problems: list[str] = []

    def add(self, path: str, msg: str) -> None:
        # Several checks may reach the same missing key (the required-keys pass and the typed
        # read that follows it); the user should see each problem once.
        problem = f"{path}: {msg}"
        if problem not in self.problems:
            self.problems.append(problem)

    def keys(
        self, node: Any, path: str, allowed: list[str] | tuple[str, ...], required: tuple[str, ...] = ()
    ) -> bool:
        if not isinstance(node, dict):
            self.add(path, f"expected a mapping, got {_typename(node)}")
            return False
        for k in node:
            if k not in allowed:
                close = difflib.get_close_matches(str(k), list(allowed), n=1, cutoff=0.5)
                hint = f" (did you mean '{close[0]}'?)" if close else f" (known keys: {', '.join(allowed)})"
                self.add(_join(path, str(k)), f"unknown key{hint}")
        for k in required:
            if k not in node or node[k] is None:
                self.add(_join(path, k), "required key is missing")
        return True

    def number(
        self,
        node: dict,
        key: str,
        path: str,
        default: float | None = None,
        *,
        positive: bool = False,
        nonneg: bool = False,
        lo: float | None = None,
        hi: float | None = None,
    ) -> float | None:
        p = _join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
            return default
        v = node[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.add(p, f"expected a number, got {_typename(v)} {v!r}")
            return default
        v = float(v)
        if positive and v <= 0:
            self.add(p, f"must be > 0, got {v:g}")
        elif nonneg and v < 0:
            self.add(p, f"must be >= 0, got {v:g}")
        if lo is not None and v < lo:
            self.add(p, f"must be >= {lo:g}, got {v:g}")
        if hi is not None and v > hi:
            self.add(p, f"must be <= {hi:g}, got {v:g}")
        return v

    def vector(
        self,
        node: dict,
        key: str,
        path: str,
        n: int,
        default: Any = None,
        *,
        positive: bool = False,
        nonneg: bool = False,
    ) -> np.ndarray | None:
        p = _join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
                return None
            return np.asarray(default, dtype=float)
        return self.vector_value(node[key], p, n, positive=positive, nonneg=nonneg)

    def vector_value(
        self, v: Any, p: str, n: int, *, positive: bool = False, nonneg: bool = False
    ) -> np.ndarray | None:
        if (
            not isinstance(v, (list, tuple))
            or len(v) != n
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) for x in v)
        ):
            self.add(p, f"expected a list of {n} numbers, got {v!r}")
            return None
        arr = np.asarray(v, dtype=float)
        if positive and np.any(arr <= 0):
            self.add(p, f"every value must be > 0, got {v!r}")
        elif nonneg and np.any(arr < 0):
            self.add(p, f"every value must be >= 0, got {v!r}")
        return arr

    def string(
        self, node: dict, key: str, path: str, default: str | None = None, choices: tuple[str, ...] = ()
    ) -> str | None:
        p = _join(path, key)
        if key not in node or node[key] is None:
            if default is None:
                self.add(p, "required key is missing")
            return default
        v = node[key]
        if not isinstance(v, str) or not v:
            self.add(p, f"expected a non-empty string, got {_typename(v)} {v!r}")
            return default
        if choices and v not in choices:
            close = difflib.get_close_matches(v, list(choices), n=1, cutoff=0.5)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            self.add(p, f"'{v}' is not one of {', '.join(choices)}{hint}")
            return default
        return v

    def boolean(self, node: dict, key: str, path: str, default: bool) -> bool:
        if key not in node or node[key] is None:
            return default
        v = node[key]
        if not isinstance(v, bool):
            self.add(_join(path, key), f"expected true or false, got {v!r}")
            return default
        return v

    def listing(self, node: dict, key: str, path: str, required: bool = False) -> list:
        if key not in node or node[key] is None:
            if required:
                self.add(_join(path, key), "required key is missing")
            return []
        v = node[key]
        if not isinstance(v, list):
            self.add(_join(path, key), f"expected a list, got {_typename(v)}")
            return []
        return v


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _typename(v: Any) -> str:
    return {dict: "mapping", list: "list", str: "string", bool: "boolean", type(None): "nothing"}.get(
        type(v), type(v).__name__
    )


def rotation_matrix(roll_pitch_yaw_deg: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles in degrees."""
    r, p, y = (math.radians(float(a)) for a in roll_pitch_yaw_deg)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrix → quaternion [qx, qy, qz, qw]."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat()


# ----------------------------------------------------------------------------- sections


def _resolve_planner(c: _Checker, raw: Any, optimizer_names: list[str] | None) -> dict[str, Any]:
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
        for k in ("population", "iterations"):
            v = c.number(
                opt, k, "planner.optimizer", planner["optimizer"][k], lo=2 if k == "population" else 1
            )
            if v is not None and v != int(v):
                c.add(f"planner.optimizer.{k}", f"must be a whole number, got {v:g}")
            planner["optimizer"][k] = int(v) if v is not None else planner["optimizer"][k]
        params = opt.get("params") or {}
        if not isinstance(params, dict):
            c.add("planner.optimizer.params", f"expected a mapping, got {_typename(params)}")
            params = {}
        planner["optimizer"]["params"] = dict(params)
        if name not in (None, "none") and names and name in names:
            try:
                from swarmplan import optimizers

                optimizers.make(name, population=planner["optimizer"]["population"], **params)
            except ValueError as exc:
                c.add("planner.optimizer.params", str(exc))
    sm = raw.get("smoothing")
    if sm is not None and c.keys(sm, "planner.smoothing", ["enabled"]):
        planner["smoothing"]["enabled"] = c.boolean(sm, "enabled", "planner.smoothing", True)
    for section in extra_sections:
        if section in raw:
            if not isinstance(raw[section], dict):
                c.add(f"planner.{section}", f"expected a mapping, got {_typename(raw[section])}")
            else:
                planner[section] = copy.deepcopy(raw[section])
    return planner


def _resolve_agent_params(c: _Checker, node: dict, path: str, base: dict[str, Any]) -> dict[str, Any]:
    """Merge agent parameter keys of ``node`` over ``base`` (both in world-file form)."""
    out = copy.deepcopy(base)
    if "model" in node:
        out["model"] = c.string(node, "model", path, base["model"], MODELS)
    for k in ("radius", "max_accel", "min_turn_radius"):
        if k in node:
            out[k] = c.number(node, k, path, base[k], positive=True)
    if "min_altitude" in node:
        out["min_altitude"] = c.number(node, "min_altitude", path, base["min_altitude"], nonneg=True)
    if "max_climb_angle" in node:
        v = c.number(node, "max_climb_angle", path, base["max_climb_angle"], positive=True)
        if v is not None and v > 90:
            c.add(_join(path, "max_climb_angle"), f"must be <= 90 degrees, got {v:g}")
        out["max_climb_angle"] = v
    if "separation" in node:
        v = c.vector_value(node["separation"], _join(path, "separation"), 3, nonneg=True)
        out["separation"] = v.tolist() if v is not None else base["separation"]
    if "speed" in node:
        sp = node["speed"]
        if c.keys(sp, _join(path, "speed"), ["min", "max", "cruise"]):
            for k in ("min", "max", "cruise"):
                if k in sp:
                    out["speed"][k] = c.number(sp, k, _join(path, "speed"), base["speed"][k], nonneg=True)
    return out


def _check_agent_params(c: _Checker, a: dict[str, Any], path: str) -> None:
    sp = a["speed"]
    if None in (sp["min"], sp["max"], sp["cruise"]):
        return
    if sp["max"] <= 0:
        c.add(f"{path}.speed.max", f"must be > 0, got {sp['max']:g}")
    if sp["min"] > sp["max"]:
        c.add(f"{path}.speed", f"min ({sp['min']:g}) is above max ({sp['max']:g})")
    elif not sp["min"] <= sp["cruise"] <= sp["max"]:
        c.add(
            f"{path}.speed.cruise",
            f"must lie between min ({sp['min']:g}) and max ({sp['max']:g}), got {sp['cruise']:g}",
        )
    if a["model"] == "fixed_wing" and sp["min"] <= 0:
        c.add(f"{path}.speed.min", "a fixed_wing agent needs a speed floor > 0")


def _resolve_motion(c: _Checker, m: Any, path: str) -> tuple[dict | None, Motion | None]:
    if not isinstance(m, dict):
        c.add(path, f"expected a mapping, got {_typename(m)}")
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


def _load_mesh(c: _Checker, path: str, file: str, base_dir: Path, scale: np.ndarray) -> tuple | None:
    import trimesh

    fp = (base_dir / file).resolve()
    if not fp.is_file():
        c.add(f"{path}.file", f"mesh file not found: {fp}")
        return None
    try:
        mesh = trimesh.load(str(fp), force="mesh")
    except Exception as exc:  # trimesh raises many kinds; all mean "cannot read"
        c.add(f"{path}.file", f"cannot read mesh {fp}: {exc}")
        return None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        c.add(f"{path}.file", f"{fp} holds no triangles")
        return None
    return np.asarray(mesh.vertices, dtype=float) * scale, np.asarray(mesh.faces, dtype=np.int64)


def _resolve_obstacle(c: _Checker, o: Any, path: str, base_dir: Path) -> tuple[dict | None, Obstacle | None]:
    if not isinstance(o, dict):
        c.add(path, f"expected a mapping, got {_typename(o)}")
        return None, None
    shape = c.string(o, "shape", path, None, SHAPES)
    per_shape = {
        "sphere": ["radius"],
        "box": ["size"],
        "cylinder": ["radius", "height"],
        "capsule": ["radius", "height"],
        "mesh": ["file", "scale"],
    }
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
    if shape in ("sphere", "cylinder", "capsule"):
        kw["radius"] = c.number(o, "radius", path, None, positive=True)
        out["radius"] = kw["radius"]
    if shape in ("cylinder", "capsule"):
        kw["height"] = c.number(o, "height", path, None, positive=shape == "cylinder", nonneg=True)
        out["height"] = kw["height"]
    if shape == "box":
        kw["size"] = c.vector(o, "size", path, 3, positive=True)
        out["size"] = _lst(kw["size"])
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
            loaded = _load_mesh(c, path, file, base_dir, scale)
            if loaded is not None:
                kw["vertices"], kw["faces"] = loaded
    motion = None
    if o.get("motion") is not None:
        out["motion"], motion = _resolve_motion(c, o["motion"], f"{path}.motion")
    if any(v is None for v in (oid, shape, pos, rot, *kw.values())):
        return out, None
    if shape == "mesh" and "vertices" not in kw:
        return out, None
    R = rotation_matrix(rot)
    obst = Obstacle(
        id=oid, shape=shape, position=pos, rotation=R, rotation_deg=tuple(rot.tolist()), motion=motion, **kw
    )
    if shape == "mesh":
        # The log inlines mesh geometry in world coordinates (scale, rotation, position applied).
        out["vertices"] = (kw["vertices"] @ R.T + pos).round(9).tolist()
        out["faces"] = kw["faces"].tolist()
    return out, obst


def _resolve_threat(c: _Checker, t: Any, path: str) -> tuple[dict | None, Threat | None]:
    if not c.keys(t, path, ["kind", "position", "r_min", "r_max", "weight"]):
        return None, None
    kind = c.string(t, "kind", path, None, THREAT_KINDS)
    pos = c.vector(t, "position", path, 3)
    r_min = c.number(t, "r_min", path, 0.0, nonneg=True)
    r_max = c.number(t, "r_max", path, None, positive=True)
    weight = c.number(t, "weight", path, 1.0, nonneg=True)
    if r_min is not None and r_max is not None and r_min >= r_max:
        c.add(path, f"r_min ({r_min:g}) must be below r_max ({r_max:g})")
    out = {"kind": kind, "position": _lst(pos), "r_min": r_min, "r_max": r_max, "weight": weight}
    if None in (kind, r_min, r_max, weight) or pos is None:
        return out, None
    return out, Threat(kind, pos, r_min, r_max, weight)


# ----------------------------------------------------------------------------- entry points


def load_world(path: str | Path, optimizer_names: list[str] | None = None) -> World:
    """Read, validate and resolve the world file at ``path``; raise :class:`WorldError` on any problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise WorldError([f"cannot read file: {exc.strerror or exc}"], str(path)) from None
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise WorldError([f"{where}invalid YAML: {getattr(exc, 'problem', exc)}"], str(path)) from None
    return parse_world(raw, base_dir=path.parent, source=path, optimizer_names=optimizer_names)


def parse_world(
    raw: Any,
    base_dir: str | Path = ".",
    source: str | Path | None = None,
    optimizer_names: list[str] | None = None,
) -> World:
    """Validate and resolve an already-parsed world mapping (see :func:`load_world`)."""
    if optimizer_names is None:
        from swarmplan import optimizers

        optimizer_names = optimizers.available()
    base_dir = Path(base_dir)
    label = str(source) if source is not None else "world"
    c = _Checker()
    top_keys = [
        "name",
        "seed",
        "bounds",
        "sim",
        "terrain",
        "obstacles",
        "threats",
        "agent_defaults",
        "agents",
        "planner",
        "log",
    ]
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
        c.add("bounds", f"expected a mapping, got {_typename(raw['bounds'])}")

    sim = dict(SIM_DEFAULTS)
    if raw.get("sim") is not None and c.keys(raw["sim"], "sim", list(SIM_DEFAULTS)):
        for k, dv in SIM_DEFAULTS.items():
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

    agent_keys = list(AGENT_DEFAULTS)
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
        _check_agent_params(c, params, p)
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
            )
        )
    _check_defaults_alone(c, defaults)

    planner = _resolve_planner(c, raw.get("planner"), optimizer_names)

    log = dict(LOG_DEFAULTS)
    if raw.get("log") is not None and c.keys(raw["log"], "log", list(LOG_DEFAULTS)):
        log["path"] = c.string(raw["log"], "path", "log", LOG_DEFAULTS["path"])
        log["foxglove"] = c.boolean(raw["log"], "foxglove", "log", True)
        log["flush_interval"] = c.number(raw["log"], "flush_interval", "log", 1.0, positive=True)

    # Geometry checks need a valid frame; run them only when the parts they use are sound.
    _check_placements(c, agents, agent_list, obstacles, bmin, bmax, peaks)

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
        "planner": planner,
        "log": log,
    }
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
        planner=planner,
        log_path=log["path"],
        resolved=resolved,
        source=Path(source) if source is not None else None,
    )


def _flat_values(d: dict) -> list:
    out = []
    for v in d.values():
        out.extend(_flat_values(v) if isinstance(v, dict) else [v])
    return out


def _check_defaults_alone(c: _Checker, defaults: dict) -> None:
    sp = defaults["speed"]
    if None not in (sp["min"], sp["max"]) and sp["min"] > sp["max"]:
        c.add("agent_defaults.speed", f"min ({sp['min']:g}) is above max ({sp['max']:g})")


def _check_placements(
    c: _Checker,
    agents: list[AgentSpec],
    raw_agents: list,
    obstacles: list[Obstacle],
    bmin: np.ndarray | None,
    bmax: np.ndarray | None,
    peaks: list[Peak],
) -> None:
    from swarmplan.geometry.shapes import signed_distance

    index = {a.get("id"): i for i, a in enumerate(raw_agents) if isinstance(a, dict)}
    static = [o for o in obstacles if not o.moving]
    for a in agents:
        p = f"agents[{index.get(a.id, '?')}]"
        for key, point, against in (("start", a.start, obstacles), ("goal", a.goal, static)):
            if bmin is not None and bmax is not None and (np.any(point < bmin) or np.any(point > bmax)):
                c.add(f"{p}.{key}", f"{point.tolist()} is outside bounds {bmin.tolist()}..{bmax.tolist()}")
                continue
            for o in against:
                d = float(signed_distance(o, point[None, :])[0])
                if d < a.radius:
                    what = "inside" if d < 0 else "touching"
                    c.add(f"{p}.{key}", f"{what} obstacle '{o.id}' (clearance {d - a.radius:.2f} m)")
            if peaks:
                ground = sum(
                    pk.height
                    * math.exp(
                        -(((point[0] - pk.center[0]) / pk.spread[0]) ** 2)
                        - ((point[1] - pk.center[1]) / pk.spread[1]) ** 2
                    )
                    for pk in peaks
                )
                if point[2] - ground < a.radius:
                    c.add(f"{p}.{key}", f"below the terrain (terrain height {ground:.2f} m at this point)")
