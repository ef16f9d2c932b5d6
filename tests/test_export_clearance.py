"""Missions as safe as the flown path: each leg of the waypoint reduction within the clearance
the path had there (bodies, terrain), and the mission's timing with PX4's corner speeds."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world  # noqa: E402

from swarmplan.export import clearance, mission  # noqa: E402
from swarmplan.export.source import AgentLimits, FlownPath  # noqa: E402
from swarmplan.replay import Recording  # noqa: E402
from swarmplan.replay.geometry import terrain_height  # noqa: E402

RADIUS = 0.25
BOX = {"id": "box", "shape": "box", "size": [4.0, 4.0, 10.0], "position": [0.0, 0.0, 5.0]}


def recording(obstacles: list[dict], **extra) -> Recording:
    world = base_world(
        [{"id": "a", "start": [0, 0, 5], "goal": [1, 1, 5], "radius": RADIUS}], obstacles, **extra
    )
    one = np.zeros((1, 1, 3))
    return Recording(
        file="synthetic.mcap",
        world=world,
        times=np.zeros(1),
        agent_ids=["a"],
        positions=one,
        velocities=one,
        modes=np.full((1, 1), "apf"),
        goals=np.zeros((1, 3)),
        radii=np.array([RADIUS]),
    )


def limits(**over) -> AgentLimits:
    base = dict(id="a", model="multirotor", radius=RADIUS, speed_min=0.0, speed_max=2.0,
                speed_cruise=1.0, max_accel=2.0, min_turn_radius=1.0, max_climb_angle_deg=45.0,
                separation=(1.0, 1.0, 1.0))  # fmt: skip
    base.update(over)
    return AgentLimits(**base)


def l_path() -> FlownPath:
    """From (0, 2.6) east to (2.6, 2.6), then south to (2.6, 0), at z = 5, every 0.1 m at 1 m/s:
    0.6 m off two faces of the box (x, y in [-2, 2]) and 0.85 m off its corner edge."""
    east = np.column_stack([np.arange(0.0, 2.6, 0.1), np.full(26, 2.6)])
    south = np.column_stack([np.full(27, 2.6), np.arange(2.6, -0.05, -0.1)])
    xy = np.vstack([east, south])
    pos = np.column_stack([xy, np.full(len(xy), 5.0)])
    return FlownPath(limits(), 0.1 * np.arange(len(pos)), pos, True)


def box_distance(p: np.ndarray) -> np.ndarray:
    """Exact distance of points (N, 3) to the box's surface (outside)."""
    q = np.abs(p - np.array(BOX["position"])) - 0.5 * np.array(BOX["size"])
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def leg_points(wp: np.ndarray, spacing: float = 1e-3) -> np.ndarray:
    return clearance.densify_path(np.arange(len(wp), dtype=float), wp, spacing)[1]


def test_plain_reduction_cuts_the_box_corner():
    path = l_path()
    idx = mission.rdp(path.positions, 2.0)
    assert idx.tolist() == [0, len(path.positions) - 1]  # the corner lies 1.84 m off the chord
    assert box_distance(leg_points(path.positions[idx])).min() < 0  # through the box


@pytest.mark.parametrize("margin", [0.0, 0.25])
def test_legs_keep_the_flown_clearance_round_the_box_corner(margin):
    path = l_path()
    rec = recording([BOX])
    allow = clearance.leg_allowance(rec, "a", path.times, path.positions, RADIUS, margin)
    assert allow.shape == (len(path.positions) - 1,) and (allow >= 0).all()
    # along a face, 0.6 m off it: 0.6 - radius - margin less a quarter radius (the sampling)
    assert np.allclose(allow[:20], 0.6 - RADIUS - margin - RADIUS / 4)
    m = mission.mission_of(path, 2.0, allow)
    assert m.indices.tolist() == [0, 26, 52]  # the corner (2.6, 2.6) is kept
    keep = RADIUS + margin
    flown = box_distance(leg_points(path.positions, 0.01)).min()
    assert box_distance(leg_points(m.waypoints)).min() >= min(keep, flown) - 1e-9
    assert m.max_deviation <= allow.max() + 1e-12 < 2.0


def test_an_allowance_of_zero_keeps_every_point_off_the_line():
    k = np.arange(11.0)
    pts = np.vstack([np.column_stack([k, np.zeros(11), np.zeros(11)]), [[10.0, 1.0, 0.0], [10.0, 2.0, 0.0]]])
    assert mission.rdp(pts, np.zeros(len(pts) - 1)).tolist() == [0, 10, 12]  # exactly collinear
    wiggle = pts + np.array([0.0, 0.0, 1e-3]) * (np.arange(len(pts)) % 2)[:, None]
    assert len(mission.rdp(wiggle, np.zeros(len(wiggle) - 1))) == len(wiggle)


def ring_round_bodies(seed: int) -> tuple[Recording, FlownPath]:
    """A turned box at the origin and spheres beyond it; a path winding round the box 0.3-2.7 m
    off its faces, up and down by a metre."""
    rng = np.random.default_rng(seed)
    bodies = [{"id": "box", "shape": "box", "size": rng.uniform(2.0, 3.5, 3).tolist(), "position": [0, 0, 0],
               "rotation": [0, 0, float(rng.uniform(0, 90))]}]  # fmt: skip
    for k in range(4):
        ang = rng.uniform(0, 2 * np.pi)
        at = [6 * np.cos(ang), 6 * np.sin(ang), float(rng.uniform(-1, 1))]
        bodies.append(
            {"id": f"s{k}", "shape": "sphere", "radius": float(rng.uniform(0.3, 1.0)), "position": at}
        )
    th = np.linspace(0.0, 3 * np.pi, 300)
    smooth = lambda: np.interp(th, np.linspace(0, 3 * np.pi, 12), rng.uniform(0, 1, 12))  # noqa: E731
    rho = 2.8 + 2.0 * smooth()
    pos = np.column_stack([rho * np.cos(th), rho * np.sin(th), 2.0 * smooth() - 1.0])
    return recording(bodies), FlownPath(limits(), 0.1 * np.arange(len(pos)), pos, True)


@pytest.mark.parametrize("seed", range(8))
def test_every_leg_keeps_the_clearance_its_span_had(seed):
    # Each leg's distance to every body is at least min(radius + margin, the least the flown
    # path kept over the leg's span); the plain reduction (bound 3 m) breaks that on every draw.
    rec, path = ring_round_bodies(seed)
    pos = path.positions
    margin = 0.1

    def dist(p: np.ndarray) -> float:
        d = clearance.body_distances(rec, ["a"], np.zeros(len(p)), p[None], np.array([RADIUS]))
        return float(min(v.min() for v in d.values()))

    def broken(idx: np.ndarray) -> int:
        return sum(
            dist(leg_points(pos[[a, b]], 0.01))
            < min(RADIUS + margin, dist(leg_points(pos[a : b + 1], 0.01))) - 1e-9
            for a, b in zip(idx[:-1], idx[1:], strict=True)
        )

    allow = clearance.leg_allowance(rec, "a", path.times, pos, RADIUS, margin)
    assert broken(mission.rdp(pos, 3.0)) > 0
    assert broken(mission.mission_of(path, 3.0, allow).indices) == 0


def test_terrain_legs_keep_the_height_the_path_kept():
    peak = {"center": [0.0, 0.0], "height": 10.0, "spread": [5.0, 5.0]}
    world = {"terrain": {"peaks": [peak]}}
    # Round the hill's foot 1 m above the terrain: the chord between the ends crosses the hill.
    th = np.linspace(-0.5 * np.pi, 0.5 * np.pi, 200)
    xy = np.column_stack([6.0 * np.cos(th), 6.0 * np.sin(th)])
    pos = np.column_stack([xy, terrain_height(world, xy) + 1.0])
    assert terrain_height(world, np.zeros((1, 2)))[0] > pos[:, 2].max()  # the chord goes through
    fits = clearance.terrain_test(world, pos, RADIUS, 0.25)
    assert fits is not None and not fits(0, len(pos) - 1) and fits(0, 1)
    idx = mission.rdp(pos, 5.0, fits)
    legs = leg_points(pos[idx], 0.01)
    tol = clearance.TERRAIN_TOLERANCE * RADIUS  # the dip allowed between the leg's samples
    assert (clearance.heights(world, legs) >= 0.5 - tol).all()  # radius + margin, which the path kept
    assert clearance.terrain_test({"terrain": None}, pos, RADIUS, 0.25) is None  # flat ground


def test_terrain_slope_bound():
    world = {"terrain": {"peaks": [{"center": [0, 0], "height": 10.0, "spread": [5.0, 8.0]}]}}
    g = clearance.terrain_slope(world)
    assert g == pytest.approx(10.0 * math.sqrt(2 / math.e) / 5.0)
    x = np.linspace(0.0, 20.0, 20001)
    z = terrain_height(world, np.column_stack([x, np.zeros_like(x)]))
    assert np.abs(np.diff(z) / np.diff(x)).max() == pytest.approx(g, rel=1e-4)  # reached along x


def test_corner_speeds_follow_the_turn():
    path = FlownPath(limits(), np.arange(5.0), np.zeros((5, 3)), True)
    wp = np.array([[0, 0, 0], [4, 0, 0], [8, 0, 0], [8, 4, 0], [4, 4, 0.0]])
    m = mission.Mission(path, wp, np.arange(5), np.ones(4), 1.0, 0.0)
    v = mission.corner_speeds(m)
    a, d = 2.0, RADIUS
    assert v[0] == 0.0 and v[-1] == 0.0
    assert v[1] > 1e6  # straight on: no limit
    assert v[2] == pytest.approx(math.sqrt(a * d * math.tan(math.pi / 4)))  # a right angle
    assert v[3] == pytest.approx(v[2])


def test_speed_profile_is_the_accel_envelope():
    s = np.linspace(0.0, 10.0, 1001)
    v = mission.speed_profile(
        s, np.full_like(s, 2.0), np.array([0.0, 5.0, 10.0]), np.array([0.0, 0.5, 0.0]), 1.0
    )
    exact = np.minimum.reduce([np.full_like(s, 2.0), np.sqrt(2 * s), np.sqrt(0.25 + 2 * np.abs(s - 5.0)),
                               np.sqrt(2 * (10.0 - s))])  # fmt: skip
    assert np.allclose(v, exact, atol=1e-12)


def test_the_timed_mission_passes_a_corner_at_its_corner_speed():
    path = l_path()
    m = mission.mission_of(path, 2.0, np.zeros(len(path.positions) - 1))
    t, pos = mission.timed(m, 0.01)
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / np.diff(t)
    corner = np.linalg.norm(0.5 * (pos[1:] + pos[:-1]) - m.waypoints[1], axis=1).argmin()
    assert speed[corner] <= mission.corner_speeds(m)[1] + 2.0 * 0.01 * 2.0  # within a step's change
    assert speed.max() <= path.limits.speed_max + 1e-9


def test_the_rounded_mission_turns_on_the_corner_circle_within_max_accel():
    path = l_path()
    wp = np.array([[0.0, 2.6, 5.0], [2.6, 2.6, 5.0], [2.6, 0.0, 5.0]])  # one right-angle corner
    m = mission.Mission(path, wp, np.array([0, 26, 52]), np.ones(2), 0.1, 0.0)
    corner = wp[1]
    verts, caps, at = mission.rounded(m)
    d = RADIUS  # the acceptance radius; a right angle: r = d tan(45 deg) = d
    centre = corner + np.array([-d, -d, 0.0])
    arc = np.linalg.norm(verts - corner, axis=1) < d - 1e-9
    assert arc.sum() > 10
    assert np.allclose(np.linalg.norm(verts[arc] - centre, axis=1), d)  # on the circle
    assert mission.polyline_distance(verts, m.waypoints).max() <= d + 1e-12
    assert at[0] == 0.0 and at[-1] == 0.0 and np.isinf(at[1:-1]).all()
    v_corner = math.sqrt(2.0 * d)  # sqrt(a r)
    assert caps[1:-1][np.isfinite(caps[1:-1])].min() == pytest.approx(v_corner)
    t, pos = mission.timed(m, 0.05)
    vel = np.diff(pos, axis=0) / np.diff(t)[:, None]
    acc = np.linalg.norm(np.diff(vel, axis=0), axis=1) / np.diff(0.5 * (t[1:] + t[:-1]))
    turning = np.linalg.norm(pos[1:-1] - corner, axis=1) < d
    assert turning.sum() >= 3
    assert acc[turning].max() <= 2.0 * 1.05  # the turn at max_accel (drawn in chords)
    assert acc.max() <= 2.0 * 1.25  # the start and the stop: the speed profile's own steps


def test_path_distance_to_a_dense_polyline():
    from swarmplan.export.check import path_distance

    line = np.column_stack([np.linspace(0.0, 10.0, 1001), np.zeros(1001), np.zeros(1001)])
    pts = np.array([[5.0, 0.3, 0.0], [5.004, 0.0, -0.2], [-1.0, 0.0, 0.0], [10.0, 3.0, 4.0]])
    assert np.allclose(path_distance(pts, line), [0.3, 0.2, 1.0, 5.0], atol=1e-12)
    # Behind or ahead on the path is no deviation; beside it is.
    corner = np.vstack(
        [line, np.column_stack([np.full(1000, 10.0), np.linspace(0.01, 10.0, 1000), np.zeros(1000)])]
    )
    assert path_distance(np.array([[9.9, 0.1, 0.0]]), corner)[0] == pytest.approx(0.1)


def test_bench_export_counts_per_class_and_format():
    from swarmplan.export.bench import markdown, table

    def entry(ok: bool, contacts: int = 0, sep: int = 0, dev: float = 0.5, lost: int | None = None) -> dict:
        return {"ok": ok, "contacts": contacts, "separation_entries": sep,
                "separation_lost": sep if lost is None else lost, "deviation_over_limit": dev,
                "deviation_over_bound": 0.9, "waypoints": 7}  # fmt: skip

    records = [
        {"name": "w0", "agents": 2, "flight_contacts": 0, "px4": entry(True)},
        {"name": "w1", "agents": 3, "flight_contacts": 1, "px4": entry(False, contacts=2)},
        {"name": "w2", "agents": 1, "flight_contacts": 0, "px4": entry(False, dev=1.5)},
        {"name": "w3", "agents": 1, "flight_contacts": 0, "px4": {"refused": "agent a: ..."}},
        {
            "name": "w4",
            "agents": 2,
            "flight_contacts": 0,
            "flight_near_misses": 1,
            "px4": entry(False, sep=3),
        },
        # inside a separation ellipsoid only where, and as deep as, its flight itself was
        {
            "name": "w5",
            "agents": 2,
            "flight_contacts": 0,
            "flight_near_misses": 2,
            "px4": entry(True, sep=4, lost=0),
        },
    ]
    t = table("lab", "px4", records)
    assert (t["worlds"], t["exported"], t["ok"], t["clean_flights"], t["ok_of_clean"]) == (6, 5, 2, 2, 1)
    assert (t["safe"], t["safe_of_clean"], t["with_contact"], t["separation_lost"]) == (3, 2, 1, 1)
    assert t["deviation_broken"] == 1
    assert t["check_deviation_over_limit"] == 1.5 and t["waypoints"] == 7 and t["pieces"] is None
    assert "| lab | px4 | 5/6 | 2/5 | 1/2 | 3/5 | 2/2 | 1 | 1 | 1 |" in markdown([t])


def test_bench_export_refuses_bad_arguments(capsys):
    from swarmplan.cli.bench import main

    assert main(["export", "--worlds", "0", "--class", "moon"]) == 2
    err = capsys.readouterr().err
    assert "--worlds: must be >= 1" in err and "--class: expected one of" in err
