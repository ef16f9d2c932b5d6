"""Dense swarms on the field's standard scenarios (swarmplan.bench.swarm_scenarios): every agent
home with no contact, with the default planner and with pure APF; the scenario generator's
geometry; the contact meter of ``bench swarm`` on exact cases; its command line's errors."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import fly_metered

from swarmplan.bench import swarm_scenarios as S
from swarmplan.bench.swarm_runs import ContactMeter
from swarmplan.sim import Simulation


def fly(name: str, agents: int, planner: str, seed: int = 0) -> tuple[Simulation, ContactMeter]:
    """Fly a scenario to its end; contacts measured from positions, swept between steps."""
    world = S.scenario_world(name, agents, seed)
    sim = Simulation(world, planner=planner)
    return sim, fly_metered(sim, seed)


def _assert_home(name: str, agents: int, planner: str) -> None:
    sim, meter = fly(name, agents, planner)
    s = sim.summary()
    assert s["arrived"] == agents, f"{name} {agents} {planner}: {s['arrived']}/{agents} at t={sim.state.t}"
    assert s["collisions"] == 0 and not meter.pairs, meter.pairs
    assert meter.min_gap > 0.0
    assert sim.state.t < sim.world.max_time  # within 3x the straight flight + 30 s


@pytest.mark.parametrize("planner", ["world", "none"])
@pytest.mark.parametrize("agents", [16, 64])
@pytest.mark.parametrize("name", ["sphere", "circle"])
def test_every_agent_home_without_contact(name, agents, planner):
    _assert_home(name, agents, planner)


@pytest.mark.slow
@pytest.mark.parametrize("planner", ["world", "none"])
@pytest.mark.parametrize("agents", [256, 512])
@pytest.mark.parametrize("name", ["sphere", "circle"])
def test_every_agent_home_without_contact_at_scale(name, agents, planner):
    _assert_home(name, agents, planner)


def test_sphere_is_antipodal_on_its_radius():
    raw = S.sphere(64, seed=3)
    start = np.array([a["start"] for a in raw["agents"]])
    goal = np.array([a["goal"] for a in raw["agents"]])
    centre = (start + goal) / 2.0
    np.testing.assert_allclose(centre, np.broadcast_to(centre[0], centre.shape), atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(start - centre, axis=1), 2.2 * 8.0, atol=1e-5)
    # Evenly spread: no two starts closer than 4 m at 64 agents (17.6 m sphere).
    d = np.linalg.norm(start[:, None] - start[None], axis=-1) + np.eye(64) * 1e9
    assert d.min() > 4.0
    # The horizon: 3x the straight flight at cruise (5 m/s) plus 30 s.
    assert raw["sim"]["max_time"] == pytest.approx(3 * 2 * 17.6 / 5.0 + 30.0, abs=0.1)


def test_scenarios_are_seeded_and_valid():
    for name, make in S.SCENARIOS.items():
        assert make(16, 1) == make(16, 1)
        assert make(16, 1) != make(16, 2)
        world = S.scenario_world(name, 16, 1)  # parses: starts and goals clear of everything
        assert len(world.agents) == 16
        a = world.agents[0]
        assert (a.radius, a.speed_max, a.speed_cruise, world.dt, world.goal_tolerance) == (
            0.5,
            6.0,
            5.0,
            0.1,
            2.0,
        )


@pytest.mark.parametrize(
    "agents", [16, 64, pytest.param(256, marks=pytest.mark.slow), pytest.param(512, marks=pytest.mark.slow)]
)
def test_every_scenario_parses_for_several_seeds(agents):
    """Starts and goals clear of every obstacle at every size (the pillars inside the sphere
    once touched agents on it at 16 agents, seed 2)."""
    for name in S.SCENARIOS:
        if agents > S.MAX_AGENTS.get(name, agents):
            continue
        for seed in range(3 if agents > 64 else 5):
            S.scenario_world(name, agents, seed)


def test_circle_is_planar_and_doorway_has_one_gap():
    raw = S.circle(32, 0)
    z = {a["start"][2] for a in raw["agents"]} | {a["goal"][2] for a in raw["agents"]}
    assert len(z) == 1
    door = S.doorway(16, 0)
    walls = sorted(door["obstacles"], key=lambda o: o["position"][1])
    top_of_south = walls[0]["position"][1] + walls[0]["size"][1] / 2
    bottom_of_north = walls[1]["position"][1] - walls[1]["size"][1] / 2
    assert bottom_of_north - top_of_south == pytest.approx(S.DOOR_WIDTH)
    assert all(o["size"][2] >= door["bounds"]["max"][2] for o in walls)  # as high as the bounds


def test_contact_meter_sees_a_crossing_between_samples():
    meter = ContactMeter(np.array([0.5, 0.5]))
    # Head-on, they swap places within one step: both samples 4 m apart, the sweep meets.
    meter.update(np.array([[0.0, 0, 0], [2.0, 0, 0]]), np.array([[2.0, 0, 0], [0.0, 0, 0]]))
    assert meter.pairs == {(0, 1)}
    assert meter.min_gap == pytest.approx(-1.0)
    # Parallel 1.2 m apart: no contact, gap 0.2 m.
    meter = ContactMeter(np.array([0.5, 0.5]))
    meter.update(np.array([[0.0, 0, 0], [0.0, 1.2, 0]]), np.array([[1.0, 0, 0], [1.0, 1.2, 0]]))
    assert not meter.pairs and meter.min_gap == pytest.approx(0.2)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--sizes", "16,x"], "--sizes"),
        (["--sizes", "1"], "--sizes"),
        (["--seeds", "0"], "--seeds"),
        (["--peers", "rvo"], "--peers"),
        (["--scenarios", "spheres"], "--scenarios"),
    ],
)
def test_bench_swarm_rejects_bad_arguments(argv, message, tmp_path, capsys):
    """In the test's process (``python -m swarmplan.bench``'s own refusals, exit code and no
    traceback, run in a process of their own in test_bench_outputs.py)."""
    from swarmplan.cli.bench import main as bench_main

    try:
        code = bench_main(["swarm", *argv, "--out", str(tmp_path)])
    except SystemExit as stop:  # argparse's own refusals
        code = stop.code
    err = capsys.readouterr().err
    assert code == 2 and not any(tmp_path.iterdir())
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0]


def test_lab_scenarios_are_the_literatures():
    """RMADER's circle: antipodal on a 10 m circle at the asked altitude, its drone and step;
    the Crazyswarm room: a grid swapped through its centre, the downwash ellipsoid as the
    separation (semi-axes minus both radii); every lab scenario parses at each of its sizes."""
    raw = S.rmader_circle(10, 0, altitude=5.0)
    start = np.array([a["start"] for a in raw["agents"]])
    goal = np.array([a["goal"] for a in raw["agents"]])
    assert np.allclose(np.linalg.norm(start[:, :2], axis=1), 10.0) and np.allclose(start[:, 2], 5.0)
    assert np.allclose(goal[:, :2], -start[:, :2]) and np.allclose(goal[:, 2], 5.0)
    assert raw["agent_defaults"]["radius"] == 0.4 and raw["agent_defaults"]["speed"]["max"] == 5.0
    assert raw["sim"]["dt"] == 0.05 and raw["sim"]["goal_tolerance"] == 0.5
    room = S.crazyswarm_room(16, 0)
    sep = np.array(room["agent_defaults"]["separation"]) + 2 * room["agent_defaults"]["radius"]
    assert np.allclose(sep, S.CRAZYSWARM_ELLIPSOID)
    start = np.array([a["start"] for a in room["agents"]])
    goal = np.array([a["goal"] for a in room["agents"]])
    assert np.allclose(goal[:, :2], -start[:, :2])
    assert set(S.LAB_SIZES) == set(S.LAB_SCENARIOS)
    for name, sizes in S.LAB_SIZES.items():
        for n in sizes:
            assert len(S.scenario_world(name, n, 1).agents) == n


def test_lab_table_sets_the_published_figures_beside_ours():
    from swarmplan.bench.swarm_lab import lab_table, lab_verdicts
    from swarmplan.bench.swarm_report import Row

    rows = [
        Row("rmader_circle_5m", 10, "planner", s, 10, c, 0.3, 1.1, last, 42.0, 1.0, 10.0, 0, 4.0)
        for s, c, last in ((0, 0, 4.5), (1, 1, 5.5))
    ]
    text = lab_table(rows)
    assert "| rmader_circle_5m | 10 | planner | 20/20 | 50 % | 1 | 0.30 | 4.00 | 5.00 | 0 |" in text
    assert "| EGO-Swarm | 38 % | 5.64 |" in text and "mit-acl/rmader" in text
    verdicts = lab_verdicts(rows)
    assert verdicts[0].endswith("20/20, 1 pairs: NOT met")
    assert verdicts[1] == "- rmader_circle_5m, 10 agents, default planner: travel time 5.00 s <= 5 s: met"


def test_bench_times_the_log_apart_and_writes_the_same_log(tmp_path):
    """``bench swarm`` times swarmplan's log writing apart (a peer writes none): the log it writes
    through the timing is the plain recorder's, and the loop without it is never the slower."""
    import importlib.util
    from pathlib import Path

    from swarmplan.bench.swarm_runs import _RunMeter, _TimedRecorder, run_swarmplan
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import run_episode

    spec = importlib.util.spec_from_file_location("golden", Path(__file__).parent / "golden" / "golden.py")
    golden = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(golden)
    digests = []
    for timed in (False, True):
        sim = Simulation(S.scenario_world("sphere", 16, 0), planner="none")
        path = tmp_path / f"{timed}.mcap"
        with golden.frozen_clock():
            recorder = McapRecorder(path)
            observers = []
            if timed:
                recorder = _TimedRecorder(recorder)
                observers = [_RunMeter(sim.params.radius, False, recorder)]
            run_episode(sim, 0, observers=observers, recorder=recorder)
        digests.append(golden.describe(path)["sha256"])
    assert digests[0] == digests[1]
    row, _ = run_swarmplan("sphere", 16, 0, "apf")
    assert np.isfinite(row.rtf_logged) and row.rtf >= row.rtf_logged


def test_sphere_verdicts_weigh_the_same_work_and_say_the_logged_figure():
    from swarmplan.bench.swarm import done_verdicts, summary_table
    from swarmplan.bench.swarm_report import Row

    def row(system: str, seed: int, rtf: float, logged: float, path: float, last: float) -> Row:
        return Row("sphere", 64, system, seed, 64, 0, 1.0, path, last, last, 1.0, rtf, 0, last, logged)

    rows = [row("apf", s, 100.0 + s, 70.0, 1.2, 13.0 + s) for s in (0, 1)]
    rows += [row("orca", s, 90.0, float("nan"), 1.0, 9.0) for s in (0, 1)]
    verdicts = done_verdicts(rows)
    assert "- sphere 64: pure APF real-time factor 100.5 vs ORCA 90.0: met (with its log: 70.0)" in verdicts
    assert "- sphere 64: last arrival 14.0 s vs ORCA's 9.0 s (at most 1.5x: 13.5 s): NOT met" in verdicts
    assert "- sphere 64: pure APF's mean path 1.200 x the straight line <= 1.25: met" in verdicts
    table = summary_table(rows)
    assert "| 100.5 | 70.0 | 0 |" in table and "| 90.0 | - | 0 |" in table
