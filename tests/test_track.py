"""Quadrotor tracking of recorded runs (swarmplan.track): model physics, controller, reference
feasibility reporting, the tracker: config section, and the command line."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world, states_from_arrays, write_log  # noqa: E402
from helpers import audit  # noqa: E402

from swarmplan.cli.track import main as cli_main  # noqa: E402
from swarmplan.replay import load  # noqa: E402
from swarmplan.track import PID, TrackerConfig, parse_tracker, track  # noqa: E402
from swarmplan.track.quadrotor import _deriv, simulate  # noqa: E402
from swarmplan.track.reference import Reference, build_reference, feasibility, fill_gaps  # noqa: E402
from swarmplan.world.tracker_config import G  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DT = 0.1


def smooth_step(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """Minimum-jerk 0 -> 1 between t0 and t1."""
    s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def make_log(
    path: Path,
    positions: np.ndarray,
    ids: list[str] | None = None,
    models: list[str] | None = None,
    arrive: bool = True,
    **world_extra,
) -> str:
    """A contract log of agents flying ``positions`` (A, T, 3) sampled every DT."""
    n_a, n_t, _ = positions.shape
    ids = ids or [f"u{i}" for i in range(n_a)]
    models = models or ["multirotor"] * n_a
    times = DT * np.arange(n_t)
    goals = positions[:, -1]
    agents = [
        {"id": ids[i], "start": positions[i, 0].tolist(), "goal": goals[i].tolist(), "model": models[i]}
        for i in range(n_a)
    ]
    modes = [["apf"] * (n_t - 1) + ["arrived" if arrive else "apf"] for _ in range(n_a)]
    world = base_world(agents, **world_extra)
    world["bounds"] = {"min": [-500, -500, 0], "max": [500, 500, 200]}
    states = states_from_arrays(times, ids, positions, modes=modes, goals=goals)
    summary = {"interrupted": False, "success": True, "wall_time": 0.1, "agents": []}
    return write_log(path, world, states, summary=summary)


def line_positions(n_t: int, start, end, t0: float, t1: float) -> np.ndarray:
    t = DT * np.arange(n_t)
    s = smooth_step(t, t0, t1)[:, None]
    return np.asarray(start, float) + s * (np.asarray(end, float) - np.asarray(start, float))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """``python -m swarmplan.track`` in a subprocess (the real entry point)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, "-m", "swarmplan.track", *args], capture_output=True, text=True, env=env, timeout=300
    )


def run_main(capsys, *args: str) -> subprocess.CompletedProcess:
    """The CLI in-process (an uncaught exception fails the test, like a traceback would)."""
    capsys.readouterr()
    code = cli_main(list(args))
    cap = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, cap.out, cap.err)


# ------------------------------------------------------------------------- model physics


def test_hover_is_an_equilibrium_of_the_model():
    cfg = TrackerConfig()
    x = np.zeros((1, 13))
    x[0, 12] = cfg.mass * G
    dx = _deriv(x, np.array([cfg.mass * G]), np.zeros((1, 3)), cfg, np.asarray(cfg.inertia))
    np.testing.assert_allclose(dx, 0.0, atol=1e-12)


def test_tilted_flight_at_drag_terminal_speed_is_steady():
    # Pitch theta with thrust m g / cos(theta): horizontal force m g tan(theta) = drag v^2.
    cfg = TrackerConfig()
    theta = np.radians(30.0)
    v = np.sqrt(cfg.mass * G * np.tan(theta) / cfg.drag)
    thrust = cfg.mass * G / np.cos(theta)
    x = np.zeros((1, 13))
    x[0, 3] = v
    x[0, 7] = theta
    x[0, 12] = thrust
    dx = _deriv(x, np.array([thrust]), np.zeros((1, 3)), cfg, np.asarray(cfg.inertia))
    np.testing.assert_allclose(dx[0, 3:], 0.0, atol=1e-9)
    np.testing.assert_allclose(dx[0, :3], [v, 0, 0], atol=1e-12)


def test_constant_torque_spins_up_at_torque_over_inertia():
    cfg = TrackerConfig()
    x = np.zeros((1, 13))
    x[0, 12] = cfg.mass * G
    tau = np.array([[0.01, 0.0, 0.0]])
    dx = _deriv(x, np.array([cfg.mass * G]), tau, cfg, np.asarray(cfg.inertia))
    assert dx[0, 9] == pytest.approx(0.01 / cfg.inertia[0])


# ------------------------------------------------------------------------- controller


def _ref(positions: np.ndarray, dt: float = 0.005) -> Reference:
    times = DT * np.arange(positions.shape[1])
    vel = np.zeros((positions.shape[0], 2, 3))
    return build_reference(times, positions, vel, dt)


def test_hover_reference_is_held_exactly():
    pos = np.tile([3.0, -2.0, 10.0], (1, 50, 1))
    fl = simulate(_ref(pos), TrackerConfig())
    assert np.abs(fl.pos - pos[:, :1]).max() < 1e-9
    assert fl.tilt_deg.max() < 1e-6
    assert fl.thrust.max() == pytest.approx(TrackerConfig().mass * G)


def test_smooth_feasible_reference_is_tracked_closely():
    # 60 m in 10 s minimum-jerk (peak speed 11 m/s, peak acceleration 3.5 m/s^2): well inside limits.
    pos = line_positions(160, [0, 0, 10], [60, 20, 15], 2.0, 12.0)[None]
    ref = _ref(pos)
    cfg = TrackerConfig()
    assert not feasibility(ref, cfg).any()
    fl = simulate(ref, cfg)
    err = np.linalg.norm(fl.pos - ref.pos, axis=2)
    assert err.max() < 0.2
    assert fl.tilt_deg.max() < 30.0


def test_agents_are_independent_in_the_vectorized_simulation():
    a = line_positions(100, [0, 0, 10], [30, 0, 10], 1.0, 6.0)
    b = line_positions(100, [5, 5, 20], [5, -25, 30], 2.0, 8.0)
    cfg = TrackerConfig()
    both = simulate(_ref(np.stack([a, b])), cfg)
    alone = simulate(_ref(b[None]), cfg)
    np.testing.assert_allclose(both.pos[1], alone.pos[0], atol=1e-9)


def test_rk4_step_halved_changes_the_flight_by_millimetres():
    pos = line_positions(100, [0, 0, 10], [40, 10, 10], 1.0, 6.0)[None]
    coarse = simulate(_ref(pos, 0.005), TrackerConfig(dt=0.005))
    fine = simulate(_ref(pos, 0.0025), TrackerConfig(dt=0.0025))
    assert np.abs(fine.pos[:, ::2] - coarse.pos).max() < 5e-3


def test_thrust_never_exceeds_the_thrust_to_weight_limit():
    # A 20 m climb in 1 s asks for ~ 12 g; the motors give 2 g.
    pos = line_positions(60, [0, 0, 10], [0, 0, 30], 1.0, 2.0)[None]
    cfg = TrackerConfig()
    ref = _ref(pos)
    assert feasibility(ref, cfg).any()
    fl = simulate(ref, cfg)
    assert fl.thrust.max() <= cfg.max_thrust * (1 + 1e-9)
    assert fl.thrust.max() > 0.99 * cfg.max_thrust
    assert fl.saturated.any()


# ------------------------------------------------------------------------- reference honesty


def test_teleport_in_the_log_is_reported_not_hidden(tmp_path, capsys):
    # Hover, then a 20 m jump in one recorded step: no vehicle can do that.
    pos = np.tile([0.0, 0.0, 20.0], (1, 80, 1))
    pos[0, 40:, 0] = 20.0
    log = make_log(tmp_path / "teleport.mcap", pos)
    res = track(load(log), TrackerConfig())
    m = res.agents["u0"]
    assert not m.reference_feasible
    assert m.infeasible_s > 0
    # The jump is between t = 3.9 and 4.0; the spline through it rings a few samples before.
    assert len(m.infeasible_at) == 1 and 3.0 <= m.infeasible_at[0] <= 4.0
    assert m.max_reference_accel > 100.0
    assert m.max_error_m > 5.0  # the vehicle lags the jump: large error, shown
    assert 3.9 <= m.time_of_max_error_s <= 5.0
    out = json.loads(run_main(capsys, log, "--json").stdout)
    assert out["agents"]["u0"]["reference_feasible"] is False
    assert out["agents"]["u0"]["max_error_m"] > 5.0
    text = run_main(capsys, log).stdout
    assert "WARNING u0: reference infeasible" in text


def test_feasible_log_is_reported_feasible(tmp_path):
    pos = line_positions(150, [0, 0, 10], [50, 30, 20], 1.0, 11.0)[None]
    res = track(load(make_log(tmp_path / "ok.mcap", pos)), TrackerConfig())
    m = res.agents["u0"]
    assert m.reference_feasible and m.infeasible_at == ()
    assert m.max_error_m < 0.2
    assert m.max_error_away_from_infeasible_m == pytest.approx(m.max_error_m)


def test_a_log_cut_in_flight_brakes_at_the_agents_max_accel_after_its_end(tmp_path):
    # A timed-out run ends with the agent still flying (mode apf): the log never asked it to
    # stop there, so the reference goes on and brakes at its max_accel (5 m/s^2) instead.
    t = DT * np.arange(60)
    speed = 8.0 * smooth_step(t, 0.5, 4.5)
    pos = np.zeros((1, 60, 3))
    pos[0, 1:, 0] = np.cumsum(speed[1:] * DT)
    pos[0, :, 2] = 10.0
    rec = load(make_log(tmp_path / "timeout.mcap", pos, arrive=False))
    res = track(rec, TrackerConfig())
    m = res.agents["u0"]
    assert m.reference_feasible and m.max_error_m < 0.5
    assert res.ref.times[-1] == pytest.approx(t[-1] + 8.0 / 5.0 + 2.0, abs=DT)
    end = res.ref.pos[0, -1, 0]
    assert end == pytest.approx(pos[0, -1, 0] + 8.0**2 / (2 * 5.0), abs=0.5)  # its braking distance
    assert np.abs(np.diff(res.ref.vel[0, :, 0])).max() / TrackerConfig().dt <= 5.0 + 1e-6


def test_stop_at_the_end_of_the_log_is_flown_out_in_the_settle_hover(tmp_path):
    # The log ends while the agent still flies at 8 m/s: the settle hover shows its stop.
    t = DT * np.arange(60)
    speed = 8.0 * smooth_step(t, 0.5, 4.5)
    pos = np.zeros((1, 60, 3))
    pos[0, 1:, 0] = np.cumsum(speed[1:] * DT)
    pos[0, :, 2] = 10.0
    rec = load(make_log(tmp_path / "cut.mcap", pos))
    with_hold = track(rec, TrackerConfig())
    without = track(rec, TrackerConfig(settle_time=0.0))
    assert with_hold.ref.times[-1] == pytest.approx(t[-1] + 2.0)
    assert without.ref.times[-1] == pytest.approx(t[-1])
    assert without.agents["u0"].reference_feasible
    assert not with_hold.agents["u0"].reference_feasible  # 8 m/s to 0 within a step
    assert with_hold.agents["u0"].infeasible_at[0] > 5.0
    assert with_hold.agents["u0"].max_error_m > without.agents["u0"].max_error_m


def point_mass(accels: np.ndarray) -> np.ndarray:
    """Positions (T, 3) of the simulator's multirotor: v += a dt, then p += v dt (semi-implicit)."""
    v = np.cumsum(accels * DT, axis=0)
    v[0] = 0.0
    p = np.cumsum(v * DT, axis=0) + np.array([0.0, 0.0, 10.0])
    return p


def test_velocity_reference_reproduces_the_recorded_kinematics():
    rng = np.random.default_rng(4)
    acc = rng.uniform(-4.0, 4.0, size=(80, 3))  # within the point mass's max_accel of 4 (per axis)
    acc[0] = 0.0
    p = point_mass(acc)
    times = DT * np.arange(len(p))
    u = np.diff(p, axis=0) / DT  # the recorded velocities (each step's displacement over h)
    ends = np.stack([np.zeros(3), u[-1]])[None]  # at rest at t = 0, last step's velocity at the end
    ref = build_reference(times, p[None], ends, 0.005, "velocity")
    at = np.round(times / 0.005).astype(int)
    dv = np.abs(np.diff(u, axis=0)).max()
    # through every inner recorded position within |dv| h / 8, every mid-step point exactly
    assert np.abs(ref.pos[0, at[1:-1]] - p[1:-1]).max() <= dv * DT / 8 + 1e-9
    assert np.abs(ref.pos[0, 0] - p[0]).max() <= np.abs(u[0]).max() * DT / 4 + 1e-9  # from rest
    np.testing.assert_allclose(ref.pos[0, at[-1]], p[-1], atol=1e-9)
    mid = at[:-1] + 10
    np.testing.assert_allclose(ref.pos[0, mid], 0.5 * (p[:-1] + p[1:]), atol=1e-9)
    # its acceleration is the recorded one: each step's velocity change over h (after the first)
    inner = ref.acc[0, at[2] + 1 : at[-1] - 11]
    assert np.abs(inner).max() <= 4.0 + 1e-9


def test_chatter_is_feasible_for_the_velocity_reference_but_not_for_the_cubic_spline():
    # The APF sometimes alternates +-a every step. The point mass does that within its limit;
    # an interpolating cubic spline triples it (3 a / h^2 second differences) at the knots.
    acc = np.zeros((60, 3))
    acc[10:50, 0] = 5.0 * (-1.0) ** np.arange(40)
    p = point_mass(acc)
    times = DT * np.arange(len(p))
    cfg = TrackerConfig(max_tilt_deg=40.0)  # g tan 40 = 8.2 m/s^2: above 5, below 3 x 5
    vel = np.zeros((1, 2, 3))
    assert not feasibility(build_reference(times, p[None], vel, 0.005, "velocity"), cfg).any()
    assert feasibility(build_reference(times, p[None], vel, 0.005, "cubic"), cfg).any()


def test_fill_gaps_holds_the_nearest_sample():
    times = np.arange(5) * 0.1
    p = np.full((1, 5, 3), np.nan)
    p[0, 1] = [1, 1, 1]
    p[0, 3] = [3, 3, 3]
    out = fill_gaps(times, p)
    np.testing.assert_array_equal(out[0, :, 0], [1, 1, 1, 3, 3])


# ------------------------------------------------------------------------- tracker: config


def test_parse_tracker_defaults_and_round_trip():
    cfg, problems = parse_tracker(None)
    assert problems == [] and cfg == TrackerConfig()
    custom = dataclasses.replace(TrackerConfig(), mass=2.0, position=PID(3.0, 0.1, 2.0))
    again, problems = parse_tracker(custom.to_dict())
    assert problems == [] and again == custom


def test_parse_tracker_reads_every_key():
    raw = {
        "mass": 2.5,
        "inertia": [0.05, 0.05, 0.09],
        "thrust_to_weight": 2.5,
        "drag": 0.1,
        "drag_feedforward": False,
        "motor_time_constant": 0.04,
        "max_tilt_deg": 40,
        "max_rate_deg_s": 180,
        "dt": 0.004,
        "settle_time": 1.0,
        "reference": "cubic",
        "position": {"kp": 3, "ki": 0.2, "kd": 2.5},
        "attitude": {"kp": 9},
        "rate": {"kp": 30, "kd": 0.1},
    }
    cfg, problems = parse_tracker(raw)
    assert problems == []
    assert cfg.mass == 2.5 and cfg.inertia == (0.05, 0.05, 0.09) and cfg.drag_feedforward is False
    assert cfg.position == PID(3.0, 0.2, 2.5) and cfg.attitude == PID(9.0) and cfg.rate == PID(30.0, 0.0, 0.1)
    assert cfg.max_thrust == pytest.approx(2.5 * 2.5 * G)


@pytest.mark.parametrize(
    ("raw", "problem"),
    [
        ({"mass": -1}, "tracker.mass: must be > 0, got -1"),
        ({"mass": "heavy"}, "tracker.mass: expected a number, got string 'heavy'"),
        ({"thrust_to_weight": 0.9}, "tracker.thrust_to_weight: must be > 1, got 0.9"),
        ({"drag": -0.1}, "tracker.drag: must be >= 0, got -0.1"),
        ({"max_tilt_deg": 95}, "tracker.max_tilt_deg: must be < 90, got 95"),
        ({"dt": 0.2}, "tracker.dt: must be <= 0.05 s for the attitude loops, got 0.2"),
        ({"inertia": [1, 2]}, "tracker.inertia: expected a list of 3 numbers, got [1, 2]"),
        ({"inertia": [1, 0, 1]}, "tracker.inertia: every value must be > 0, got [1, 0, 1]"),
        ({"drag_feedforward": "yes"}, "tracker.drag_feedforward: expected true or false, got 'yes'"),
        ({"mas": 1.0}, "tracker.mas: unknown key (did you mean 'mass'?)"),
        (
            {"reference": "cubik"},
            "tracker.reference: 'cubik' is not one of velocity, cubic (did you mean 'cubic'?)",
        ),
        ({"position": {"kq": 1}}, "tracker.position.kq: unknown key (did you mean 'kp'?)"),
        ({"position": {"kp": 0}}, "tracker.position.kp: must be > 0, got 0"),
        ({"rate": {"ki": -1}}, "tracker.rate.ki: must be >= 0, got -1"),
        ({"attitude": 5}, "tracker.attitude: expected a mapping with kp, ki, kd, got int"),
        ([1, 2], "tracker: expected a mapping, got list"),
    ],
)
def test_parse_tracker_names_each_problem(raw, problem):
    cfg, problems = parse_tracker(raw)
    assert problems == [problem]
    assert isinstance(cfg, TrackerConfig)


def test_parse_tracker_collects_every_problem_under_the_given_path():
    _, problems = parse_tracker({"mass": 0, "drag": -1, "zzz": 1}, "world.tracker")
    assert problems == [
        "world.tracker.zzz: unknown key (known keys: mass, thrust_to_weight, drag, motor_time_constant, "
        "max_tilt_deg, max_rate_deg_s, dt, settle_time, inertia, drag_feedforward, reference, position, "
        "attitude, rate)",
        "world.tracker.mass: must be > 0, got 0",
        "world.tracker.drag: must be >= 0, got -1",
    ]


# ------------------------------------------------------------------------- command line


@pytest.fixture(scope="module")
def two_agent_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("track")
    a = line_positions(120, [0, 0, 10], [40, 20, 15], 1.0, 9.0)
    # A fixed wing at a constant 5 m/s (it never hovers).
    b = np.array([0.0, 40.0, 20.0]) + DT * np.arange(120)[:, None] * np.array([5.0, 0.0, 0.0])
    return make_log(
        d / "two.mcap", np.stack([a, b]), ids=["quad", "plane"], models=["multirotor", "fixed_wing"]
    )


def test_cli_json_reports_every_agent_with_its_own_vehicle_model(two_agent_log, capsys):
    r = run_main(capsys, two_agent_log, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert list(out) == ["agents"]
    quad, plane = out["agents"]["quad"], out["agents"]["plane"]
    assert quad["skipped"] is None
    assert 0 < quad["max_error_m"] < 0.2 and 0 < quad["rms_error_m"] <= quad["max_error_m"]
    assert 0 < quad["max_tilt_deg"] < 30 and quad["max_thrust_n"] > 0
    assert quad["model"] == "multirotor" and plane["model"] == "fixed_wing"
    assert plane["skipped"] is None and 0 <= plane["max_error_m"] < 0.05
    assert plane["max_bank_deg"] < 1.0 and plane["within_error_limit"]


def test_cli_table_and_single_agent(two_agent_log, capsys):
    r = run_main(capsys, two_agent_log, "--agent", "quad")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].split()[:3] == ["agent", "max", "err"]
    assert lines[1].startswith("quad ")
    assert not any(line.startswith("plane") for line in lines)


def test_cli_out_is_a_contract_log_with_the_tracking_channel(two_agent_log, tmp_path, capsys):
    out = tmp_path / "tracked.mcap"
    png = tmp_path / "tracked.png"
    r = run_main(capsys, two_agent_log, "--out", str(out), "--plot", str(png))
    assert r.returncode == 0, r.stderr
    assert png.stat().st_size > 10_000
    # replay's audit always, the shared checker too where it is beside the checkout
    problems, _notes, stats = audit(out, allow_failure=True)
    assert problems == [] and stats["agents"] == 2
    rec = load(out)
    src = load(two_agent_log)
    assert rec.n_steps == src.n_steps
    # The fixed wing as flown by the aircraft model (a straight line: on it within centimetres).
    assert np.abs(rec.positions[1] - src.positions[1]).max() < 0.05
    assert 0 < np.abs(rec.positions[0] - src.positions[0]).max() < 0.2  # the quadrotor as flown
    assert rec.world["tracker"] == TrackerConfig().to_dict()

    from mcap.reader import make_reader

    with open(out, "rb") as f:
        msgs = [json.loads(m.data) for _s, _c, m in make_reader(f).iter_messages(topics=["/tracking"])]
    assert len(msgs) == src.n_steps
    last = msgs[-1]["agents"]
    assert [a["id"] for a in last] == ["quad"]
    ref, trk = np.asarray(last[0]["reference"]), np.asarray(last[0]["tracked"])
    np.testing.assert_allclose(ref, src.positions[0, -1], atol=1e-9)  # the spline passes the samples
    assert np.linalg.norm(trk - ref) == pytest.approx(last[0]["error_m"])
    np.testing.assert_allclose(trk, rec.positions[0, -1])


def test_cli_reads_the_tracker_section_of_the_world(tmp_path, capsys):
    pos = line_positions(120, [0, 0, 10], [60, 0, 10], 1.0, 7.0)[None]
    default = track(load(make_log(tmp_path / "a.mcap", pos)), TrackerConfig())
    log = make_log(tmp_path / "b.mcap", pos, tracker={"max_tilt_deg": 5.0})
    out = json.loads(run_main(capsys, log, "--json").stdout)["agents"]["u0"]
    assert out["max_tilt_deg"] < 5.5 < default.agents["u0"].max_tilt_deg
    assert out["reference_feasible"] is False  # 5 degrees cannot give the line's acceleration


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.mcap"], "track: missing.mcap: no such file"),
        (["{log}", "--agent", "nobody"], "track: --agent nobody: no such agent (agents: quad, plane)"),
        (["{log}", "--out", "{log}/dir/x.mcap"], "is a file, not a directory"),
        (["{log}", "--out", "{tmp}/x.txt"], "expected a .mcap file"),
        (["{log}", "--out", "{log}"], "would overwrite the input log"),
        (["{log}", "--plot", "{tmp}/x.bmpx"], "unsupported extension '.bmpx'"),
        (["{log}", "--plot", "{tmp}/noext"], "no extension"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(two_agent_log, tmp_path, capsys, args, message):
    args = [a.format(log=two_agent_log, tmp=tmp_path) for a in args]
    r = run_main(capsys, *args)
    assert r.returncode == 2
    assert r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1 and message in r.stderr
    assert "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_cli_bad_tracker_section_exits_2(tmp_path, capsys):
    pos = np.tile([0.0, 0.0, 10.0], (1, 20, 1))
    log = make_log(tmp_path / "bad.mcap", pos, tracker={"mass": -2, "dragg": 1})
    r = run_main(capsys, log, "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip() == (
        "track: /world tracker.dragg: unknown key (did you mean 'drag'?) (and 1 more)"
    )


def test_cli_not_a_log_exits_2(tmp_path, capsys):
    p = tmp_path / "junk.mcap"
    p.write_bytes(b"not an mcap file at all")
    r = run_main(capsys, str(p))
    assert r.returncode == 2 and "not an MCAP file" in r.stderr and "Traceback" not in r.stderr


def test_python_dash_m_missing_file_exits_2_without_traceback():
    r = run_cli("no/such/run.mcap", "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip() == "track: no/such/run.mcap: no such file"


# ------------------------------------------------------------------------- simulator logs


def _simulated_log(tmp_path: Path, **top) -> str:
    """A short run of a small world (two multirotors crossing around a sphere), logged."""
    from helpers import base_world as sim_world
    from helpers import make_world, run_to_end

    raw = sim_world(
        obstacles=[{"id": "s", "shape": "sphere", "radius": 6, "position": [50, 52, 20]}],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "b", "start": [50, 10, 20], "goal": [50, 90, 25]},
        ],
        **top,
    )
    log = tmp_path / "run.mcap"
    _, summary, _ = run_to_end(make_world(raw), seed=0, log_path=log)
    assert summary["success"] and all(a["hard_stops"] == 0 for a in summary["agents"])
    return str(log)


@pytest.fixture(scope="module")
def tilt_limited_log(tmp_path_factory) -> str:
    """The small world's run with a tracker section (``max_tilt_deg`` 12): the section changes
    only what the tracker reads from the world, never the flight."""
    return _simulated_log(tmp_path_factory.mktemp("simulated"), tracker={"max_tilt_deg": 12.0})


def test_a_simulated_run_is_tracked_within_1_2_m(tilt_limited_log):
    # Arrival and braking within max_accel (swarmplan.sim) leave nothing infeasible to fly; the
    # tracker's defaults are passed explicitly, so the world's tracker section plays no part.
    result = track(load(tilt_limited_log), TrackerConfig())
    assert sorted(result.agents) == ["a", "b"]
    for m in result.agents.values():
        assert m.reference_feasible
        assert 0 < m.max_error_m <= 1.2


def test_the_world_files_tracker_section_reaches_the_tracker(tilt_limited_log, capsys):
    log = tilt_limited_log
    assert load(log).world["tracker"]["max_tilt_deg"] == 12.0
    out = json.loads(run_main(capsys, log, "--json").stdout)["agents"]
    default = track(load(log), TrackerConfig())
    for aid, m in out.items():
        assert m["max_tilt_deg"] <= 12.5 < default.agents[aid].max_tilt_deg


def test_cli_tracks_a_fixed_wing_alone(two_agent_log, capsys):
    r = run_main(capsys, two_agent_log, "--agent", "plane", "--json")
    assert r.returncode == 0, r.stderr
    plane = json.loads(r.stdout)["agents"]["plane"]
    assert plane["model"] == "fixed_wing" and plane["within_error_limit"]
