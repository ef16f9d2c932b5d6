"""The run CLI: exit codes, bad input (exit 2, no traceback, no log), overrides, and a log that
the independent checker accepts."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from helpers import audit, base_world, read_log

from swarmplan.cli.run import main

REPO = Path(__file__).resolve().parents[1]


def write_world(tmp_path: Path, raw: dict, name: str = "w.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return p


def bad_world(tmp_path):
    raw = base_world(
        obstacles=[{"id": "tower", "shape": "sphere", "radius": 5, "position": [50, 50, 20]}],
        agents=[
            {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
            {"id": "b", "start": [50, 51, 20], "goal": [90, 60, 20], "sped": 3},
        ],
    )
    raw["log"] = {"path": "logs/{name}-{seed}.mcap"}
    return write_world(tmp_path, raw)


def test_bad_world_subprocess_exit_2_no_traceback_no_log(tmp_path):
    world = bad_world(tmp_path)
    r = subprocess.run(
        [sys.executable, "-m", "swarmplan.run", str(world), "--out", str(tmp_path / "out.mcap")],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO)),  # this checkout's package, wherever cwd is
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert "agents[1].start: inside obstacle 'tower'" in r.stderr
    assert "agents[1].sped: unknown key (did you mean 'speed'?)" in r.stderr
    assert not (tmp_path / "out.mcap").exists()
    assert not (tmp_path / "logs").exists()
    assert list(tmp_path.glob("**/*.mcap")) == []


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--optimizer", "bogus"], "unknown optimizer 'bogus'"),
        (["--max-time", "-1"], "--max-time: must be > 0"),
        (["--seed", "-4"], "--seed: must be >= 0"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, monkeypatch, capsys, extra, fragment):
    monkeypatch.chdir(tmp_path)
    world = write_world(tmp_path, base_world())
    assert main([str(world), *extra]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err
    assert list(tmp_path.glob("**/*.mcap")) == []


def test_missing_and_broken_world_files_exit_2(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([str(tmp_path / "absent.yaml")]) == 2
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n")
    assert main([str(broken)]) == 2
    err = capsys.readouterr().err
    assert "cannot read" in err and "invalid YAML" in err
    assert list(tmp_path.glob("**/*.mcap")) == []


def test_unknown_optimizer_in_world_lists_known(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    world = write_world(tmp_path, base_world(planner={"optimizer": {"name": "wao"}}))
    assert main([str(world)]) == 2
    err = capsys.readouterr().err
    assert "planner.optimizer.name: unknown optimizer 'wao' (did you mean 'woa'?)" in err
    assert "rscdwoa" in err and "pso" in err


def test_bad_planner_sections_exit_2_listing_every_problem(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    raw = base_world(
        planner={"escape": {"horizn": 5, "rounds": 0}, "global": {"cost": "mfco", "waypoints": 2.5}}
    )
    world = write_world(tmp_path, raw)
    assert main([str(world), "--out", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for fragment in (
        "planner.escape.horizn: unknown key (did you mean 'horizon'?)",
        "planner.escape.rounds: expected a whole number >= 1, got 0",
        "planner.global.cost: 'mfco' is not one of",
        "planner.global.waypoints: must be a whole number, got 2.5",
    ):
        assert fragment in err, err
    assert not (tmp_path / "x.mcap").exists()


def test_optimizer_override_drops_the_worlds_algorithm_params(tmp_path, monkeypatch, capsys):
    """rscdwoa's beta in the world must not reach woa when --optimizer woa runs it."""
    monkeypatch.chdir(tmp_path)
    raw = base_world(planner={"optimizer": {"name": "rscdwoa", "params": {"beta": 0.74}}})
    world = write_world(tmp_path, raw)
    assert main([str(world), "--optimizer", "woa", "--out", str(tmp_path / "w.mcap"), "--quiet"]) in (0, 1)
    assert "Traceback" not in capsys.readouterr().err
    assert (tmp_path / "w.mcap").exists()


def test_success_exit_0_default_log_path_and_check_log(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    raw = base_world(name="cli-ok", seed=4)
    raw["log"] = {"path": "logs/{name}-{seed}-{optimizer}.mcap", "foxglove": False}
    world = write_world(tmp_path, raw)
    assert main([str(world), "--optimizer", "none"]) == 0
    out = capsys.readouterr().out
    assert "SUCCESS: 1/1 arrived" in out
    log = tmp_path / "logs" / "cli-ok-4-none.mcap"
    assert log.exists()
    problems, _notes, stats = audit(log)
    assert problems == [] and stats["arrived"] == 1
    summary = read_log(log)["/summary"][-1][1]
    assert summary["success"] is True and summary["seed"] == 4 and summary["optimizer"] == "none"


def test_seed_out_and_max_time_overrides_exit_1_on_timeout(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    world = write_world(tmp_path, base_world())
    out = tmp_path / "o" / "run.mcap"
    code = main(
        [str(world), "--seed", "9", "--out", str(out), "--max-time", "2", "--optimizer", "none", "--quiet"]
    )
    assert code == 1  # 80 m in 2 s cannot be flown: finished, not successful
    assert capsys.readouterr().out == ""  # --quiet
    msgs = read_log(out)
    assert msgs["/world"][0][1]["seed"] == 9
    assert msgs["/world"][0][1]["sim"]["max_time"] == 2.0
    assert msgs["/agents/state"][-1][1]["t"] == pytest.approx(2.0)
    assert [d["kind"] for _, d in msgs["/events"]][-1] == "timeout"
    problems, _notes, _ = audit(out, allow_failure=True)
    assert problems == []


def test_keyboard_interrupt_exit_1_and_closed_log(tmp_path, monkeypatch, capsys):
    from swarmplan.sim import Simulation

    monkeypatch.chdir(tmp_path)
    world = write_world(tmp_path, base_world())
    out = tmp_path / "int.mcap"
    original = Simulation.step
    n = {"k": 0}

    def step(self):
        n["k"] += 1
        if n["k"] > 10:
            raise KeyboardInterrupt
        return original(self)

    monkeypatch.setattr(Simulation, "step", step)
    assert main([str(world), "--out", str(out), "--optimizer", "none"]) == 1
    assert "interrupted" in capsys.readouterr().err
    summary = read_log(out)["/summary"][-1][1]
    assert summary["interrupted"] is True


def test_quickstart_world_runs_clean_and_replays_whole(tmp_path, monkeypatch, capsys):
    """The quickstart's run succeeds, its log passes the audit and replay reads it back whole:
    every agent, every step, the movers' tracks, the summary's figures recomputed."""
    import numpy as np

    from swarmplan.replay import compare_with_summary, compute_metrics, load

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "qs.mcap"
    code = main([str(REPO / "worlds" / "quickstart.yaml"), "--out", str(out), "--quiet"])
    problems, _notes, stats = audit(out, allow_failure=True)
    assert problems == [], problems
    assert code == 0, f"quickstart did not succeed: {stats}"
    rec = load(out)
    assert not rec.truncated and rec.summary is not None
    assert rec.agent_ids == [a["id"] for a in rec.world["agents"]]
    assert rec.n_steps >= 2 and rec.times[-1] == pytest.approx(rec.summary["sim_time"])
    assert np.isfinite(rec.positions).all()
    assert set(rec.obstacle_tracks) == {o["id"] for o in rec.moving_obstacles}
    problems, n = compare_with_summary(rec, compute_metrics(rec))
    assert problems == [], problems
    assert n >= 5 * rec.n_agents


@pytest.mark.parametrize("where", ["a directory", "/proc/x.mcap"])
def test_unwritable_out_exit_2_one_line_before_any_work(tmp_path, monkeypatch, capsys, where):
    from swarmplan.sim import Simulation

    monkeypatch.chdir(tmp_path)
    world = write_world(tmp_path, base_world())
    out = str(tmp_path) if where == "a directory" else where
    monkeypatch.setattr(Simulation, "reset", lambda *a, **k: pytest.fail("the run started"))
    assert main([str(world), "--out", out]) == 2
    err = capsys.readouterr().err
    assert "--out: cannot write the log" in err and "Traceback" not in err
    assert len([line for line in err.splitlines() if line.strip()]) == 2  # "error: ..." + the problem


def test_bench_sim_zero_agents_exit_2(capsys):
    from swarmplan.cli.bench import main as bench

    assert bench(["sim", "--agents", "0"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "error: --agents: must be >= 1, got 0"


def test_bench_sim_of_a_missing_world_file_exit_2(capsys, tmp_path):
    from swarmplan.cli.bench import main as bench

    assert bench(["sim", "--world", str(tmp_path / "none.yaml")]) == 2
    assert capsys.readouterr().err.strip() == f"error: --world: no such file: {tmp_path / 'none.yaml'}"


def test_sigterm_closes_the_log_like_ctrl_c_and_counts_only_written_steps(tmp_path):
    """SIGTERM ends the run at a step boundary: exit 1, a readable log whose /summary says
    interrupted and counts exactly the steps whose states are in the log."""
    import os
    import signal
    import time

    out = tmp_path / "term.mcap"
    world = REPO / "worlds" / "traps" / "concave_wall.yaml"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen(
        [sys.executable, "-m", "swarmplan.run", str(world), "--out", str(out), "--optimizer", "none",
         "--max-time", "100000", "--quiet"],
        env=env, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while (not out.exists() or out.stat().st_size < 20000) and time.monotonic() < deadline:
            time.sleep(0.1)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 1, err
    assert "interrupted" in err and "Traceback" not in err
    log = read_log(out)
    summary = log["/summary"][-1][1]
    assert summary["interrupted"] is True and summary["success"] is False
    states = [m for _, m in log["/agents/state"]]
    assert summary["steps"] == len(states) - 1 > 0
    assert summary["sim_time"] == states[-1]["t"]
