"""Sweeps on Dask: a LocalCluster of one worker process runs small studies of tiny worlds (the
suite runs a file per core already, so a second worker would only add its start-up).

Rows and logs (16 = 2 worlds x 2 optimizers x 2 seeds x 2 override values, every log audited by
check_log and by the replay recomputation), the same rows as serial ``swarmplan.run`` runs, a
worker killed mid-run loses nothing, ``--resume`` redoes nothing, a failing world gives error
rows, bad specs exit 2 naming every problem, and ``compare`` on the same engine.
"""

from __future__ import annotations

import copy
import math
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import audit, find_check_log, log_positions

from swarmplan.cli.sweep import main as sweep_main
from swarmplan.replay.metrics import compare_with_summary, compute_metrics
from swarmplan.replay.recording import load
from swarmplan.sweep import engine
from swarmplan.sweep.adapter import OverrideError, set_dotted
from swarmplan.sweep.spec import SpecError, load_spec

AGENTS = {"model": "multirotor", "radius": 1.0, "speed": {"min": 0, "max": 10, "cruise": 7},
          "max_accel": 4, "min_altitude": 3, "separation": [4, 4, 2]}  # fmt: skip

#: Two agents crossing past a sphere: arrives in ~12 s without any escape.
OPEN = {
    "name": "open",
    "seed": 0,
    "bounds": {"min": [0, 0, 0], "max": [100, 100, 50]},
    "sim": {"dt": 0.1, "max_time": 16, "goal_tolerance": 2.0},
    "obstacles": [{"id": "ball", "shape": "sphere", "radius": 6, "position": [50, 50, 20]}],
    "agent_defaults": AGENTS,
    "agents": [
        {"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
        {"id": "b", "start": [50, 10, 20], "goal": [50, 90, 22]},
    ],
    "planner": {"optimizer": {"name": "woa", "population": 8, "iterations": 8}},
    "log": {"foxglove": False},
}
#: A U-shaped pocket in front of the goal, flown on the bare field (``planner.apf.guide: false``,
#: which the workers read from the world file): pure APF gets stuck, the optimizer plans escapes.
POCKET = {
    "name": "pocket",
    "seed": 1,
    "bounds": {"min": [0, 0, 0], "max": [120, 80, 30]},
    "sim": {"dt": 0.1, "max_time": 12, "goal_tolerance": 2.0},
    "obstacles": [
        {"id": "back", "shape": "box", "size": [4, 36, 40], "position": [62, 40, 15]},
        {"id": "left", "shape": "box", "size": [24, 4, 40], "position": [48, 22, 15]},
        {"id": "right", "shape": "box", "size": [24, 4, 40], "position": [48, 58, 15]},
    ],
    "agent_defaults": AGENTS,
    "agents": [{"id": "uav1", "start": [10, 40, 15], "goal": [105, 40, 15]}],
    "planner": {
        "apf": {"k_att": 1.0, "k_rep": 50.0, "influence": 12.0, "k_agent": 20.0, "guide": False},
        "stuck": {"window": 2.0, "min_progress": 0.5},
        "optimizer": {"name": "woa", "population": 8, "iterations": 8},
    },
    "log": {"foxglove": False},
}
POP = "planner.optimizer.population"


def write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def study(tmp: Path, worlds=(("open.yaml", OPEN), ("pocket.yaml", POCKET)), **spec) -> Path:
    for name, raw in worlds:
        write(tmp / name, raw)
    base = {"name": "t", "worlds": [n for n, _ in worlds], "optimizers": ["woa", "rscdwoa"], "seeds": 2,
            "overrides": {POP: [6, 10]}}  # fmt: skip
    base.update(spec)
    return write(tmp / "spec.yaml", base)


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    import logging

    with (
        distributed.LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            silence_logs=logging.ERROR,
            dashboard_address=":0",
        ) as c,
        distributed.Client(c) as client,
    ):
        yield c, client


@pytest.fixture(scope="module")
def full(cluster, tmp_path_factory):
    """The 16-run sweep, run once for the tests that read it."""
    _, client = cluster
    tmp = tmp_path_factory.mktemp("full")
    spec = load_spec(study(tmp))
    out = tmp / "out"
    rows, skipped = engine.run_tasks(spec.tasks(), out, spec.override_keys, client, progress=False)
    return spec, out, rows, skipped


def test_sixteen_rows_and_sixteen_valid_logs(full):
    spec, out, rows, skipped = full
    assert skipped == 0 and len(rows) == 16
    keys = {(r["world"], r["optimizer"], r["seed"], r[POP]) for r in rows}
    assert keys == {(w, o, s, p) for w in ("open.yaml", "pocket.yaml") for o in ("woa", "rscdwoa")
                    for s in (0, 1) for p in (6, 10)}  # fmt: skip
    assert all(r["status"] == "ok" for r in rows), [r["error"] for r in rows if r["status"] != "ok"]
    csv_rows = engine.read_results(out / "results.csv")
    assert [(r["world"], r["optimizer"], int(r["seed"]), int(r[POP])) for r in csv_rows] == [
        (r["world"], r["optimizer"], r["seed"], r[POP]) for r in rows
    ]
    assert list(csv_rows[0]) == engine.columns([POP])
    logs = sorted(out.glob("runs/*"))
    assert len(logs) == 16 and {out / r["log"] for r in rows} == set(logs)  # no leftover .part files
    # The open world flies through without escapes; the pocket needs them under every optimizer.
    for r in rows:
        assert (r["escapes"] > 0) == (r["world"] == "pocket.yaml"), r
        assert r["success"] == (r["world"] == "open.yaml") and r["arrived"] == (2 if r["success"] else 0)
    for r in rows:
        rec = load(out / r["log"])
        assert not rec.truncated and not rec.interrupted
        assert rec.summary["seed"] == r["seed"] and rec.summary["optimizer"] == r["optimizer"]
        assert rec.world["planner"]["optimizer"]["population"] == r[POP]
        problems, n = compare_with_summary(rec, compute_metrics(rec))
        assert problems == [] and n > 0, (r["log"], problems)
        if find_check_log() is not None:
            problems, _notes, _stats = audit(out / r["log"], allow_failure=True)
            assert problems == [], (r["log"], problems)


def test_report_tables_verdicts_and_box_plots(full, tmp_path):
    spec, out, rows, _ = full
    from swarmplan.sweep.report import write_report

    report = write_report(tmp_path, spec.name, rows, list(spec.optimizers), spec.override_keys, 0.05, [])
    text = report.read_text()
    assert text.count("| woa ") == 4 and text.count("| rscdwoa ") == 4  # 2 worlds x 2 values
    assert "(reference)" in text and "planning vs woa" in text
    pngs = sorted(tmp_path.glob("box-*.png"))
    assert [p.name for p in pngs] == ["box-open.png", "box-pocket.png"]
    from matplotlib.image import imread

    img = imread(pngs[1])
    assert img.shape[1] > 600 and np.std(img[..., :3]) > 0.05  # drawn, not blank


def _serial_row(tmp: Path, world: dict, optimizer: str, seed: int, population: int) -> tuple[Path, dict]:
    """The run as a user would do it by hand: a world file with the value, then swarmplan.run."""
    from swarmplan.cli.run import main as run_main

    raw = copy.deepcopy(world)
    raw["planner"]["optimizer"]["population"] = population
    path = write(tmp / f"{world['name']}-{population}.yaml", raw)
    log = tmp / f"{world['name']}-{optimizer}-{seed}-{population}.mcap"
    code = run_main([str(path), "--optimizer", optimizer, "--seed", str(seed), "--out", str(log), "--quiet"])
    assert code in (0, 1)
    return log, load(log).summary


@pytest.mark.parametrize(("world", "optimizer", "seed", "pop"), [
    (OPEN, "rscdwoa", 1, 6), (POCKET, "woa", 0, 10), (POCKET, "rscdwoa", 1, 6)])  # fmt: skip
def test_same_rows_as_serial_swarmplan_run(full, tmp_path, world, optimizer, seed, pop):
    _, out, rows, _ = full
    row = next(r for r in rows if r["world"] == f"{world['name']}.yaml" and r["optimizer"] == optimizer
               and r["seed"] == seed and r[POP] == pop)  # fmt: skip
    log, summary = _serial_row(tmp_path, world, optimizer, seed, pop)
    arrived = [a for a in summary["agents"] if a["arrived"]]
    expect = {
        "success": summary["success"],
        "arrived": summary["arrived"],
        "collisions": summary["collisions"],
        "sim_time": summary["sim_time"],
        "escapes": sum(a["escapes"] for a in summary["agents"]),
        "path_length_mean": np.mean([a["path_length"] for a in arrived]) if arrived else math.nan,
        "arrival_time_mean": np.mean([a["arrival_time"] for a in arrived]) if arrived else math.nan,
    }
    got = {k: row[k] for k in expect}
    np.testing.assert_equal(got, expect)
    _, t1, p1 = log_positions(out / row["log"])
    _, t2, p2 = log_positions(log)
    np.testing.assert_array_equal(t1, t2)
    np.testing.assert_array_equal(p1, p2)


def test_resume_redoes_nothing(full, cluster, tmp_path):
    spec, out, rows, _ = full
    _, client = cluster
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("runs/*.mcap")}
    again, skipped = engine.run_tasks(
        spec.tasks(), out, spec.override_keys, client, resume=True, progress=False
    )
    assert skipped == 16
    assert {p: p.stat().st_mtime_ns for p in out.glob("runs/*.mcap")} == stamps
    np.testing.assert_equal(again, rows)
    assert len(engine.read_results(out / "results.csv")) == 16


def test_resume_reruns_only_what_is_missing(cluster, tmp_path):
    """A sweep cut short (one log lost, one cut mid-file, results.csv behind): --resume runs
    exactly those two again and ends with every row once."""
    _, client = cluster
    spec = load_spec(study(tmp_path, worlds=(("open.yaml", OPEN),), seeds=2, overrides={}))
    out = tmp_path / "out"
    rows, _ = engine.run_tasks(spec.tasks(), out, [], client, progress=False)
    logs = [out / r["log"] for r in rows]
    logs[0].unlink()
    data = logs[3].read_bytes()
    logs[3].write_bytes(data[: len(data) // 2])
    keep = {p: p.stat().st_mtime_ns for p in (logs[1], logs[2])}
    lines = (out / "results.csv").read_text().splitlines()
    (out / "results.csv").write_text("\n".join(lines[:2]) + "\n")  # header + first row only
    ran = []
    again, skipped = engine.run_tasks(
        spec.tasks(), out, [], client, resume=True, progress=False, on_row=ran.append
    )
    assert skipped == 2 and sorted((r["optimizer"], r["seed"]) for r in ran) == [("rscdwoa", 1), ("woa", 0)]
    assert {p: p.stat().st_mtime_ns for p in keep} == keep
    assert len(engine.read_results(out / "results.csv")) == 4 and all(r["status"] == "ok" for r in again)
    for a, b in zip(again, rows, strict=True):
        np.testing.assert_equal(
            {k: v for k, v in a.items() if k not in engine.TIMING},
            {k: v for k, v in b.items() if k not in engine.TIMING},
        )


def test_worker_killed_mid_run_loses_nothing(cluster, tmp_path):
    _, client = cluster
    spec = load_spec(study(tmp_path, worlds=(("pocket.yaml", POCKET),), seeds=[0, 1, 2], overrides={}))
    out = tmp_path / "out"
    result: dict = {}
    thread = threading.Thread(
        target=lambda: result.update(rows=engine.run_tasks(spec.tasks(), out, [], client, progress=False)[0])
    )
    thread.start()
    victim = None
    deadline = time.monotonic() + 60
    while victim is None and time.monotonic() < deadline:
        # A run is mid-flight once its attempt's log file has been written to.
        parts = [p for p in out.glob("runs/*.part") if p.stat().st_size > 0]
        busy = {w: ks for w, ks in client.processing().items() if ks}
        if parts and busy:
            worker, keys = next(iter(busy.items()))
            running = [p for p in parts if any(p.name.split(".mcap")[0] in k for k in keys)]
            if running:
                victim = (worker, keys, running)
                pid = client.run(os.getpid, workers=[worker])[worker]
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.02)
    thread.join(120)
    assert victim is not None, "no run was seen in flight"
    rows = result["rows"]
    assert len(rows) == 6 and len({(r["optimizer"], r["seed"]) for r in rows}) == 6
    assert all(r["status"] == "ok" for r in rows), [r["error"] for r in rows]
    assert len(engine.read_results(out / "results.csv")) == 6
    assert sorted(out.glob("runs/*")) == sorted(
        out / r["log"] for r in rows
    )  # the dead attempt's file is gone
    for r in rows:
        rec = load(out / r["log"])
        assert not rec.truncated and rec.summary["seed"] == r["seed"]


def test_world_that_raises_gives_error_rows_and_the_sweep_goes_on(cluster, tmp_path):
    _, client = cluster
    spec = load_spec(study(tmp_path, seeds=[0], overrides={}))
    # Edited after validation (someone saving the file during a sweep): the runs of that world raise.
    (tmp_path / "pocket.yaml").write_text("name: pocket\nbounds: [oops\n")
    rows, _ = engine.run_tasks(spec.tasks(), tmp_path / "out", [], client, progress=False)
    assert [(r["world"], r["status"]) for r in rows] == [
        ("open.yaml", "ok"),
        ("open.yaml", "ok"),
        ("pocket.yaml", "error"),
        ("pocket.yaml", "error"),
    ]
    for r in rows[2:]:
        assert r["error"].startswith("WorldError") and "invalid YAML" in r["error"] and r["success"] is False
    csv_rows = engine.read_results(tmp_path / "out" / "results.csv")
    assert [r["status"] for r in csv_rows] == ["ok", "ok", "error", "error"] and "invalid YAML" in csv_rows[
        3
    ]["error"]


def test_cli_on_a_running_scheduler_with_resume(full, cluster, capsys):
    spec, out, rows, _ = full
    c, _ = cluster
    code = sweep_main([str(spec.source), "--scheduler", c.scheduler_address, "--out", str(out), "--resume"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "= 16 runs" in err and "16 runs (16 kept from an earlier sweep, 0 run now), 0 error(s)" in err
    assert "dashboard: " in err and c.scheduler_address in err
    assert "| rscdwoa " in (out / "report.md").read_text()


def test_bad_specs_exit_2_naming_every_problem_and_run_nothing(tmp_path, capsys):
    spec = study(tmp_path, worlds=(("open.yaml", OPEN),), optimizers=["woa", "wao", "none"], seed=3,
                 overrides={POP: [1, 6], "planner.optimizer.populaton": [5], "name.x": [1],
                            "agents.7.radius": [1.0], "sim.dt": 0.1})  # fmt: skip
    raw = yaml.safe_load(spec.read_text())
    raw["worlds"].append("missing/*.yaml")
    write(spec, raw)
    out = tmp_path / "out"
    assert sweep_main([str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and not out.exists()
    for needle in (
        "seed: unknown key (did you mean 'seeds'?)",
        "no world file matches 'missing/*.yaml'",
        "unknown optimizer 'wao' (did you mean 'woa'?)",
        "overrides.sim.dt: expected a non-empty list",
        # the override paths and values, checked against the world format by parse_world:
        "planner.optimizer.population: must be >= 2",
        "planner.optimizer.populaton: unknown key",
        "overrides.name.x: name is a str",
        "overrides.agents.7.radius: agents has 2 item(s), no index 7",
    ):
        assert needle in err, err
    lines = err.strip().splitlines()
    assert len(lines) >= 8 and len(set(lines)) == len(lines), err  # each problem once
    assert not out.exists()
    bad = {"worlds": "open.yaml", "optimizers": ["woa"], "overrides": {"planner.optimizer.name": ["ba"]}}
    with pytest.raises(SpecError) as exc:
        load_spec(write(tmp_path / "s2.yaml", bad))
    assert "chosen by 'optimizers:'" in str(exc.value)


def test_set_dotted_paths():
    raw = {"agents": [{"id": "a"}], "planner": None}
    set_dotted(raw, "agents.0.radius", 2.0)
    set_dotted(raw, "planner.optimizer.params.tent_beta", 0.7)
    assert raw == {
        "agents": [{"id": "a", "radius": 2.0}],
        "planner": {"optimizer": {"params": {"tent_beta": 0.7}}},
    }
    with pytest.raises(OverrideError, match="index it with a number"):
        set_dotted(raw, "agents.first.radius", 1.0)


def test_compare_is_a_front_end_of_the_engine(cluster, tmp_path, capsys):
    from swarmplan.cli.compare import main as compare_main

    c, _ = cluster
    world = write(tmp_path / "open.yaml", OPEN)
    out = tmp_path / "cmp"
    code = compare_main([str(world), "--optimizers", "woa,none", "--seeds", "2", "--out-dir", str(out),
                         "--scheduler", c.scheduler_address])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    rows = engine.read_results(out / "results.csv")
    assert [(r["optimizer"], r["seed"], r["status"]) for r in rows] == [
        ("woa", "0", "ok"), ("woa", "1", "ok"), ("none", "0", "ok"), ("none", "1", "ok")]  # fmt: skip
    table = [ln for ln in captured.out.splitlines() if ln.startswith("| ")]
    assert table[2].startswith("| woa ") and "2/2 (100%)" in table[2] and "(reference)" in table[2]
    assert table[3].startswith("| none ") and len(sorted(out.glob("runs/*.mcap"))) == 4
    home = [c.strip() for c in table[0].split("|")].index("agents home")
    assert [c.strip() for c in table[2].split("|")][home] == "4/4"  # 2 agents x 2 seeds
    # the open world never needs an optimizer: said, and each note once
    said = captured.out + captured.err
    assert "note: no optimizer ran in any run of woa: " in captured.out and "(the same as `none`'s)" in said
    assert said.count("no verdict can be significant") == 1 and said.count("rank-sum") == 1
    assert compare_main([str(world), "--optimizers", "woa,nope", "--seeds", "0"]) == 2
    err = capsys.readouterr().err
    assert "--seeds: must be >= 1" in err and "--optimizers: unknown optimizer 'nope'" in err, err
