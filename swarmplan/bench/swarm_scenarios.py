"""The field's standard dense-swarm scenarios, generated from parameters.

Every scenario is a function ``(agents, seed) -> dict`` returning a world mapping (parse it with
:func:`swarmplan.world.parse_world`, or call :func:`scenario_world` for the ``World``). All share
the agents of RVO2-3D's sphere example as the swarm literature flies them: multirotors of radius
0.5 m, 6 m/s at most, 5 m/s cruise, 5 m/s² (the default), a 1 m separation margin, dt 0.1 s and a
2 m goal tolerance. ``max_time`` is the horizon the benchmark allows: three times the longest
straight-line flight at cruise speed plus 30 s.

- ``sphere``: N agents evenly spread (Fibonacci lattice, rotated by the seed) on a sphere of
  radius 2.2 sqrt(N) m, each flying to its antipode.
- ``circle``: the same in a horizontal plane (radius 2.2 sqrt(N) m or 2.5 m of arc per agent).
- ``crossing``: two blocks of N/2 agents flying across each other's path at 90 degrees.
- ``doorway``: N/2 agents on each side of a wall swap sides through its one gap (4 m wide).
- ``sphere_pillars``: the sphere with 8 vertical pillars through its interior.
- ``forest``: agents cross a forest of pillars in opposite directions while spheres circle
  through it (the moving obstacles of MADER's benchmarks).

The literature's lab scenarios (:data:`LAB_SCENARIOS`, flown at their own sizes
:data:`LAB_SIZES`), with their own agents:

- ``rmader_circle_<h>m``: RMADER's circle swap (mit-acl/rmader): 10 or 32 drones of radius
  0.4 m at 5 m/s and 7 m/s² on a 10 m circle at altitude h = 1, 2, 5 or 8 m swap to their
  antipodes; tolerance 0.5 m, dt 0.05 s.
- ``crazyswarm_room``: 8, 16 or 49 Crazyflies (radius 0.05 m, 1 m/s) in a room swap their
  take-off grid through its centre, Crazyswarm's downwash ellipsoid as the separation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from swarmplan.world.model import World

RADIUS = 0.5
SPEED = {"min": 0.0, "max": 6.0, "cruise": 5.0}
SEPARATION = [1.0, 1.0, 1.0]
DT = 0.1
GOAL_TOLERANCE = 2.0
FLOOR = 15.0  # m: lowest start/goal height (clear of the ground's repulsion)
MARGIN = 15.0  # m between the swarm and the faces of the bounds
MIN_ALTITUDE = 5.0  # m: the soft floor the published tables were flown with


def _world(
    name: str, seed: int, starts: np.ndarray, goals: np.ndarray, obstacles: list[dict]
) -> dict[str, Any]:
    """A world around ``starts``/``goals`` (N, 3) with the benchmark's agents and horizon."""
    pts = np.vstack([starts, goals])
    lo = pts.min(axis=0) - MARGIN
    hi = pts.max(axis=0) + MARGIN
    lo[2] = 0.0
    straight = float(np.linalg.norm(goals - starts, axis=1).max())
    horizon = 3.0 * straight / SPEED["cruise"] + 30.0
    return {
        "name": name,
        "seed": int(seed),
        "bounds": {"min": [round(float(v), 6) for v in lo], "max": [round(float(v), 6) for v in hi]},
        "sim": {
            "dt": DT,
            "max_time": round(math.ceil(horizon * 10.0) / 10.0, 1),
            "goal_tolerance": GOAL_TOLERANCE,
        },
        "obstacles": obstacles,
        "agent_defaults": {
            "model": "multirotor",
            "radius": RADIUS,
            "speed": dict(SPEED),
            "separation": list(SEPARATION),
            "min_altitude": MIN_ALTITUDE,
        },
        "agents": [
            {"id": f"a{i}", "start": [round(float(v), 6) for v in s], "goal": [round(float(v), 6) for v in g]}
            for i, (s, g) in enumerate(zip(starts, goals, strict=True))
        ],
    }


def _fibonacci_sphere(n: int, seed: int) -> np.ndarray:
    """``n`` unit vectors evenly spread over the sphere, rotated at random by ``seed``."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    u = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return u @ q.T


def sphere_radius(agents: int) -> float:
    return 2.2 * math.sqrt(agents)


def sphere(agents: int, seed: int = 0) -> dict[str, Any]:
    """Antipodal sphere: every agent flies through the centre to the opposite point."""
    rad = sphere_radius(agents)
    centre = np.array([0.0, 0.0, FLOOR + rad])
    u = _fibonacci_sphere(agents, seed)
    return _world(f"sphere-{agents}", seed, centre + rad * u, centre - rad * u, [])


def sphere_pillars(agents: int, seed: int = 0) -> dict[str, Any]:
    """The sphere with 8 vertical pillars (radius 1 m, 1.4 sphere radii tall: inside the sphere,
    clear of the agents on it) on a ring of 0.4 sphere radii about its vertical axis."""
    raw = sphere(agents, seed)
    rad = sphere_radius(agents)
    ring = 0.4 * rad
    pillars = []
    for k in range(8):
        a = 2.0 * math.pi * (k + 0.5) / 8.0
        pillars.append(
            {
                "id": f"pillar{k}",
                "shape": "cylinder",
                "radius": 1.0,
                "height": round(1.4 * rad, 6),
                "position": [
                    round(ring * math.cos(a), 6),
                    round(ring * math.sin(a), 6),
                    round(FLOOR + rad, 6),
                ],
            }
        )
    raw["obstacles"] = pillars
    raw["name"] = f"sphere_pillars-{agents}"
    return raw


def circle(agents: int, seed: int = 0) -> dict[str, Any]:
    """Antipodal circle in a horizontal plane (the circle swaps of EGO-Swarm and MADER)."""
    rad = max(sphere_radius(agents), 2.5 * agents / (2.0 * math.pi))
    a = 2.0 * math.pi * (np.arange(agents) / agents + np.random.default_rng(seed).uniform())
    u = np.column_stack([np.cos(a), np.sin(a), np.zeros(agents)])
    centre = np.array([0.0, 0.0, FLOOR + 5.0])
    return _world(f"circle-{agents}", seed, centre + rad * u, centre - rad * u, [])


def _block(count: int, spacing: float) -> np.ndarray:
    """``count`` offsets (lateral, vertical) on a square-ish grid centred on 0."""
    cols = math.ceil(math.sqrt(count))
    rows = math.ceil(count / cols)
    k = np.arange(count)
    return np.column_stack(
        [(k % cols - (cols - 1) / 2.0) * spacing, (k // cols - (rows - 1) / 2.0) * spacing]
    )


def crossing(agents: int, seed: int = 0) -> dict[str, Any]:
    """Two blocks of agents (a grid in the plane across their flight, 4 m apart) fly 2L m
    along +x and along +y, crossing at the origin; the seed jitters the grid by up to 0.5 m."""
    rng = np.random.default_rng(seed)
    na = agents // 2
    nb = agents - na
    spacing = 4.0
    length = max(40.0, 2.0 * spacing * math.ceil(math.sqrt(max(na, nb))))
    z0 = FLOOR + spacing * math.ceil(math.sqrt(max(na, nb))) / 2.0
    starts, goals = [], []
    for count, axis in ((na, 0), (nb, 1)):
        off = _block(count, spacing) + rng.uniform(-0.5, 0.5, size=(count, 2))
        s = np.zeros((count, 3))
        s[:, axis] = -length
        s[:, 1 - axis] = off[:, 0]
        s[:, 2] = z0 + off[:, 1]
        g = s.copy()
        g[:, axis] = length
        starts.append(s)
        goals.append(g)
    return _world(f"crossing-{agents}", seed, np.vstack(starts), np.vstack(goals), [])


DOOR_WIDTH = 4.0


def doorway(agents: int, seed: int = 0) -> dict[str, Any]:
    """A wall across the field (x = 0, as high as the bounds) with one 4 m gap; half the agents
    start on each side (a grid 4 m apart, 20 m from the wall) and swap sides."""
    rng = np.random.default_rng(seed)
    na = agents // 2
    nb = agents - na
    spacing = 4.0
    dist = 20.0 + spacing * math.ceil(math.sqrt(max(na, nb)))
    z0 = FLOOR
    starts, goals = [], []
    for count, side in ((na, -1.0), (nb, 1.0)):
        cols = math.ceil(math.sqrt(count))
        k = np.arange(count)
        s = np.column_stack(
            [
                side * (20.0 + (k // cols) * spacing),
                (k % cols - (cols - 1) / 2.0) * spacing,
                np.full(count, z0),
            ]
        )
        s[:, :2] += rng.uniform(-0.5, 0.5, size=(count, 2))
        g = s.copy()
        g[:, 0] = -s[:, 0]
        starts.append(s)
        goals.append(g)
    raw = _world(f"doorway-{agents}", seed, np.vstack(starts), np.vstack(goals), [])
    lo, hi = raw["bounds"]["min"], raw["bounds"]["max"]
    lo[0], hi[0] = min(lo[0], -dist - MARGIN), max(hi[0], dist + MARGIN)
    top = hi[2]
    width = hi[1] - lo[1]
    half = DOOR_WIDTH / 2.0
    walls = []
    for name, y0, y1 in (("wall_south", lo[1] - 1.0, -half), ("wall_north", half, hi[1] + 1.0)):
        walls.append(
            {
                "id": name,
                "shape": "box",
                "size": [1.0, round(y1 - y0, 6), round(top + 2.0, 6)],
                "position": [0.0, round((y0 + y1) / 2.0, 6), round(top / 2.0, 6)],
            }
        )
    if width <= DOOR_WIDTH:
        raise ValueError("doorway: the field is narrower than the door")
    raw["obstacles"] = walls
    return raw


def forest(agents: int, seed: int = 0) -> dict[str, Any]:
    """Two blocks of agents fly across a forest of pillars in opposite directions (along +x and
    -x, offset so they meet head-on) while spheres circle through the forest."""
    rng = np.random.default_rng(seed)
    na = agents // 2
    nb = agents - na
    spacing = 4.0
    side = spacing * math.ceil(math.sqrt(max(na, nb)))
    length = max(50.0, 2.0 * side)
    z0 = FLOOR + side / 2.0
    starts, goals = [], []
    for count, sign in ((na, 1.0), (nb, -1.0)):
        off = _block(count, spacing) + rng.uniform(-0.5, 0.5, size=(count, 2))
        s = np.column_stack([np.full(count, -sign * length), off[:, 0], z0 + off[:, 1]])
        g = s.copy()
        g[:, 0] = sign * length
        starts.append(s)
        goals.append(g)
    s_all, g_all = np.vstack(starts), np.vstack(goals)
    raw = _world(f"forest-{agents}", seed, s_all, g_all, [])
    top = raw["bounds"]["max"][2]
    half_w = side / 2.0 + 10.0
    obstacles: list[dict[str, Any]] = []
    cell = 10.0
    xs = np.arange(-length + 20.0, length - 20.0 + 1e-9, cell)
    ys = np.arange(-half_w, half_w + 1e-9, cell)
    k = 0
    for x in xs:
        for y in ys:
            p = np.array([x, y]) + rng.uniform(-2.5, 2.5, 2)
            obstacles.append(
                {
                    "id": f"tree{k}",
                    "shape": "cylinder",
                    "radius": 0.6,
                    "height": round(top, 6),
                    "position": [round(float(p[0]), 6), round(float(p[1]), 6), round(top / 2.0, 6)],
                }
            )
            k += 1
    movers = max(2, agents // 16)
    for m in range(movers):
        c = np.array([rng.uniform(-0.6 * length, 0.6 * length), rng.uniform(-0.5 * half_w, 0.5 * half_w)])
        radius_c = rng.uniform(6.0, 12.0)
        a = rng.uniform(0.0, 2.0 * math.pi)
        z = z0 + rng.uniform(-side / 3.0, side / 3.0)
        obstacles.append(
            {
                "id": f"mover{m}",
                "shape": "sphere",
                "radius": 1.0,
                "position": [
                    round(float(c[0] + radius_c * math.cos(a)), 6),
                    round(float(c[1] + radius_c * math.sin(a)), 6),
                    round(float(z), 6),
                ],
                "motion": {
                    "type": "circle",
                    "center": [round(float(c[0]), 6), round(float(c[1]), 6), round(float(z), 6)],
                    "radius": round(float(radius_c), 6),
                    "angular_speed": round(float(rng.choice([-1.0, 1.0]) * 2.0 / radius_c), 6),
                },
            }
        )
    # Keep starts and goals clear of the trees (a tree nearer than 3 m to one moves away).
    for o in obstacles:
        if "motion" in o:
            continue
        p = np.array(o["position"][:2])
        d = np.linalg.norm(np.vstack([s_all, g_all])[:, :2] - p, axis=1)
        if d.min() < 3.0:
            o["position"][1] = round(float(p[1] + (3.5 if p[1] >= 0 else -3.5)), 6)
    raw["obstacles"] = obstacles
    return raw


SCENARIOS: dict[str, Callable[[int, int], dict[str, Any]]] = {
    "sphere": sphere,
    "circle": circle,
    "crossing": crossing,
    "doorway": doorway,
    "sphere_pillars": sphere_pillars,
    "forest": forest,
}
"""Scenario name -> generator ``(agents, seed) -> world mapping``."""

# ---------------------------------------------------------------- the literature's lab scenarios

RMADER_RADIUS = 0.4
"""m: half of RMADER's drone bounding box (0.8 x 0.8 x 0.5 m, ``rmader/param/rmader.yaml`` of
mit-acl/rmader)."""
RMADER_SPEED = 5.0  # m/s: its v_max
RMADER_ACCEL = 7.0  # m/s²: its a_max
RMADER_CIRCLE = 10.0  # m: radius of its circle swap
RMADER_TOLERANCE = 0.5  # m
LAB_DT = 0.05  # s

CRAZYFLIE_RADIUS = 0.05  # m
CRAZYFLIE_SPEED = 1.0  # m/s (Crazyswarm's examples fly at --maxvel 1.0)
CRAZYFLIE_ACCEL = 2.0  # m/s²
CRAZYSWARM_ELLIPSOID = (0.125, 0.125, 0.375)
"""m: the downwash ellipsoid of Crazyswarm's collision avoidance (``RADII`` of its scripts,
USC-ACTLab/crazyswarm): no other centre inside it. swarmplan's separation adds both radii to the
larger semi-axes, so the separation asked is these minus two radii."""
CRAZYSWARM_SPACING = 0.5  # m between neighbours on the take-off grid


def _lab_world(
    name: str,
    seed: int,
    starts: np.ndarray,
    goals: np.ndarray,
    bounds: tuple[list, list],
    agent: dict,
    tol: float,
) -> dict[str, Any]:
    """A world of the lab scenarios around ``starts``/``goals`` (N, 3) with ``agent`` as every
    agent's defaults; ``max_time`` three times the longest straight flight at cruise + 30 s."""
    straight = float(np.linalg.norm(goals - starts, axis=1).max())
    horizon = 3.0 * straight / agent["speed"]["cruise"] + 30.0
    return {
        "name": name,
        "seed": int(seed),
        "bounds": {
            "min": [round(float(v), 6) for v in bounds[0]],
            "max": [round(float(v), 6) for v in bounds[1]],
        },
        "sim": {
            "dt": LAB_DT,
            "max_time": round(math.ceil(horizon * 10.0) / 10.0, 1),
            "goal_tolerance": tol,
        },
        "obstacles": [],
        "agent_defaults": agent,
        "agents": [
            {"id": f"a{i}", "start": [round(float(v), 6) for v in s], "goal": [round(float(v), 6) for v in g]}
            for i, (s, g) in enumerate(zip(starts, goals, strict=True))
        ],
    }


def rmader_circle(agents: int, seed: int = 0, altitude: float = 1.0) -> dict[str, Any]:
    """RMADER's circle swap: ``agents`` drones evenly on a 10 m circle at ``altitude`` swap to
    their antipodes (radius 0.4 m, 5 m/s, 7 m/s², tolerance 0.5 m, dt 0.05 s; seed 0 starts on
    the x axis, other seeds turn the circle)."""
    turn = 0.0 if seed == 0 else np.random.default_rng(seed).uniform()
    a = 2.0 * math.pi * (np.arange(agents) / agents + turn)
    u = np.column_stack([np.cos(a), np.sin(a), np.zeros(agents)])
    centre = np.array([0.0, 0.0, altitude])
    half = RMADER_CIRCLE + 5.0
    agent = {
        "model": "multirotor",
        "radius": RMADER_RADIUS,
        "speed": {"min": 0.0, "max": RMADER_SPEED, "cruise": RMADER_SPEED},
        "max_accel": RMADER_ACCEL,
        "separation": [0.1, 0.1, 0.1],
    }
    bounds = ([-half, -half, 0.0], [half, half, altitude + 5.0])
    name = f"rmader_circle_{altitude:g}m-{agents}"
    return _lab_world(name, seed, centre + RMADER_CIRCLE * u, centre - RMADER_CIRCLE * u, bounds, agent,
                      RMADER_TOLERANCE)  # fmt: skip


def crazyswarm_room(agents: int, seed: int = 0) -> dict[str, Any]:
    """A Crazyswarm-style room: ``agents`` Crazyflies (radius 0.05 m, 1 m/s, 2 m/s²) on a square
    take-off grid 0.5 m apart, 0.5 m above the floor, each flying to the grid point opposite it
    through the grid's centre at 1.0 m (a swap of the whole grid); their downwash ellipsoid
    (0.125, 0.125, 0.375) m as the separation; the room 1.5 m wider than the grid on every
    side and 2.5 m high; tolerance the agent's radius; the seed jitters the grid by up to 5 cm."""
    rng = np.random.default_rng(seed)
    off = _block(agents, CRAZYSWARM_SPACING)
    if seed:
        off = off + rng.uniform(-0.05, 0.05, size=off.shape)
    starts = np.column_stack([off, np.full(agents, 0.5)])
    goals = np.column_stack([-off, np.full(agents, 1.0)])
    half = float(np.abs(off).max()) + 1.5
    sep = [round(e - 2.0 * CRAZYFLIE_RADIUS, 6) for e in CRAZYSWARM_ELLIPSOID]
    agent = {
        "model": "multirotor",
        "radius": CRAZYFLIE_RADIUS,
        "speed": {"min": 0.0, "max": CRAZYFLIE_SPEED, "cruise": CRAZYFLIE_SPEED},
        "max_accel": CRAZYFLIE_ACCEL,
        "separation": sep,
    }
    bounds = ([-half, -half, 0.0], [half, half, 2.5])
    return _lab_world(f"crazyswarm_room-{agents}", seed, starts, goals, bounds, agent, CRAZYFLIE_RADIUS)


LAB_SCENARIOS: dict[str, Callable[[int, int], dict[str, Any]]] = {
    **{
        f"rmader_circle_{h:g}m": (lambda n, s, h=h: rmader_circle(n, s, altitude=h))
        for h in (1.0, 2.0, 5.0, 8.0)
    },
    "crazyswarm_room": crazyswarm_room,
}
"""The literature's lab scenarios: name -> ``(agents, seed) -> world mapping``."""

LAB_SIZES = {
    **{name: (10, 32) for name in LAB_SCENARIOS if name.startswith("rmader")},
    "crazyswarm_room": (8, 16, 49),
}
"""The swarm sizes each lab scenario is flown at."""

PUBLISHED = {
    ("rmader_circle", 10): (
        "mit-acl/rmader, 10-agent circle, no communication delay",
        [("RMADER", 100.0, 9.65), ("MADER", 97.0, 7.81), ("EGO-Swarm", 38.0, 5.64)],
    ),
}
"""Published (collision-free runs %, mean travel time s) beside a lab scenario family and size."""


OBSTACLE_FREE = ("sphere", "circle", "crossing")
"""The scenarios without obstacles (the ones ORCA-3D can fly)."""

MAX_AGENTS = {"doorway": 64}
"""Scenarios flown only up to a swarm size (one gap serialises the swap)."""


def scenario_world(
    name: str,
    agents: int,
    seed: int = 0,
    planner: dict[str, Any] | None = None,
    comms: dict[str, Any] | None = None,
    separation: float | None = None,
) -> World:
    """The parsed ``World`` of scenario ``name`` with ``agents`` agents (``planner``: an optional
    ``planner`` section, e.g. ``{"optimizer": {"name": "none"}}``; ``comms``: an optional
    ``comms`` section; ``separation``: the agents' separation on every axis, m, in place of
    the scenario's)."""
    from swarmplan.world import parse_world

    known = {**SCENARIOS, **LAB_SCENARIOS}
    if name not in known:
        raise ValueError(f"unknown scenario '{name}' (known: {', '.join(known)})")
    if agents < 2:
        raise ValueError(f"agents: at least 2, got {agents}")
    raw = known[name](agents, seed)
    if planner is not None:
        raw["planner"] = planner
    if comms is not None:
        raw["comms"] = comms
    if separation is not None:
        raw["agent_defaults"]["separation"] = [float(separation)] * 3
    return parse_world(raw)
