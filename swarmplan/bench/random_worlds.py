"""Random valid worlds of three classes of aircraft, for ``bench reach`` and the property tests.

:func:`random_world` draws one world mapping (parse it with :func:`swarmplan.world.parse_world`)
from one ``numpy.random.Generator``: the same generator state gives the same world. Each world has
1 to 8 agents and 0 to 8 bodies of every shape the world format accepts (sphere, box, cylinder,
capsule), some standing on the ground, some floating, some raised slabs (overhangs), some turned;
in a third of the worlds up to two of them move (a circle, a loop of waypoints or a straight
line, slower than the slowest agent). The ground is z = 0, the bounds' floor.

Classes (the agent's parameters, drawn per agent; the world's size; the step):

- ``lab``: multirotors of radius 0.05-0.2 m, 0.5-2 m/s, 1-4 m/s², in rooms of 3-10 m
  (2.5-6 m high); dt 0.05 s.
- ``field``: multirotors of radius 0.3-1 m, 5-15 m/s, 2-8 m/s², over 100-1000 m (20-200 m
  high); dt 0.1 s.
- ``fixed_wing``: minimum turn radius R of 20-2000 m, cruise speed sqrt(R a) for a lateral
  acceleration a of 2-8 m/s² (speeds 0.7-1.3 of cruise), in worlds of 6-12 R across and 3-5 R
  high; dt the time the fastest agent takes to turn by 1/20 rad, 0.1-0.5 s.

Starts and goals are sampled over the whole free volume: 40 % anywhere, the rest near a surface
(just above the ground, beside a body, under a raised slab, beside a face of the bounds). A
multirotor's point keeps at least 1.5 radii from every static body, the ground and the bounds'
faces (starts also from the moving bodies at t = 0, by the distance they cover in a second); a
fixed wing's keeps its turn radius plus its body (the room a turn needs: it cannot stop). Starts
are clear of each other, and goals of each other, by the agents' separation ellipsoids (fixed
wings' starts also two turn radii apart); each goal lies at least a fifth of the world's width
from its start (fixed wings: two turn radii). The goal tolerance is each class's tight one:
the smallest agent's radius, at most 0.3 m (multirotors), or R / 4 of the tightest-turning fixed
wing; ``max_time`` is three times the longest straight flight at cruise speed plus 30 s. The
planner keeps its defaults: nothing is tuned to a world.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

CLASSES = ("lab", "field", "fixed_wing")
"""The classes of :func:`random_world`."""

SHAPES = ("sphere", "box", "cylinder", "capsule")
"""The body shapes drawn (every primitive the world format accepts)."""

DT = {"lab": 0.05, "field": 0.1, "fixed_wing": 0.1}
"""The simulation step of each class (s); a fixed wing's grows with its turn radius (:func:`_dt`)."""


def _dt(kind: str, agents: list[dict[str, Any]]) -> float:
    """The world's step: the class's, or for fixed wings the time the fastest one takes to turn
    by 1/20 rad on the tightest turn radius, between 0.1 and 0.5 s (in 0.05 s)."""
    if kind != "fixed_wing":
        return DT[kind]
    turn = min(a["min_turn_radius"] for a in agents) / max(a["speed"]["max"] for a in agents) / 20.0
    return round(min(0.5, max(DT[kind], math.floor(turn / 0.05) * 0.05)), 2)


MULTIROTOR_TOLERANCE_CAP = 0.3
"""m: a multirotor world's goal tolerance is its smallest agent's radius, at most this."""


def _r(x: float) -> float:
    return round(float(x), 6)


def _vec(v: np.ndarray) -> list[float]:
    return [_r(x) for x in v]


def _agent_params(kind: str, rng: np.random.Generator, turn_radius: float) -> dict[str, Any]:
    """One agent's parameters (world-format keys) for its class."""
    if kind == "fixed_wing":
        R = turn_radius * rng.uniform(0.85, 1.2)
        cruise = math.sqrt(R * rng.uniform(2.0, 8.0))
        body = rng.uniform(0.5, 2.0) * math.sqrt(R / 20.0)
        sep = body * rng.uniform(2.0, 5.0)
        return {
            "model": "fixed_wing",
            "radius": _r(body),
            "speed": {"min": _r(0.7 * cruise), "max": _r(1.3 * cruise), "cruise": _r(cruise)},
            "max_accel": _r(rng.uniform(1.0, 4.0)),
            "min_turn_radius": _r(R),
            "max_climb_angle": _r(rng.uniform(15.0, 30.0)),
            "min_altitude": _r(rng.uniform(0.0, 0.5) * R),
            "separation": [_r(sep), _r(sep), _r(0.5 * sep)],
        }
    if kind == "lab":
        radius, vmax, accel = rng.uniform(0.05, 0.2), rng.uniform(0.5, 2.0), rng.uniform(1.0, 4.0)
        min_alt = rng.uniform(0.0, 1.0)
    else:
        radius, vmax, accel = rng.uniform(0.3, 1.0), rng.uniform(5.0, 15.0), rng.uniform(2.0, 8.0)
        min_alt = rng.uniform(0.0, 10.0)
    sep = radius * rng.uniform(1.0, 3.0)
    out: dict[str, Any] = {
        "model": "multirotor",
        "radius": _r(radius),
        "speed": {"min": 0.0, "max": _r(vmax), "cruise": _r(vmax * rng.uniform(0.7, 1.0))},
        "max_accel": _r(accel),
        # a downwash-like ellipsoid: taller than wide
        "separation": [_r(sep), _r(sep), _r(sep * rng.uniform(1.0, 2.5))],
    }
    if rng.uniform() < 2.0 / 3.0:  # else the world format's default min_altitude
        out["min_altitude"] = _r(min_alt)
    return out


def _extent(kind: str, rng: np.random.Generator, turn_radius: float) -> np.ndarray:
    """The bounds' size (x, y, z) of a world of ``kind``; the floor is z = 0."""
    if kind == "lab":
        x, y = rng.uniform(3.0, 10.0, 2)
        return np.array([x, y, rng.uniform(2.5, min(6.0, max(x, y)))])
    if kind == "field":
        side = rng.uniform(100.0, 1000.0)
        x, y = side, side * rng.uniform(0.5, 1.0)
        return np.array([x, y, float(np.clip(rng.uniform(0.1, 0.3) * side, 20.0, 200.0))])
    x, y = rng.uniform(6.0, 12.0, 2) * turn_radius
    return np.array([x, y, rng.uniform(3.0, 5.0) * turn_radius])


def _body(rng: np.random.Generator, k: int, size: np.ndarray, scale: float, kind: str) -> dict[str, Any]:
    """One body: standing on the ground, floating, or a raised slab (an overhang)."""
    shape = SHAPES[int(rng.integers(len(SHAPES)))]
    place = rng.choice(["ground", "float", "slab"], p=[0.45, 0.35, 0.2])
    s = scale * rng.uniform(0.5, 1.5)  # the body's characteristic size
    top = size[2]
    xy = rng.uniform([0.1, 0.1], [0.9, 0.9]) * size[:2]
    body: dict[str, Any] = {"id": f"body{k}", "shape": shape}
    rot = [0.0, 0.0, 0.0]
    if place == "slab":
        shape = body["shape"] = "box"
        thick = s * rng.uniform(0.05, 0.2)
        dims = np.array([s * rng.uniform(1.0, 2.5), s * rng.uniform(1.0, 2.5), thick])
        z = rng.uniform(0.25, 0.7) * top
        body["size"] = _vec(dims)
        rot = [0.0, 0.0, rng.uniform(0.0, 90.0)]
        centre = [xy[0], xy[1], z]
    elif shape == "sphere":
        rad = 0.5 * s
        z = rad if place == "ground" else rng.uniform(0.2, 0.8) * top
        body["radius"] = _r(rad)
        centre = [xy[0], xy[1], z]
    elif shape == "box":
        dims = np.array([s * rng.uniform(0.3, 1.5), s * rng.uniform(0.3, 1.5), s * rng.uniform(0.3, 1.5)])
        if place == "ground":
            dims[2] = rng.uniform(0.2, 0.9) * top  # a wall, a cabinet or a block
            if rng.uniform() < 0.4:  # a thin wall
                dims[int(rng.integers(2))] = s * rng.uniform(0.05, 0.15)
        z = dims[2] / 2.0 if place == "ground" else rng.uniform(0.2, 0.8) * top
        body["size"] = _vec(dims)
        rot = [0.0, 0.0, rng.uniform(0.0, 90.0)] if rng.uniform() < 0.5 else [0.0, 0.0, 0.0]
        if place == "float" and rng.uniform() < 0.3:
            rot = list(rng.uniform(0.0, 90.0, 3))
        centre = [xy[0], xy[1], z]
    else:  # cylinder, capsule
        rad = 0.5 * s * rng.uniform(0.2, 0.8)
        if place == "ground":  # a pillar
            height = rng.uniform(0.3, 0.95) * top - (2.0 * rad if shape == "capsule" else 0.0)
            height = max(height, 0.1 * rad)
            z = height / 2.0 + (rad if shape == "capsule" else 0.0)
        else:
            height = s * rng.uniform(0.5, 2.0)
            z = rng.uniform(0.2, 0.8) * top
            if rng.uniform() < 0.5:  # lying or leaning
                rot = [rng.uniform(0.0, 90.0), rng.uniform(0.0, 90.0), rng.uniform(0.0, 180.0)]
        body["radius"] = _r(rad)
        body["height"] = _r(height)
        centre = [xy[0], xy[1], z]
    body["position"] = _vec(np.asarray(centre))
    if any(rot):
        body["rotation"] = _vec(np.asarray(rot))
    return body


def _motion(rng: np.random.Generator, body: dict[str, Any], size: np.ndarray, speed: float) -> dict[str, Any]:
    """A motion keeping the body roughly inside the bounds, at ``speed`` m/s."""
    p = np.asarray(body["position"], dtype=float)
    kind = rng.choice(["circle", "waypoints", "linear"], p=[0.4, 0.4, 0.2])
    if kind == "circle":
        rad = rng.uniform(0.1, 0.3) * float(min(size[0], size[1]))
        a = rng.uniform(0.0, 2.0 * math.pi)
        centre = p - rad * np.array([math.cos(a), math.sin(a), 0.0])
        sign = 1.0 if rng.uniform() < 0.5 else -1.0
        return {
            "type": "circle",
            "center": _vec(centre),
            "radius": _r(rad),
            "angular_speed": _r(sign * speed / rad),
        }
    if kind == "waypoints":
        pts = [_vec(rng.uniform(0.1, 0.9, 3) * size) for _ in range(int(rng.integers(1, 4)))]
        for q in pts:  # keep the body's height band (a ground body stays on the ground)
            q[2] = _r(p[2])
        return {"type": "waypoints", "waypoints": pts, "speed": _r(speed), "loop": True}
    d = rng.normal(size=3)
    d[2] = 0.0
    d /= max(float(np.linalg.norm(d)), 1e-9)
    return {"type": "linear", "velocity": _vec(d * speed)}


def _obstacles(raw_bodies: list[dict[str, Any]]) -> list:
    """The parsed bodies (their exact signed distances are what the world loader checks with)."""
    from swarmplan.world.checker import Checker
    from swarmplan.world.schema import _resolve_obstacle

    out = []
    for k, b in enumerate(raw_bodies):
        _, o = _resolve_obstacle(Checker(), b, f"obstacles[{k}]", Path("."))
        out.append(o)
    return out


class _Space:
    """Clearances of points in a world: to the static bodies, the ground and the bounds' faces,
    and to the moving bodies at t = 0."""

    def __init__(self, size: np.ndarray, raw_bodies: list[dict[str, Any]]):
        from swarmplan.geometry.shapes import signed_distance

        self.size = size
        self._sd = signed_distance
        bodies = _obstacles(raw_bodies)
        self.static = [o for o in bodies if not o.moving]
        self.moving = [o for o in bodies if o.moving]
        self.mover_speed = [float(_speed_of(b)) for b in raw_bodies if "motion" in b]

    def clearance(self, p: np.ndarray, movers: bool = False) -> float:
        faces = min(float(p.min()), float((self.size - p).min()))  # the floor z = 0 is a face
        d = [faces] + [float(self._sd(o, p[None])[0]) for o in self.static]
        if movers:
            d += [
                float(self._sd(o, p[None])[0]) - v for o, v in zip(self.moving, self.mover_speed, strict=True)
            ]
        return min(d)


def _speed_of(body: dict[str, Any]) -> float:
    m = body["motion"]
    if m["type"] == "circle":
        return abs(m["angular_speed"]) * m["radius"]
    if m["type"] == "waypoints":
        return m["speed"]
    return float(np.linalg.norm(m["velocity"]))


def _point(
    rng: np.random.Generator,
    space: _Space,
    raw_bodies: list[dict[str, Any]],
    need: float,
    near: float,
    movers: bool,
) -> np.ndarray | None:
    """A point whose clearance is at least ``need``: anywhere (40 %) or within ``near`` beyond
    it of a surface (the ground, a body, the underside of a slab, a face of the bounds)."""
    size = space.size
    lo, hi = np.full(3, need), size - need
    if np.any(lo >= hi):
        return None
    for _ in range(200):
        mode = rng.choice(["free", "ground", "body", "under", "face"], p=[0.4, 0.2, 0.2, 0.1, 0.1])
        p = rng.uniform(lo, hi)
        band = (need, need + near)
        if mode == "ground":
            p[2] = rng.uniform(*band)
        elif mode == "face":
            axis = int(rng.integers(2))
            p[axis] = rng.uniform(*band) if rng.uniform() < 0.5 else size[axis] - rng.uniform(*band)
        elif mode in ("body", "under") and raw_bodies:
            slabs = [b for b in raw_bodies if b["id"].startswith("body") and "motion" not in b]
            if mode == "under":
                slabs = [b for b in slabs if b["shape"] == "box" and b["size"][2] < 0.3 * max(b["size"][:2])]
            if not slabs:
                continue
            b = slabs[int(rng.integers(len(slabs)))]
            c = np.asarray(b["position"], dtype=float)
            if mode == "under":
                half = 0.5 * np.asarray(b["size"][:2], dtype=float)
                p = c + np.array([*(rng.uniform(-0.8, 0.8, 2) * half), 0.0])
                p[2] = c[2] - 0.5 * b["size"][2] - rng.uniform(*band)
            else:  # along a random ray out of the body's centre, at the band's distance
                u = rng.normal(size=3)
                u /= max(float(np.linalg.norm(u)), 1e-9)
                target = rng.uniform(*band)
                p = _at_distance(space, c, u, target, float(size.max()))
                if p is None:
                    continue
        if np.any(p < lo) or np.any(p > hi):
            continue
        c = space.clearance(p, movers=movers)
        if c >= need and (mode == "free" or c <= need + 2.0 * near):
            return p
    return None


def _at_distance(space: _Space, c: np.ndarray, u: np.ndarray, target: float, far: float) -> np.ndarray | None:
    """The point on the ray ``c + s u`` (0 <= s <= ``far``) where its clearance to the static
    bodies first reaches ``target`` (to 1/4096 of ``far``), or None."""
    if not space.static:
        return None
    a, b = 0.0, far
    for _ in range(2):  # a coarse pass, then a fine one between the two samples around it
        s = np.linspace(a, b, 65)
        q = c + s[:, None] * u
        d = np.min([space._sd(o, q) for o in space.static], axis=0)
        out = np.flatnonzero(d >= target)
        if not len(out):
            return None
        k = int(out[0])
        if k == 0:
            return q[0]
        a, b = s[k - 1], s[k]
    return c + b * u


def _clear_of(
    p: np.ndarray, others: list[np.ndarray], bodies: list[tuple[np.ndarray, float]], sep: np.ndarray, r: float
) -> bool:
    """``p`` (an agent of separation ``sep`` and radius ``r``) outside every other point's
    separation ellipsoid, as the simulation measures it: |dp / (max(sep_i, sep_j) + r_i + r_j)|
    at least 1 (with 5 % to spare)."""
    for q, (sep_j, r_j) in zip(others, bodies, strict=True):
        if float(np.linalg.norm((p - q) / (np.maximum(sep, sep_j) + r + r_j))) < 1.05:
            return False
    return True


def random_world(
    kind: str,
    rng: np.random.Generator,
    *,
    name: str | None = None,
    max_agents: int = 8,
    max_bodies: int = 8,
    small: bool = False,
) -> dict[str, Any]:
    """A random valid world mapping of class ``kind`` (see the module's docstring) drawn from
    ``rng``. ``max_agents``, ``max_bodies`` cap the counts; ``small`` keeps the world at the
    small end of its class (lab rooms of 3-5 m, fields of 100-200 m, turn radii of 20-100 m)
    for quick runs."""
    if kind not in CLASSES:
        raise ValueError(f"unknown class {kind!r} (known: {', '.join(CLASSES)})")
    for _ in range(100):
        raw = _try_world(kind, rng, max_agents=max_agents, max_bodies=max_bodies, small=small)
        if raw is not None:
            if name is not None:
                raw["name"] = name
            return raw
    raise RuntimeError(f"no valid {kind} world in 100 draws")  # pragma: no cover (never seen)


def _try_world(kind: str, rng: np.random.Generator, *, max_agents: int, max_bodies: int, small: bool):  # noqa: ANN202
    n_agents = int(rng.integers(1, max_agents + 1))
    n_bodies = int(rng.integers(0, max_bodies + 1))
    turn = 0.0
    if kind == "fixed_wing":
        turn = float(math.exp(rng.uniform(math.log(20.0), math.log(100.0 if small else 2000.0))))
    agents = [_agent_params(kind, rng, turn) for _ in range(n_agents)]
    size = _extent(kind, rng, turn)
    if small:
        size = size * {"lab": 0.5, "field": 0.2, "fixed_wing": 1.0}[kind]
        size = np.maximum(size, {"lab": [3.0, 3.0, 2.5], "field": [100.0, 50.0, 20.0]}.get(kind, 0.0))
    scale = 0.12 * float(min(size[0], size[1]))
    bodies = [_body(rng, k, size, scale, kind) for k in range(n_bodies)]
    slowest = min(a["speed"]["cruise"] for a in agents)
    if bodies and rng.uniform() < 1.0 / 3.0:
        for k in rng.permutation(len(bodies))[: int(rng.integers(1, 3))]:
            bodies[k]["motion"] = _motion(rng, bodies[k], size, slowest * rng.uniform(0.2, 0.6))
            bodies[k]["id"] = f"mover{k}"
    space = _Space(size, bodies)
    starts: list[np.ndarray] = []
    goals: list[np.ndarray] = []
    placed: list[tuple[np.ndarray, float]] = []
    min_leg = 2.0 * turn if kind == "fixed_wing" else 0.2 * float(min(size[0], size[1]))
    kept = []
    for a in agents:
        r = a["radius"]
        if kind == "fixed_wing":
            need, near = a["min_turn_radius"] + r, 0.3 * a["min_turn_radius"]
        else:
            need, near = 1.5 * r, max(0.5, 2.0 * r) if kind == "field" else 0.3
        sep = np.asarray(a["separation"], dtype=float)
        for _ in range(20):
            s = _point(rng, space, bodies, need, near, movers=True)
            g = _point(rng, space, bodies, need, near, movers=False)
            if s is None or g is None or float(np.linalg.norm(g - s)) < min_leg:
                continue
            if not _clear_of(s, starts, placed, sep, r) or not _clear_of(g, goals, placed, sep, r):
                continue
            if kind == "fixed_wing" and any(np.linalg.norm(s - q) < 2.0 * turn for q in starts):
                continue
            starts.append(s)
            goals.append(g)
            placed.append((sep, r))
            kept.append(a)
            break
    if not kept:
        return None
    if kind == "fixed_wing":
        tolerance = min(a["min_turn_radius"] for a in kept) / 4.0
    else:
        tolerance = min(MULTIROTOR_TOLERANCE_CAP, min(a["radius"] for a in kept))
    straight = max(
        float(np.linalg.norm(g - s)) / a["speed"]["cruise"]
        for s, g, a in zip(starts, goals, kept, strict=True)
    )
    return {
        "name": f"reach-{kind}",
        "seed": 0,
        "bounds": {"min": [0.0, 0.0, 0.0], "max": _vec(size)},
        "sim": {
            "dt": _dt(kind, kept),
            "max_time": _r(math.ceil((3.0 * straight + 30.0) * 10.0) / 10.0),
            "goal_tolerance": _r(tolerance),
        },
        "obstacles": bodies,
        "agents": [
            {"id": f"a{i}", "start": _vec(s), "goal": _vec(g), **a}
            for i, (s, g, a) in enumerate(zip(starts, goals, kept, strict=True))
        ],
    }


def sample_problems(worlds: int, seed: int, kind: str) -> list[str]:
    """The problems of a sample of random worlds asked on a command line: ``--worlds`` per
    class, ``--seed`` of the draws, ``--class`` (one of :data:`CLASSES` or all)."""
    problems = []
    if worlds < 1:
        problems.append(f"--worlds: must be >= 1, got {worlds}")
    if seed < 0:
        problems.append(f"--seed: must be >= 0, got {seed}")
    if kind != "all" and kind not in CLASSES:
        problems.append(f"--class: expected one of {', '.join(CLASSES)} or all, got {kind!r}")
    return problems
