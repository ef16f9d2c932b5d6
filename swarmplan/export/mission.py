"""PX4 / ArduPilot missions: the flown path as waypoints, in QGroundControl's ``.plan`` (JSON)
and the plain ``QGC WPL 110`` waypoint list.

Waypoints: the flown path reduced by Ramer-Douglas-Peucker in 3D, so every recorded position
stays within the bound of the waypoint polyline. Each leg's speed is the leg's length over the
time the agent took for it (the mission's timing is the flown timing); a ``DO_CHANGE_SPEED``
precedes a leg whose speed differs from the one in force by more than a tenth of the agent's
cruise speed. Geodetic coordinates from the world's ``origin`` (x east, y north, z up: a local
East-North-Up frame at the origin), converted with pymap3d on the WGS-84 ellipsoid; altitudes
are relative to the home position (frame 3, ``MAV_FRAME_GLOBAL_RELATIVE_ALT``), the ground under
the agent's start.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .source import AgentLimits, ExportError, FlownPath

# MAVLink commands and frames (common.xml)
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LOITER_UNLIM = 17
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
MAV_AUTOPILOT_PX4 = 12
MAV_TYPE_FIXED_WING = 1
MAV_TYPE_QUADROTOR = 2
SPEED_CHANGE = 0.1  # of the cruise speed: a leg this much faster or slower gets its own speed
TAKEOFF_PITCH_DEG = 15.0  # a fixed wing's takeoff climb angle (param 1), within most climb limits


@dataclass(frozen=True)
class Mission:
    """One agent's mission in the world frame: waypoints (W, 3), the index of the flown step at
    each, the speed of each leg (W - 1,), and the agent's parameters that shape the items."""

    path: FlownPath
    waypoints: np.ndarray
    indices: np.ndarray
    leg_speeds: np.ndarray
    bound: float
    max_deviation: float  # m, of the recorded positions from the waypoint polyline

    @property
    def fixed_wing(self) -> bool:
        return self.path.limits.model == "fixed_wing"

    def commanded_speeds(self) -> np.ndarray:
        """The speed in force on each leg: a new one only where the leg's own speed differs from
        the one in force by more than SPEED_CHANGE of the cruise speed."""
        out = np.empty_like(self.leg_speeds)
        step = SPEED_CHANGE * max(self.path.limits.speed_cruise, 1e-9)
        current = None
        for k, v in enumerate(self.leg_speeds):
            if current is None or abs(v - current) > step:
                current = float(v)
            out[k] = current
        return out

    def acceptance_radius(self) -> float:
        return acceptance_radius_of(self.path.limits)

    def loiter_radius(self) -> float:
        return self.path.limits.min_turn_radius


def acceptance_radius_of(lim: AgentLimits) -> float:
    """A multirotor's waypoint is reached when its body covers it (its radius); a fixed wing
    passes through within the tracking bound max(5 m, 0.05 R_min)."""
    return max(5.0, 0.05 * lim.min_turn_radius) if lim.model == "fixed_wing" else lim.radius


def rdp(
    points: np.ndarray, bound: float | np.ndarray, fits: Callable[[int, int], bool] | None = None
) -> np.ndarray:
    """Indices of the points Ramer-Douglas-Peucker keeps (3D, distance to the chord segment).

    ``bound`` is a number or one per segment of the polyline (N - 1,): the chord from point a to
    point b may lie at most min(bound[a:b]) from the points between (and then, as every point
    of the polyline between lies that close to the chord, every point of the chord lies that
    close to the polyline between: each chord point has one with the same projection on it).
    ``fits(a, b)``, when given, is a further test every kept chord passes; two neighbours
    always pass."""
    n = len(points)
    allow = np.broadcast_to(np.asarray(bound, float), (max(n - 1, 0),))
    keep = np.zeros(n, bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        d = segment_distances(points[a + 1 : b], points[a], points[b])
        k = int(np.argmax(d))
        far = d[k] > float(allow[a:b].min())
        if far or (fits is not None and not fits(a, b)):
            m = a + 1 + k if far else (a + b) // 2
            keep[m] = True
            stack.extend([(a, m), (m, b)])
    return np.flatnonzero(keep)


def segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of points ``p`` (N, 3) to the segment a-b."""
    d = b - a
    dd = float(d @ d)
    s = np.zeros(len(p)) if dd < 1e-18 else np.clip((p - a) @ d / dd, 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * d), axis=1)


def polyline_distance(p: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 3) to the polyline through ``vertices`` (W, 3)."""
    if len(vertices) == 1:
        return np.linalg.norm(p - vertices[0], axis=1)
    out = np.full(len(p), np.inf)
    for a, b in zip(vertices[:-1], vertices[1:], strict=True):
        out = np.minimum(out, segment_distances(p, a, b))
    return out


def mission_of(
    path: FlownPath,
    bound: float,
    allowance: np.ndarray | None = None,
    fits: Callable[[int, int], bool] | None = None,
) -> Mission:
    """The agent's mission: waypoints within ``bound`` of its flown path (and within
    ``allowance`` (K - 1,) of each segment a leg spans, passing ``fits``: see :func:`rdp`), leg
    speeds on its timing."""
    limit = bound if allowance is None else np.minimum(bound, allowance)
    idx = rdp(path.positions, limit, fits)
    wp = path.positions[idx]
    lengths = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    durations = np.diff(path.times[idx])
    speeds = lengths / np.maximum(durations, 1e-9)
    lim = path.limits
    speeds = np.clip(speeds, lim.speed_min, lim.speed_max)
    dev = float(polyline_distance(path.positions, wp).max())
    return Mission(path, wp, idx, speeds, bound, dev)


# ---------------------------------------------------------------------- geodesy


def origin_of(world: dict[str, Any]) -> dict[str, float]:
    """The world's ``origin``, or an :class:`ExportError` naming the missing key."""
    origin = world.get("origin")
    if not isinstance(origin, dict) or "lat" not in origin or "lon" not in origin:
        raise ExportError(
            "the log's world has no origin {lat, lon, alt}: a geodetic export needs one "
            "(add `origin: {lat: ..., lon: ..., alt: ...}` to the world file, or give --origin LAT,LON,ALT)"
        )
    return {"lat": float(origin["lat"]), "lon": float(origin["lon"]), "alt": float(origin.get("alt", 0.0))}


def _pymap3d() -> Any:
    try:
        import pymap3d
    except ImportError:  # pragma: no cover - a declared dependency
        raise ExportError("geodetic exports need pymap3d: pip install pymap3d") from None
    return pymap3d


def to_geodetic(xyz: np.ndarray, origin: dict[str, float]) -> np.ndarray:
    """World points (N, 3) (x east, y north, z up from the origin) as (lat, lon, alt) (N, 3),
    WGS-84 degrees and metres above the origin's reference (altitude = ``origin.alt`` + height
    on the ellipsoid's normal)."""
    pm = _pymap3d()
    p = np.asarray(xyz, float).reshape(-1, 3)
    lat, lon, h = pm.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], origin["lat"], origin["lon"], origin["alt"])
    return np.column_stack([lat, lon, h])


def from_geodetic(lla: np.ndarray, origin: dict[str, float]) -> np.ndarray:
    """The inverse of :func:`to_geodetic`: (lat, lon, alt) (N, 3) as world points."""
    pm = _pymap3d()
    g = np.asarray(lla, float).reshape(-1, 3)
    e, n, u = pm.geodetic2enu(g[:, 0], g[:, 1], g[:, 2], origin["lat"], origin["lon"], origin["alt"])
    return np.column_stack([e, n, u])


# ---------------------------------------------------------------------- mission items


@dataclass(frozen=True)
class Item:
    command: int
    frame: int
    params: tuple[float, float, float, float, float, float, float]  # p1..p4, lat, lon, alt


def items(mission: Mission, origin: dict[str, float], ground: float) -> tuple[list[Item], list[float]]:
    """The mission items and the home position [lat, lon, alt AMSL]. Altitudes of the items are
    relative to home: the ground (``ground``, world z) under the agent's start."""
    wp = mission.waypoints
    start = wp[0]
    home_xyz = np.array([start[0], start[1], ground])
    geo = to_geodetic(np.vstack([home_xyz, wp]), origin)
    home = [float(geo[0, 0]), float(geo[0, 1]), float(origin["alt"] + ground)]
    rel = wp[:, 2] - ground
    lat, lon = geo[1:, 0], geo[1:, 1]
    fixed = mission.fixed_wing
    accept = mission.acceptance_radius()
    out = [
        Item(
            MAV_CMD_NAV_TAKEOFF,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            (TAKEOFF_PITCH_DEG if fixed else 0.0, 0.0, 0.0, math.nan, lat[0], lon[0], rel[0]),
        )
    ]
    speeds = mission.commanded_speeds()
    current = None
    for k in range(1, len(wp)):
        v = float(speeds[k - 1])
        if current is None or v != current:
            out.append(
                Item(
                    MAV_CMD_DO_CHANGE_SPEED,
                    MAV_FRAME_MISSION,
                    (0.0 if fixed else 1.0, v, -1.0, 0.0, 0.0, 0.0, 0.0),
                )
            )
            current = v
        last = k == len(wp) - 1
        if fixed and last:
            # Loiter for good at the goal, on a circle of at least the turn radius (clockwise).
            out.append(
                Item(
                    MAV_CMD_NAV_LOITER_UNLIM,
                    MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    (0.0, 0.0, mission.loiter_radius(), math.nan, lat[k], lon[k], rel[k]),
                )
            )
        else:
            out.append(
                Item(
                    MAV_CMD_NAV_WAYPOINT,
                    MAV_FRAME_GLOBAL_RELATIVE_ALT,
                    (0.0, accept, 0.0, math.nan, lat[k], lon[k], rel[k]),
                )
            )
    return out, home


def plan_json(mission: Mission, its: list[Item], home: list[float]) -> dict[str, Any]:
    """QGroundControl's plan file (fileType Plan, version 1; mission version 2)."""
    lim = mission.path.limits
    qgc_items = []
    for k, it in enumerate(its, start=1):
        params = [None if isinstance(v, float) and math.isnan(v) else float(v) for v in it.params]
        entry: dict[str, Any] = {
            "autoContinue": True,
            "command": it.command,
            "doJumpId": k,
            "frame": it.frame,
            "params": params,
            "type": "SimpleItem",
        }
        if it.frame == MAV_FRAME_GLOBAL_RELATIVE_ALT:
            entry["Altitude"] = float(it.params[6])
            entry["AltitudeMode"] = 1
            entry["AMSLAltAboveTerrain"] = None
        qgc_items.append(entry)
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {
            "version": 2,
            "firmwareType": MAV_AUTOPILOT_PX4,
            "vehicleType": MAV_TYPE_FIXED_WING if mission.fixed_wing else MAV_TYPE_QUADROTOR,
            "cruiseSpeed": float(lim.speed_cruise) if mission.fixed_wing else 15.0,
            "hoverSpeed": float(lim.speed_cruise) if not mission.fixed_wing else 5.0,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": home,
            "items": qgc_items,
        },
    }


def wpl_text(its: list[Item], home: list[float]) -> str:
    """The ``QGC WPL 110`` list: line 0 the home position (absolute altitude), then the items;
    columns index, current, frame, command, p1..p4, lat, lon, alt, autocontinue (tab-separated)."""
    lines = ["QGC WPL 110"]
    row = [0, 1, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, 0.0, 0.0, 0.0, 0.0, home[0], home[1], home[2], 1]
    lines.append("\t".join(_fmt(v) for v in row))
    for k, it in enumerate(its, start=1):
        p = [0.0 if isinstance(v, float) and math.isnan(v) else v for v in it.params]
        lines.append("\t".join(_fmt(v) for v in [k, 0, it.frame, it.command, *p, 1]))
    return "\n".join(lines) + "\n"


def _fmt(v: float | int) -> str:
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return f"{float(v):.8f}" if abs(float(v)) < 1e4 else repr(float(v))


def plan_text(mission: Mission, its: list[Item], home: list[float]) -> str:
    return json.dumps(plan_json(mission, its, home), indent=2) + "\n"


ARC_STEP = 0.05  # rad: a rounded corner is drawn as chords of this angle (drawn 3e-4 r inside)


def corner_geometry(mission: Mission) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per waypoint (W,): the speed a multirotor passes it at, the distance from it at which its
    turn leaves and rejoins the legs, and the turn angle (0 straight on). The turn is PX4's
    (``computeMaxSpeedInWaypoint``): the circle tangent to both legs at the distance
    d = the acceptance radius from the waypoint (at most half of either leg), radius
    r = d tan(alpha / 2), flown at the speed sqrt(a r) that turns at the agent's max_accel a
    (alpha the angle between the legs, pi straight on). The first and the last waypoint: 0
    (from rest, to rest)."""
    wp = mission.waypoints
    speed = np.zeros(len(wp))
    reach = np.zeros(len(wp))
    turn = np.zeros(len(wp))
    if len(wp) > 2:
        u = wp[:-2] - wp[1:-1]
        w = wp[2:] - wp[1:-1]
        nu, nw = np.linalg.norm(u, axis=1), np.linalg.norm(w, axis=1)
        cos = np.clip(np.einsum("ij,ij->i", u, w) / np.maximum(nu * nw, 1e-300), -1.0, 1.0)
        half = 0.5 * np.arccos(cos)
        d = np.minimum(mission.acceptance_radius(), 0.5 * np.minimum(nu, nw))
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            speed[1:-1] = np.sqrt(mission.path.limits.max_accel * d * np.tan(np.minimum(half, 0.5 * np.pi)))
        reach[1:-1] = d
        turn[1:-1] = np.pi - 2.0 * half
        degenerate = (nu == 0) | (nw == 0)  # a repeated point is no corner
        speed[1:-1][degenerate] = np.inf
        reach[1:-1][degenerate] = 0.0
        turn[1:-1][degenerate] = 0.0
    return speed, reach, turn


def corner_speeds(mission: Mission) -> np.ndarray:
    """The speed a multirotor passes each waypoint at (:func:`corner_geometry`)."""
    return corner_geometry(mission)[0]


def rounded(mission: Mission) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path a multirotor flies the mission on: the waypoint polyline with each corner turned
    on its circle (:func:`corner_geometry`), as vertices (M, 3), and the speed cap of each of its
    pieces (M - 1,): the leg's commanded speed, on a turn also its corner speed (the turn's
    acceleration is then at most max_accel). Every point of it lies within the acceptance
    radius of the waypoint polyline (the turn stays inside the triangle of its waypoint and its
    two tangent points). Third, the speed at each vertex (M,): 0 at the ends and where the path
    turns back on itself, else unbounded (inf)."""
    wp = mission.waypoints
    legs = mission.commanded_speeds()
    speed, reach, turn = corner_geometry(mission)
    verts = [wp[0]]
    caps: list[float] = []
    at = [0.0]
    for i in range(1, len(wp)):
        leg = float(legs[i - 1])
        if i == len(wp) - 1 or turn[i] < 1e-9 or reach[i] <= 0 or turn[i] > np.pi - 1e-9:
            verts.append(wp[i])  # straight on, a reversal (stops there) or the end
            caps.append(leg)
            at.append(float(speed[i]) if i < len(wp) - 1 else 0.0)
            continue
        e1 = (wp[i] - wp[i - 1]) / np.linalg.norm(wp[i] - wp[i - 1])
        e2 = (wp[i + 1] - wp[i]) / np.linalg.norm(wp[i + 1] - wp[i])
        normal = e2 - (e1 @ e2) * e1
        normal /= np.linalg.norm(normal)
        r = reach[i] / math.tan(0.5 * turn[i])
        t1 = wp[i] - reach[i] * e1
        centre = t1 + r * normal
        theta = np.linspace(0.0, turn[i], max(2, int(np.ceil(turn[i] / ARC_STEP)) + 1))
        arc = centre + r * (-np.cos(theta)[:, None] * normal + np.sin(theta)[:, None] * e1)
        verts.append(t1)
        caps.append(leg)
        verts.extend(arc[1:])
        caps.extend([min(leg, float(legs[i]), float(speed[i]))] * (len(arc) - 1))
        at.extend([math.inf] * len(arc))
    return np.array(verts), np.array(caps), np.array(at)


def speed_profile(
    s: np.ndarray, caps: np.ndarray, at: np.ndarray, at_speeds: np.ndarray, accel: float
) -> np.ndarray:
    """The fastest speeds at arc lengths ``s`` (sorted) within ``caps`` there and ``at_speeds``
    at the arc lengths ``at``, changing at most at ``accel``: v(s)^2 = min over every cap
    (c_i, s_i) of c_i^2 + 2 accel |s - s_i| (two running minima)."""
    pts = np.concatenate([s, at])
    c2 = np.concatenate([caps, at_speeds]) ** 2
    order = np.argsort(pts, kind="stable")
    pts, c2 = pts[order], c2[order]
    fwd = np.minimum.accumulate(c2 - 2 * accel * pts)
    bwd = np.minimum.accumulate((c2 + 2 * accel * pts)[::-1])[::-1]
    i = np.searchsorted(pts, s, side="right") - 1
    j = np.searchsorted(pts, s, side="left")
    return np.sqrt(np.maximum(np.minimum(fwd[i] + 2 * accel * s, bwd[j] - 2 * accel * s), 0.0))


def timed(mission: Mission, step: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The mission flown on its own timing: times (K,) from its start and positions (K, 3), every
    ``step`` s (default: the log's step). A multirotor flies the rounded path (:func:`rounded`)
    at the legs' commanded speeds, changing speed at its max_accel, from rest at the start to
    rest at the end, and turns each corner at most at its corner speed; a fixed wing flies the
    waypoint polyline at speed throughout."""
    lim = mission.path.limits
    if step is None:
        step = float(np.median(np.diff(mission.path.times)))
    if mission.fixed_wing:
        wp, caps = mission.waypoints, mission.commanded_speeds()
        at = np.full(len(wp), math.inf)
    else:
        wp, caps, at = rounded(mission)
    seg = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    if total <= 0:
        return np.array([0.0, step]), np.vstack([wp[0], wp[0]])
    slowest = float(mission.commanded_speeds().min())
    ds = max(min(step * max(slowest, 1e-3) / 4.0, total / 4.0), 1e-4)
    s = np.linspace(0.0, total, int(np.ceil(total / ds)) + 1)
    mid = 0.5 * (s[1:] + s[:-1])  # speeds at the middles of the fine steps: never 0 at a rest end
    piece = np.clip(np.searchsorted(cum, mid, side="right") - 1, 0, len(seg) - 1)
    v = np.maximum(caps[piece], 1e-3)
    if not mission.fixed_wing:
        stop = np.isfinite(at)
        v = speed_profile(mid, v, cum[stop], at[stop], max(lim.max_accel, 1e-9))
    t_s = np.concatenate([[0.0], np.cumsum(np.diff(s) / np.maximum(v, 1e-6))])
    grid = np.arange(0.0, t_s[-1] + 0.5 * step, step)
    grid[-1] = t_s[-1] if grid[-1] > t_s[-1] else grid[-1]
    if grid[-1] < t_s[-1]:
        grid = np.append(grid, t_s[-1])
    s_at = np.interp(grid, t_s, s)
    pos = np.column_stack([np.interp(s_at, cum, wp[:, j]) for j in range(3)])
    return grid, pos
