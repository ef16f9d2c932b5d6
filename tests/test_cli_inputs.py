"""Every command's bad outputs and numbers: one line naming the problem, exit 2, before any work.

Sweep and compare refuse an output folder that is a file or cannot be created and a malformed
scheduler address before a cluster starts; track refuses unwritable outputs before it reads
the log and creates missing folders as run and replay do; the optimizer benchmark refuses its
outputs and a run count of 0 before it runs. Logs cut short are named as such. Ctrl-C on a
sweep in a terminal prints no worker traceback and leaves a row for every finished log.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import rich_log, straight_past_sphere_log  # noqa: E402

from swarmplan.cli.bench import main as bench_main  # noqa: E402
from swarmplan.cli.compare import main as compare_main  # noqa: E402
from swarmplan.cli.replay import main as replay_main  # noqa: E402
from swarmplan.cli.sweep import main as sweep_main  # noqa: E402
from swarmplan.cli.track import main as track_main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PROC = Path("/proc")
needs_proc = pytest.mark.skipif(not PROC.is_dir(), reason="needs /proc (a folder nobody can write in)")

#: one agent crossing an empty box: the smallest world that runs
WORLD = {
    "name": "tiny",
    "seed": 0,
    "bounds": {"min": [0, 0, 0], "max": [100, 100, 50]},
    "sim": {"dt": 0.1, "max_time": 3, "goal_tolerance": 2.0},
    "agent_defaults": {"model": "multirotor", "radius": 1.0, "speed": {"min": 0, "max": 10, "cruise": 7},
                       "max_accel": 4, "min_altitude": 3, "separation": [4, 4, 2]},
    "agents": [{"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]}],
    "planner": {"optimizer": {"name": "woa", "population": 8, "iterations": 8}},
    "log": {"foxglove": False},
}  # fmt: skip


def one_line_exit_2(capsys, code: int, needle: str) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    assert needle in err, err
    return err


@pytest.fixture
def spec(tmp_path: Path) -> Path:
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(WORLD, sort_keys=False))
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump({"name": "s", "worlds": ["tiny.yaml"], "optimizers": ["woa"], "seeds": 1}))
    return path


def _cases(tmp_path: Path) -> list[tuple[list[str], str]]:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    cases = [
        (["--out", str(a_file)], "is a file, not a directory"),
        (["--out", str(a_file / "below")], "is a file, not a directory"),
        (["--scheduler", "localhost:8786x"], "not a scheduler address"),
        (["--scheduler", "tcp://head"], "not a scheduler address"),
    ]
    if PROC.is_dir():
        cases.append((["--out", "/proc/swarmplan-x"], "cannot write in /proc"))
    return cases


def test_sweep_bad_output_folder_or_scheduler_exit_2_before_a_cluster(spec, tmp_path, capsys):
    for args, needle in _cases(tmp_path):
        one_line_exit_2(capsys, sweep_main([str(spec), *args]), needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "spec.yaml", "tiny.yaml"]


def test_compare_bad_output_folder_or_scheduler_exit_2_before_a_cluster(spec, tmp_path, capsys):
    world = str(tmp_path / "tiny.yaml")
    for args, needle in _cases(tmp_path):
        args = ["--out-dir" if a == "--out" else a for a in args]
        one_line_exit_2(capsys, compare_main([world, "--optimizers", "woa", "--seeds", "3", *args]), needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "spec.yaml", "tiny.yaml"]


def test_sweep_and_compare_default_to_the_same_number_of_workers():
    from swarmplan.cli.compare import build_parser as compare_parser
    from swarmplan.cli.sweep import build_parser as sweep_parser

    sweep = sweep_parser().parse_args(["s.yaml"])
    compare = compare_parser().parse_args(["w.yaml"])
    assert sweep.workers == compare.workers == (os.cpu_count() or 1)
    assert compare_parser().parse_args(["w.yaml", "--jobs", "3"]).workers == 3  # the old name still works


@pytest.fixture
def small_log(tmp_path: Path) -> str:
    path, _ = straight_past_sphere_log(tmp_path / "s.mcap")
    return path


@needs_proc
@pytest.mark.parametrize("option", ["--out", "--plot"])
def test_track_unwritable_output_exits_2_before_tracking(small_log, capsys, option):
    name = "/proc/t.mcap" if option == "--out" else "/proc/t.png"
    one_line_exit_2(capsys, track_main([small_log, option, name]), f"{option} {name}: cannot write in /proc")


def test_track_creates_missing_output_folders_like_run_and_replay(small_log, tmp_path, capsys):
    out, png = tmp_path / "new" / "deeper" / "t.mcap", tmp_path / "other" / "t.png"
    assert track_main([small_log, "--out", str(out), "--plot", str(png)]) == 0, capsys.readouterr().err
    assert out.stat().st_size > 1000 and png.stat().st_size > 1000


def test_track_on_a_log_cut_short_says_so(tmp_path, capsys):
    cut = rich_log(tmp_path / "cut.mcap", n_agents=2, steps=300, finish=False, chunk_size=4096)[0]
    assert track_main([cut, "--json"]) == 0
    cap = capsys.readouterr()
    assert "cut short" in cap.err and "NOTICE" in cap.err
    assert cap.out.startswith("{")  # --json stays machine-readable: the notice goes to stderr


def test_a_log_cut_before_its_first_chunk_is_cut_short_not_foreign(tmp_path, capsys):
    full = rich_log(tmp_path / "full.mcap", n_agents=2, steps=200)[0]
    head = tmp_path / "head.mcap"
    head.write_bytes(Path(full).read_bytes()[:5000])
    one_line_exit_2(capsys, track_main([str(head)]), "cut short before its first complete chunk")
    one_line_exit_2(capsys, replay_main([str(head)]), "cut short before its first complete chunk")


def test_replay_names_a_missing_file_once(tmp_path, capsys):
    missing = str(tmp_path / "missing.mcap")
    err = one_line_exit_2(capsys, replay_main([missing]), "no such file")
    assert err.count(missing) == 1, err


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--runs", "0"], "--runs: must be >= 1, got 0"),
        (["--jobs", "0"], "--jobs: must be >= 1"),
        (["--out", "{tmp}"], "is a directory, not a file"),
        (["--raw", "{tmp}"], "is a directory, not a file"),
    ],
)
def test_bench_optimizers_checks_its_numbers_and_outputs_before_running(tmp_path, capsys, args, needle):
    args = [a.format(tmp=tmp_path) for a in args]
    code = bench_main(["optimizers", "--suite", "shifted", "--algorithms", "woa", *args])
    one_line_exit_2(capsys, code, needle)


def _sweep_in_a_terminal(tmp_path: Path, stop_after_logs: int) -> tuple[subprocess.CompletedProcess, Path]:
    """A sweep in its own process group, sent SIGINT as a terminal's Ctrl-C is (to the group)."""
    world = dict(WORLD, sim={"dt": 0.1, "max_time": 2, "goal_tolerance": 2.0})
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(world, sort_keys=False))
    (tmp_path / "spec.yaml").write_text(
        yaml.safe_dump({"name": "i", "worlds": ["tiny.yaml"], "optimizers": ["woa"], "seeds": 400})
    )
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "swarmplan.sweep", "spec.yaml", "--workers", "2", "--out", "out"]
    cmd.append("--no-progress")
    # A terminal's foreground job answers Ctrl-C: the sweep starts with SIGINT's default action
    # whatever this process inherited (a shell's background job ignores SIGINT, and so would it).
    proc = subprocess.Popen(
        cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        if len(list((out / "runs").glob("*.mcap"))) >= stop_after_logs:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=180)
    return subprocess.CompletedProcess(cmd, proc.returncode, stdout, stderr), out


def test_ctrl_c_on_a_sweep_prints_no_worker_traceback_and_keeps_every_finished_row(tmp_path):
    done, out = _sweep_in_a_terminal(tmp_path, stop_after_logs=3)
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    assert "interrupted after" in done.stderr
    with open(out / "results.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    logs = sorted(f"runs/{p.name}" for p in (out / "runs").glob("*.mcap"))
    assert len(logs) >= 3
    assert sorted(r["log"] for r in rows) == logs
    assert np.all([r["status"] == "ok" for r in rows])


def test_track_with_no_trackable_agent_says_so_and_writes_nothing(tmp_path, capsys):
    """Every agent skipped (here: one in /world that never flew): an error, not a blank plot."""
    from conftest_replay import base_world, write_log

    agents = [{"id": "ghost", "start": [0, 0, 20], "goal": [40, 0, 20]}]
    states = [{"t": round(0.1 * k, 9), "agents": []} for k in range(20)]
    log = write_log(tmp_path / "g.mcap", base_world(agents), states, summary={"agents": []})
    png = tmp_path / "g.png"
    one_line_exit_2(capsys, track_main([log, "--plot", str(png)]), "no agent of")
    assert not png.exists()
