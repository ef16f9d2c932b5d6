"""Exports of flown paths: Crazyflie polynomials, PX4/ArduPilot missions, CSV; ``--check``."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world, states_from_arrays, write_log  # noqa: E402

from swarmplan.cli.export import main as cli_main  # noqa: E402
from swarmplan.export import crazyflie, mission  # noqa: E402
from swarmplan.export.source import AgentLimits, FlownPath, LimitError  # noqa: E402
from swarmplan.world import WorldError, load_world  # noqa: E402
from swarmplan.world.tracker_config import G  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DT = 0.05
ORIGIN = {"lat": 47.3977, "lon": 8.5456, "alt": 488.0}


def min_jerk(t: np.ndarray, t1: float) -> np.ndarray:
    s = np.clip(t / t1, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def limits(**over) -> AgentLimits:
    base = dict(
        id="cf",
        model="multirotor",
        radius=0.05,
        speed_min=0.0,
        speed_max=1.0,
        speed_cruise=0.8,
        max_accel=1.5,
        min_turn_radius=0.5,
        max_climb_angle_deg=45.0,
        separation=(0.5, 0.5, 0.5),
    )
    base.update(over)
    return AgentLimits(**base)


def line_path(**over) -> FlownPath:
    t = DT * np.arange(161)  # 8 s, rest to rest
    a, b = np.array([0.5, 0.5, 1.0]), np.array([3.5, 2.5, 1.5])
    pos = a + min_jerk(t, 8.0)[:, None] * (b - a)
    return FlownPath(limits(**over), t, pos, True)


def circle_path(**over) -> FlownPath:
    t = DT * np.arange(241)  # one turn of radius 1 m in 12 s, rest to rest
    th = 2 * np.pi * min_jerk(t, 12.0)
    pos = np.column_stack([2 + np.cos(th), 2 + np.sin(th), np.full_like(th, 1.2)])
    return FlownPath(limits(**over), t, pos, True)


def test_memory_holds_31_pieces_of_132_bytes():
    assert crazyflie.PIECE_BYTES == 132  # 33 float32: 4 x 8 coefficients and the duration
    assert crazyflie.MAX_PIECES == 31 == 4096 // 132


def flown(accels: np.ndarray, start: np.ndarray, **over) -> FlownPath:
    """A path as the simulator flies it from rest: per step v += a dt, then x += v dt."""
    v = np.cumsum(accels * DT, axis=0)
    pos = start + np.vstack([np.zeros(3), np.cumsum(v * DT, axis=0)])
    return FlownPath(limits(**over), DT * np.arange(len(pos)), pos, True)


def bang_bang_line(direction=(3.0, 2.0, 0.5), a=1.5) -> FlownPath:
    """Rest to rest along a line at the acceleration limit: 13 steps at +a, 40 at speed, 13 at -a."""
    u = np.asarray(direction) / np.linalg.norm(direction)
    sign = np.concatenate([np.ones(13), np.zeros(40), -np.ones(13)])
    return flown(sign[:, None] * a * u, np.array([0.5, 0.5, 1.0]), max_accel=a)


def test_ldp_exact_answers():
    y = crazyflie._ldp(np.array([[1.0, 1.0]]), np.array([2.0]))  # min |y| with y1 + y2 >= 2
    assert np.allclose(y, [1.0, 1.0], atol=1e-12)
    y = crazyflie._ldp(np.array([[1.0, 0.0], [0.0, 1.0]]), np.array([-1.0, 3.0]))  # y1 >= -1 is slack
    assert np.allclose(y, [0.0, 3.0], atol=1e-12)
    # y1 >= 1 and y1 <= 0: no answer
    assert crazyflie._ldp(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0])) is None


def test_a_line_flown_at_the_acceleration_limit_fits_within_the_limits():
    path = bang_bang_line()
    # The flown steps use the whole limit, so a smooth curve through them would break it.
    steps = np.diff(path.positions, axis=0) / DT
    assert np.linalg.norm(np.diff(steps, axis=0), axis=1).max() / DT == pytest.approx(1.5)
    # Leaving a hover, the trajectory takes up its acceleration over a ramp centred on the flown
    # path's step (it starts before it), so it does not fall behind a path that flies on at the
    # speed limit: 5 mm hold.
    fit = crazyflie.fit(path, 0.005)
    assert fit.max_deviation <= 0.005 and fit.max_speed <= 1.0 and fit.max_accel <= 1.5
    assert fit.max_jerk <= crazyflie.jerk_limit(path)
    # From rest half a step and the ramp's half (sqrt(6 * 0.005 / 1.5) = 0.141 s) before the
    # first recorded position, to rest as long after the last.
    half = math.sqrt(0.02)
    assert crazyflie.ramp_time(path, 0.005) == pytest.approx(half)
    assert fit.lead == pytest.approx(DT / 2 + half)
    assert fit.poly.duration == pytest.approx(path.duration + DT + 2 * half, abs=1e-6)
    poly = fit.poly
    t = np.linspace(0.0, poly.duration, 20001)
    assert np.linalg.norm(poly.evaluate(t, 2)[:, :3], axis=1).max() <= 1.5
    assert np.linalg.norm(poly.evaluate(t, 1)[:, :3], axis=1).max() <= 1.0
    assert np.allclose(poly.evaluate(np.array([0.0, poly.duration]), 1)[:, :3], 0.0, atol=1e-6)
    assert np.allclose(poly.evaluate(np.array([0.0, poly.duration]), 2)[:, :3], 0.0, atol=1e-4)  # hover
    assert np.allclose(poly.evaluate(np.array([0.0, poly.duration]))[:, :3],
                       path.positions[[0, -1]], atol=1e-5)  # fmt: skip
    jumps = poly.joint_jumps()
    assert jumps[0] < 1e-5 and jumps[1] < 1e-4 and jumps[2] < 1e-3  # float32 rounding only
    # Near the line (the motion, the limits and the bound are symmetric about it; the least
    # distance programme's solution under the cutting planes is not exactly, 0.6 mm off it at
    # most here), and the least-squares fit on it.
    u = path.positions[-1] - path.positions[0]
    u /= np.linalg.norm(u)
    rel = poly.evaluate(t)[:, :3] - path.positions[0]
    assert np.linalg.norm(rel - np.outer(rel @ u, u), axis=1).max() < 0.05 * 0.02


def test_the_ramp_from_a_step_of_the_acceleration_keeps_its_bound():
    # A step from rest to a at t = 0, and a linear rise of the acceleration over T centred on it
    # (T twice the ramp time): the rise is ahead by a T^2 / 48 = e / 2 at the step and by
    # a T^2 / 24 = e from T / 2 on, with the same velocity.
    a, e = 1.5, 0.005
    half = crazyflie.ramp_time(line_path(max_accel=a), e)
    t = np.linspace(-half, 3 * half, 40001)
    step = 0.5 * a * np.maximum(t, 0.0) ** 2
    rise = np.clip((t + half) / (2 * half), 0.0, 1.0) * a
    dt = t[1] - t[0]
    v = np.concatenate([[0.0], np.cumsum(0.5 * (rise[1:] + rise[:-1]) * dt)])
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    gap = x - np.interp(t, t, step)
    assert gap[np.searchsorted(t, 0.0)] == pytest.approx(e / 2, rel=1e-3)
    assert np.abs(gap).max() == pytest.approx(e, rel=1e-3) and gap[-1] == pytest.approx(e, rel=1e-3)
    assert v[-1] == pytest.approx(a * t[-1], rel=1e-6)


def steady_circle(radius: float, rate: float, max_accel: float) -> FlownPath:
    """A circle flown at ``rate`` rad/s for 2 s between a second's rise and a second's fall."""
    t = DT * np.arange(81)
    w = rate * np.minimum(min_jerk(t, 1.0), min_jerk(4.0 - t, 1.0))
    th = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * DT)])
    pos = np.column_stack([2 + radius * np.cos(th), 2 + radius * np.sin(th), np.full_like(th, 1.2)])
    return FlownPath(limits(max_accel=max_accel, speed_max=3.0), t, pos, True)


def test_the_jerk_a_crazyflie_can_produce_bounds_the_fit():
    # 0.3 m at 5 rad/s: 7.5 m/s^2 (within 9) and a jerk of r w^3 = 37.5 m/s^3, beyond the
    # 2000 deg/s x (g - 9 m/s^2) = 28.3 m/s^3 a Crazyflie produces there. A circle of the same
    # timing within that jerk has a radius of at most 28.3 / 125 = 0.226 m: 7.4 cm inside (the
    # rise and the fall leave a little room: 5 cm is out of reach).
    path = steady_circle(0.3, 5.0, 9.0)
    limit = crazyflie.jerk_limit(path)
    assert limit == pytest.approx(math.radians(2000.0) * (G - 9.0))
    fit = crazyflie.fit(path, 0.1)
    assert fit.max_jerk <= limit and fit.max_accel <= 9.0 and fit.max_deviation <= 0.1
    with pytest.raises(LimitError, match=r"jerk <= 28 m/s\^3"):
        crazyflie.fit(path, 0.05, max_pieces=6)


def test_circle_fits_continuous_to_acceleration_within_limits():
    path = circle_path()
    fit = crazyflie.fit(path, 0.005)
    assert 1 < fit.poly.n_pieces <= crazyflie.MAX_PIECES
    assert fit.max_deviation <= 0.005
    jumps = fit.poly.joint_jumps()
    assert jumps[0] < 1e-5 and jumps[1] < 1e-4 and jumps[2] < 1e-3  # float32 rounding only
    t = np.linspace(0.0, fit.poly.duration, 4001)
    r = np.linalg.norm(fit.poly.evaluate(t)[:, :2] - 2.0, axis=1)
    assert np.abs(r - 1.0).max() <= 0.005
    assert np.linalg.norm(fit.poly.evaluate(t, 1)[:, :3], axis=1).max() <= 1.0
    assert np.linalg.norm(fit.poly.evaluate(t, 2)[:, :3], axis=1).max() <= 1.5


def test_csv_round_trip_and_header():
    fit = crazyflie.fit(circle_path(), 0.01)
    text = crazyflie.csv_text(fit.poly)
    header = text.splitlines()[0].split(",")
    assert header[:3] == ["Duration", "x^0", "x^1"] and header[-1] == "yaw^7" and len(header) == 33
    back = crazyflie.read_csv(text)
    assert np.array_equal(back.coeffs, fit.poly.coeffs) and np.array_equal(back.durations, fit.poly.durations)


def test_a_path_beyond_the_limits_on_its_timing_is_refused_with_the_limits_it_needs():
    with pytest.raises(LimitError) as err:
        # 3.64 m rest to rest in 8 s: 0.33 m/s^2 at least on the flown timing, and 0.16 m/s^2
        # with the ramps of sqrt(6 * 0.01 / 0.1) = 0.77 s at its ends (4 d / T^2, T = 9.6 s)
        crazyflie.fit(line_path(max_accel=0.1), 0.01, max_pieces=4)
    msg = str(err.value)
    assert "acceleration <= 0.1 m/s^2" in msg and "needs" in msg and "\n" not in msg


def test_a_path_beyond_the_memory_is_refused_with_the_bound_that_fits():
    path = bang_bang_line()
    with pytest.raises(LimitError) as err:
        crazyflie.fit(path, 0.0005, max_pieces=8)
    msg = str(err.value)
    assert "at most 8 equal pieces (1056 of the 4096-byte trajectory memory)" in msg and "\n" not in msg
    bound = float(msg.split("--max-deviation ")[1].split()[0])
    fit = crazyflie.fit(path, bound, max_pieces=8)  # what the message says fits, fits
    assert fit.max_deviation <= bound and fit.max_accel <= 1.5 and fit.poly.n_pieces <= 8
    with pytest.raises(LimitError):
        crazyflie.fit(path, 0.9 * bound, max_pieces=8)  # and not much less


def test_rdp_keeps_every_point_within_the_bound():
    rng = np.random.default_rng(4)
    pts = np.cumsum(rng.normal(size=(400, 3)), axis=0)
    for bound in (0.5, 2.0, 5.0):
        idx = mission.rdp(pts, bound)
        assert idx[0] == 0 and idx[-1] == len(pts) - 1
        assert mission.polyline_distance(pts, pts[idx]).max() <= bound
    assert len(mission.rdp(np.linspace([0, 0, 0], [10, 5, 2], 50), 0.01)) == 2  # a straight line


def test_geodetic_round_trip():
    xyz = np.array([[0.0, 0.0, 0.0], [1000.0, -2000.0, 150.0], [-5000.0, 8000.0, 30.0]])
    geo = mission.to_geodetic(xyz, ORIGIN)
    assert np.allclose(geo[0], [ORIGIN["lat"], ORIGIN["lon"], ORIGIN["alt"]])
    assert geo[1, 0] < ORIGIN["lat"] and geo[1, 1] > ORIGIN["lon"]  # south-east: y north, x east
    assert np.abs(mission.from_geodetic(geo, ORIGIN) - xyz).max() < 1e-6


def test_origin_is_validated():
    raw = {"name": "w", "bounds": {"min": [0, 0, 0], "max": [10, 10, 10]}, "origin": {"lat": 91, "lon": 8},
           "agents": [{"id": "a", "start": [1, 1, 6], "goal": [9, 9, 6]}]}  # fmt: skip
    path = Path(os.environ.get("TMPDIR", "/tmp")) / "swarmplan-origin-test.yaml"
    import yaml

    path.write_text(yaml.safe_dump(raw))
    try:
        with pytest.raises(WorldError, match=r"origin.lat: must be <= 90"):
            load_world(path)
        raw["origin"] = {"lat": 47.0, "lon": 8.0}
        path.write_text(yaml.safe_dump(raw))
        assert load_world(path).resolved["origin"] == {"lat": 47.0, "lon": 8.0, "alt": 0.0}
    finally:
        path.unlink()


# ---------------------------------------------------------------------- logs and the command


def make_log(
    path: Path, origin: bool = True, cut: bool = False, agents: int = 2, spacing: float = 1.0
) -> str:
    t = DT * np.arange(161)
    pos = []
    for i in range(agents):
        a, b = np.array([0.5, 0.5 + spacing * i, 1.0]), np.array([3.5, 0.5 + spacing * i, 1.2])
        pos.append(a + min_jerk(t, 7.0)[:, None] * (b - a))
    pos = np.array(pos).reshape(agents, len(t), 3)
    ids = [f"cf{i + 1}" for i in range(agents)]
    specs = [{"id": ids[i], "start": pos[i, 0].tolist(), "goal": pos[i, -1].tolist(), "radius": 0.05,
              "speed": {"min": 0.0, "max": 1.0, "cruise": 0.8}, "max_accel": 1.5,
              "separation": [0.5, 0.5, 0.5]} for i in range(agents)]  # fmt: skip
    extra = {"origin": ORIGIN} if origin else {}
    world = base_world(specs, **extra)
    world["bounds"] = {"min": [0, 0, 0], "max": [4, 4, 3]}
    world["sim"] = {"dt": DT, "max_time": 10.0, "goal_tolerance": 0.1}
    modes = [["apf"] * 140 + ["arrived"] * 21 for _ in range(agents)]
    states = (
        states_from_arrays(t, ids, pos, modes=modes, goals=pos[:, -1])
        if agents
        else [{"t": float(x), "agents": []} for x in t]
    )
    summary = {"interrupted": False, "success": True, "wall_time": 0.1, "agents": []}
    out = write_log(path, world, states, summary=summary)
    if cut:
        data = Path(out).read_bytes()
        Path(out).write_bytes(data[: len(data) * 2 // 3])
    return out


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("export")
    return {
        "ok": make_log(d / "ok.mcap"),
        "no_origin": make_log(d / "no_origin.mcap", origin=False),
        "cut": make_log(d / "cut.mcap", cut=True),
        "empty": make_log(d / "empty.mcap", agents=0),
    }


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = cli_main(list(args))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_px4_plan_and_waypoints_read_back_with_pymavlink(logs, tmp_path, capsys):
    mavwp = pytest.importorskip("pymavlink.mavwp")
    out = tmp_path / "px4"
    code, text, err = run(capsys, logs["ok"], "--format", "px4", "--out", str(out))
    assert code == 0, err
    manifest = json.loads((out / "manifest.json").read_text())
    assert [a["id"] for a in manifest["agents"]] == ["cf1", "cf2"]
    for entry in manifest["agents"]:
        assert entry["max_deviation_m"] <= entry["bound_m"] == 0.1
        plan = json.loads((out / entry["file"]).read_text())
        assert plan["fileType"] == "Plan" and plan["mission"]["version"] == 2
        items = plan["mission"]["items"]
        assert items[0]["command"] == mission.MAV_CMD_NAV_TAKEOFF
        assert items[-1]["command"] == mission.MAV_CMD_NAV_WAYPOINT
        assert mission.MAV_CMD_DO_CHANGE_SPEED in [it["command"] for it in items]
        loader = mavwp.MAVWPLoader()
        n = loader.load(str(out / entry["waypoint_list"]))
        assert n == len(items) + 1  # the home position first
        cmds = [loader.wp(k).command for k in range(n)]
        assert cmds[1:] == [it["command"] for it in items]
        last = loader.wp(n - 1)
        back = mission.from_geodetic(np.array([[last.x, last.y, ORIGIN["alt"] + last.z]]), ORIGIN)[0]
        assert np.allclose(back[:2], [3.5, 0.5 + (entry["id"] == "cf2")], atol=1e-3)
        assert abs(last.z - 1.2) < 1e-6  # relative to the ground under the start


def test_crazyflie_export_and_check(logs, tmp_path, capsys):
    out = tmp_path / "cf"
    code, text, err = run(capsys, logs["ok"], "--format", "crazyflie", "--out", str(out), "--check")
    assert code == 0, text + err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["crazyflie"]["max_pieces"] == 31
    for entry in manifest["agents"]:
        assert entry["pieces"] <= 31 and entry["max_deviation_m"] <= entry["accuracy_m"] == 0.05
        assert entry["max_accel"] <= entry["accel_limit"] and entry["max_speed"] <= entry["speed_limit"]
        poly = crazyflie.read_csv((out / entry["file"]).read_text())
        assert poly.n_pieces == entry["pieces"]
    report = json.loads((out / "check.json").read_text())
    assert report["ok"] and report["contacts"] == [] and report["separation_entries"] == 0
    assert report["min_separation_m"] == pytest.approx(0.9, abs=0.01)
    assert all(a["max_deviation_m"] <= a["limit_m"] for a in report["agents"].values())


def test_csv_export_of_one_agent(logs, tmp_path, capsys):
    out = tmp_path / "csv"
    code, _, err = run(capsys, logs["ok"], "--format", "csv", "--agent", "cf2", "--out", str(out))
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["cf2.csv", "manifest.json"]
    rows = (out / "cf2.csv").read_text().splitlines()
    assert rows[0] == "t,x,y,z,vx,vy,vz" and len(rows) == 1 + 141


@pytest.mark.parametrize(
    ("case", "extra", "needle"),
    [
        ("empty", (), "has no agents"),
        ("ok", ("--agent", "nobody"), "--agent nobody: no such agent"),
        ("cut", (), "cut short"),
        ("no_origin", (), "no origin"),
        ("ok", ("--max-deviation", "-1"), "must be a number > 0"),
        ("ok", ("--origin", "95,8"), "latitude must be in [-90, 90]"),
    ],
)
def test_bad_input_is_one_line_exit_2_nothing_written(logs, tmp_path, capsys, case, extra, needle):
    out = tmp_path / "out"
    code, text, err = run(capsys, logs[case], "--format", "px4", "--out", str(out), *extra)
    assert code == 2
    assert needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_an_output_folder_that_cannot_be_written(logs, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = run(capsys, logs["ok"], "--format", "csv", "--out", str(blocker / "sub"))
    assert code == 2 and "is a file, not a directory" in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err and list(tmp_path.iterdir()) == [blocker]  # nothing half-written


def test_check_fails_when_the_swarm_meets(tmp_path, capsys):
    # Two agents on the same line a second apart in time: flown again, they meet.
    t = DT * np.arange(161)
    a, b = np.array([0.5, 1.0, 1.0]), np.array([3.5, 1.0, 1.0])
    p1 = a + min_jerk(t, 7.0)[:, None] * (b - a)
    p2 = b + min_jerk(t, 7.0)[:, None] * (a - b)
    ids = ["cf1", "cf2"]
    specs = [{"id": i, "start": p[0].tolist(), "goal": p[-1].tolist(), "radius": 0.05,
              "speed": {"min": 0.0, "max": 1.0, "cruise": 0.8}, "max_accel": 1.5,
              "separation": [0.5, 0.5, 0.5]} for i, p in zip(ids, (p1, p2), strict=True)]  # fmt: skip
    world = base_world(specs)
    world["sim"] = {"dt": DT, "max_time": 10.0, "goal_tolerance": 0.1}
    pos = np.stack([p1, p2])
    states = states_from_arrays(t, ids, pos, modes=[["apf"] * 161] * 2, goals=pos[:, -1])
    log = write_log(tmp_path / "meet.mcap", world, states, summary={"interrupted": False, "agents": []})
    code, text, _ = run(capsys, log, "--format", "crazyflie", "--out", str(tmp_path / "o"), "--check")
    assert code == 1 and "LIMIT BROKEN" in text
    report = json.loads((tmp_path / "o" / "check.json").read_text())
    assert report["min_separation_m"] < 0 and report["separation_entries"] > 0
    # the flight itself met: its closeness is no excuse for a contact
    assert any(c.startswith("cf1-cf2 at t = ") for c in report["contacts"])


def test_separation_is_held_to_the_flight_own_closeness_less_the_bounds():
    from swarmplan.export.check import Plan, separation_kept

    # radius 0.05, separation 0.5 m: the pair's ellipsoid has semi-axes 0.6 m; bounds 0.05 m each
    plans = [Plan(f"cf{k}", "multirotor", 0.05, (0.5, 0.5, 0.5), np.zeros(1), np.zeros((1, 3)), 0.05)
             for k in range(2)]  # fmt: skip

    def pair(gap: float) -> np.ndarray:
        return np.array([[[0.0, 0.0, 1.0]], [[gap, 0.0, 1.0]]])

    # the flight kept it (0.7 m: 1.167): flown again it must stay outside
    _, own, allowed = separation_kept(plans, pair(0.59), pair(0.7))
    assert own[0] == pytest.approx(0.7 / 0.6) and allowed[0] == 1.0
    # the flight came inside (0.48 m: 0.8): as deep as that, less (0.05 + 0.05) / 0.6
    depth, own, allowed = separation_kept(plans, pair(0.381), pair(0.48))
    assert own[0] == pytest.approx(0.8) and allowed[0] == pytest.approx(0.8 - 0.1 / 0.6)
    assert depth[0, 0] >= allowed[0]
    depth, _, allowed = separation_kept(plans, pair(0.379), pair(0.48))
    assert depth[0, 0] < allowed[0]


def test_check_passes_the_flight_own_near_miss_and_fails_an_export_closer_than_it(tmp_path):
    import dataclasses

    from swarmplan.export.check import check
    from swarmplan.export.files import build
    from swarmplan.replay import load
    from swarmplan.world.tracker_config import parse_tracker

    # Two agents side by side 0.45 m apart: inside their 0.6 m separation ellipsoid all along.
    rec = load(make_log(tmp_path / "near.mcap", spacing=0.45))
    cfg, _ = parse_tracker(rec.world.get("tracker"), "tracker")
    plans = build(rec, "csv").plans
    result = check(rec, plans, cfg)
    assert result.separation_entries > 0 and result.separation_lost == 0 and result.ok
    (tight,) = result.tight_pairs
    assert tight.pair == "cf1-cf2" and tight.flown == pytest.approx(0.75, abs=1e-3) and tight.ok
    # An export of cf2 0.25 m closer to cf1 than its flight: deeper than the bounds (0.1 m each) allow.
    closer = dataclasses.replace(plans[1], pos=plans[1].pos - [0.0, 0.25, 0.0])
    result = check(rec, [plans[0], closer], cfg)
    assert result.separation_lost > 0 and not result.ok and not result.tight_pairs[0].ok
    assert all(a.ok for a in result.agents)  # each vehicle follows its own export


@pytest.mark.skipif(not (ROOT / "worlds" / "crazyflie_room.yaml").exists(), reason="needs the shipped world")
def test_the_room_of_crazyflies_exports_and_checks(tmp_path, capsys):
    """The shipped room flown and exported with ``--check`` (in this process); the command's real
    entry point, ``python -m swarmplan.export``, in a process of its own on a log that is not
    there: one line naming it, exit 2, nothing written."""
    from swarmplan.cli.run import main as run_main

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    log = tmp_path / "room.mcap"
    world = str(ROOT / "worlds" / "crazyflie_room.yaml")
    code = run_main([world, "--out", str(log), "--quiet"])
    assert code == 0, capsys.readouterr()
    out = str(tmp_path / "cf")
    assert cli_main([str(log), "--format", "crazyflie", "--out", out, "--check"]) == 0, capsys.readouterr()
    missing, never = tmp_path / "none.mcap", tmp_path / "no"
    exp = subprocess.run(
        [sys.executable, "-m", "swarmplan.export", str(missing), "--format", "csv", "--out", str(never)],
        capture_output=True, text=True, env=env, timeout=600,
    )  # fmt: skip
    assert exp.returncode == 2 and exp.stderr.strip().splitlines() == [f"export: {missing}: no such file"]
    assert not never.exists()
    manifest = json.loads((tmp_path / "cf" / "manifest.json").read_text())
    for entry in manifest["agents"]:
        assert entry["max_deviation_m"] <= 0.05 and entry["pieces"] <= 31
        assert entry["joint_jumps"]["accel_m_s2"] < 1e-3
    assert json.loads((tmp_path / "cf" / "check.json").read_text())["contacts"] == []
    assert math.isfinite(manifest["agents"][0]["duration"])


SHIPPED_WORLDS = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "worlds").rglob("*.yaml"))


@pytest.mark.slow
@pytest.mark.parametrize("path", SHIPPED_WORLDS)
def test_shipped_multirotor_worlds_export_missions_within_their_bound(path, tmp_path, capsys):
    """Every shipped multirotor world, flown with its own seed, exports a PX4 mission per agent
    within its deviation bound that pymavlink loads, and ``--check`` flies the missions with no
    contact and separation kept."""
    from swarmplan.io.runner import simulate

    mavwp = pytest.importorskip("pymavlink.mavwp")
    world = load_world(ROOT / path)
    if any(a.model != "multirotor" for a in world.agents):
        pytest.skip("fixed wings: test_fixed_wing_manoeuvres flies their missions")
    log = tmp_path / "run.mcap"
    simulate(world, world.seed, log)
    out = tmp_path / "px4"
    code = cli_main([str(log), "--format", "px4", "--out", str(out), "--check", "--origin", "47.4,8.5"])
    text = capsys.readouterr().out
    assert code == 0 and "check: OK" in text, text
    for entry in json.loads((out / "manifest.json").read_text())["agents"]:
        assert entry["max_deviation_m"] <= entry["bound_m"]
        assert mavwp.MAVWPLoader().load(str(out / entry["waypoint_list"])) == entry["items"] + 1
