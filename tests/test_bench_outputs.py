"""Where the benchmarks write: a quick or default run writes to its output folder (under the
folder it is started from) and leaves the shipped docs alone; ``--docs DIR`` puts the page
elsewhere on purpose."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _tree(folder: Path) -> dict[str, str]:
    """{relative path: sha256} of every file under ``folder``."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _bench(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run(
        [sys.executable, "-m", "swarmplan.bench", *argv], cwd=cwd, env=env, capture_output=True, text=True
    )


def test_bench_swarm_quick_writes_its_output_folder_only(tmp_path: Path, monkeypatch, capsys):
    """In the test's process (``python -m swarmplan.bench``'s own exit codes are checked in
    processes of their own below)."""
    from swarmplan.cli.bench import main as bench_main

    docs = _tree(REPO / "docs")
    monkeypatch.chdir(tmp_path)
    assert bench_main(["swarm", "--quick", "--scenarios", "circle"]) == 0, capsys.readouterr().err
    assert _tree(REPO / "docs") == docs
    written = set(_tree(tmp_path))
    files = ("swarm.csv", "swarm-benchmarks.md", "swarm-circle.png")
    assert written == {f"logs/bench-swarm/{f}" for f in files}
    page = (tmp_path / "logs/bench-swarm/swarm-benchmarks.md").read_text()
    assert "| circle | 16 | planner |" in page and "![circle, 16 agents](swarm-circle.png)" in page
    assert capsys.readouterr().err == ""


def test_bench_swarm_refuses_a_file_as_its_docs_folder(tmp_path: Path):
    """--docs naming a file: one line, exit 2, before any flight."""
    (tmp_path / "page").write_text("")
    argv = ["swarm", "--quick", "--docs", str(tmp_path / "page"), "--out", str(tmp_path / "o")]
    run = _bench(argv, tmp_path)
    assert run.returncode == 2 and "--docs" in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_bench_scale_quick_writes_nothing(tmp_path: Path):
    docs = _tree(REPO / "docs")
    run = _bench(["scale", "--quick", "--skip-overhead"], tmp_path)
    assert run.returncode == 0, run.stderr
    assert _tree(REPO / "docs") == docs and _tree(tmp_path) == {}
    assert "no verdict (--quick)" in run.stdout and run.stderr == ""


def test_bench_swarm_separation_is_the_agents_and_orcas(tmp_path: Path):
    """--separation S: swarmplan's agents keep S (the world's separation on every axis), ORCA-3D
    flies with its radius grown by S/2; a bad value is refused before any flight."""
    from swarmplan.bench.swarm_scenarios import scenario_world

    world = scenario_world("circle", 4, 0, separation=2.5)
    assert all(tuple(a.separation) == (2.5, 2.5, 2.5) for a in world.agents)
    assert tuple(scenario_world("circle", 4, 0).agents[0].separation) == (1.0, 1.0, 1.0)
    run = _bench(["swarm", "--quick", "--separation", "-1", "--out", str(tmp_path / "o")], tmp_path)
    assert run.returncode == 2 and "--separation" in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "o").exists()


def test_orca_keeps_the_separation_asked():
    """ORCA-3D asked a 3 m separation on a circle swap of 6 keeps its bodies about that far
    apart (its radius grown by half the separation); asked none, it lets them come within
    1 m. (ORCA deadlocks in this symmetric swap: the gaps, not the arrivals, are compared.)"""
    pytest.importorskip("rvo23d")
    from swarmplan.bench.swarm import run_orca

    assert run_orca("circle", 6, 0).min_separation < 1.0
    assert run_orca("circle", 6, 0, separation=3.0).min_separation > 0.95 * 3.0
