"""Replay's command line on bad input and its library API."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest_replay import base_world, rich_log, states_from_arrays, straight_past_sphere_log, write_log

from swarmplan.cli.replay import main as cli_main
from swarmplan.replay import Event, ObstacleTrack, load
from swarmplan.replay.geometry import euler_deg_to_matrix, euler_deg_to_quat, quat_to_matrix


@pytest.fixture
def log(tmp_path):
    return straight_past_sphere_log(tmp_path / "run.mcap")[0]


BAD = [
    (["--plot", "x.pngg"], "--plot x.pngg: unsupported image type '.pngg'; use one of"),
    (["--plot-2d", "noext"], "--plot-2d noext: unsupported image type '(no extension)'"),
    (["--animate", "x.avi"], "--animate x.avi: unsupported animation type '.avi'; use .gif or .mp4"),
    (["--fps", "0"], "--fps: must be a positive number, got 0"),
    (["--fps", "nan"], "--fps: must be a positive number, got nan"),
    (["--max-frames", "0"], "--max-frames: must be >= 1, got 0"),
    (["--speed", "-2"], "--speed: must be a positive number, got -2"),
    (["--plot", "/proc/x.png"], "--plot /proc/x.png: cannot write in /proc"),
]


@pytest.mark.parametrize("args,message", BAD, ids=[a[0] + " " + a[1] for a, _ in BAD])
def test_bad_output_or_number_exits_2_with_one_line(log, tmp_path, monkeypatch, capsys, args, message):
    monkeypatch.chdir(tmp_path)
    assert cli_main([str(log), *args]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # checked before any work: not even the overview is printed
    assert err.count("\n") == 1 and err.startswith(f"error: {message}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]  # nothing written


def test_output_that_is_a_directory_exits_2(log, tmp_path, capsys):
    (tmp_path / "d.png").mkdir()
    assert cli_main([str(log), "--plot", str(tmp_path / "d.png")]) == 2
    assert capsys.readouterr().err == f"error: --plot {tmp_path / 'd.png'}: is a directory, not a file\n"


def test_unreadable_log_is_checked_after_outputs_exit_2(tmp_path, capsys):
    assert cli_main([str(tmp_path / "missing.mcap"), "--fps", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: --fps")
    assert cli_main([str(tmp_path / "missing.mcap")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_missing_parent_folders_are_created_like_run(log, tmp_path, capsys):
    """``run --out new/dir/x.mcap`` creates the folders; replay's outputs do the same."""
    png = tmp_path / "new" / "deeper" / "x.png"
    gif = tmp_path / "anim" / "x.gif"
    assert cli_main([str(log), "--plot", str(png), "--animate", str(gif), "--max-frames", "2"]) == 0
    assert png.stat().st_size > 1000 and gif.stat().st_size > 1000
    assert f"wrote {png}" in capsys.readouterr().out


def test_animate_rejects_bad_arguments_before_rendering(log, tmp_path):
    from swarmplan.replay.animate import animate

    rec = load(log)
    with pytest.raises(ValueError, match="unsupported animation type"):
        animate(rec, str(tmp_path / "x.avi"))
    with pytest.raises(ValueError, match="fps must be a positive number"):
        animate(rec, str(tmp_path / "x.gif"), fps=0)
    assert not any(tmp_path.glob("x.*"))


# ---------------------------------------------------------------------- library API (item 13)


def test_obstacle_track_at_scalar_and_array_shapes():
    tr = ObstacleTrack(
        "m",
        np.array([0.0, 1.0, 2.0]),
        np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]),
        np.tile([0.0, 0, 0, 1], (3, 1)),
    )
    p, q = tr.at(0.5)
    assert p.shape == (3,) and q.shape == (4,)
    assert np.allclose(p, [0.5, 0, 0])
    p, q = tr.at(np.array([0.5, 1.5]))
    assert p.shape == (2, 3) and q.shape == (2, 4)
    p, q = tr.at([0.25])
    assert p.shape == (1, 3) and np.allclose(p, [[0.25, 0, 0]])


def _drifting_times_log(path, n=409):
    """Times as a simulator computes them, (k + 1) * 0.1 in floating point: 40.800000000000004 etc."""
    times = np.array([(k + 1) * 0.1 for k in range(n)])
    assert times[407] == 40.800000000000004
    pos = np.stack([times, np.zeros(n), np.full(n, 10.0)], axis=1)[None]
    world = base_world([{"id": "a1", "start": [0, 0, 10], "goal": [100, 0, 10]}])
    events = [{"t": float(times[407]), "agent": "a1", "kind": "stuck", "detail": {"distance_to_go": 59.2}}]
    return write_log(path, world, states_from_arrays(times, ["a1"], pos), events=events)


def test_times_dt_and_event_times_on_the_step_grid(tmp_path):
    rec = load(_drifting_times_log(tmp_path / "drift.mcap"))
    assert rec.dt == 0.1  # the world's dt, not 0.10000000000000009
    assert rec.times[407] == 40.8
    assert rec.events == [Event(40.8, "a1", "stuck", {"distance_to_go": 59.2})]
    assert rec.events[0].to_json() == {
        "t": 40.8,
        "agent": "a1",
        "kind": "stuck",
        "detail": {"distance_to_go": 59.2},
    }


def test_recording_attributes(tmp_path):
    path, _pos, _ids = rich_log(tmp_path / "rich.mcap", steps=40)
    rec = load(path)
    assert rec.file == str(path)
    assert not hasattr(rec, "path")
    assert [o["id"] for o in rec.moving_obstacles] == ["intruder"]
    assert len(rec.static_obstacles) + len(rec.moving_obstacles) == len(rec.obstacles) == 6
    p, q = rec.obstacle_poses("intruder", np.array([1.0]))
    assert p.shape == (1, 3) and np.allclose(p[0], [28.0, -45, 25])
    assert all(isinstance(e, Event) and e.t == round(e.t, 9) for e in rec.events)


# ---------------------------------------------------------------------- rotations


def _rz_ry_rx(rpy):
    r, p, y = np.radians(rpy)
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_rotations_follow_the_world_contract_to_1e12():
    """R = Rz(yaw) Ry(pitch) Rx(roll) from [roll, pitch, yaw] degrees; quaternions [qx, qy, qz, qw]."""
    rng = np.random.default_rng(0)
    for rpy in rng.uniform(-400, 400, (300, 3)):
        want = _rz_ry_rx(rpy)
        assert np.abs(euler_deg_to_matrix(rpy) - want).max() < 1e-12
        q = euler_deg_to_quat(rpy)
        assert q[3] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-12
        assert np.abs(quat_to_matrix(q) - want).max() < 1e-12
        assert np.abs(quat_to_matrix(3.0 * q) - want).max() < 1e-12  # scale does not matter
    assert np.allclose(euler_deg_to_quat([0, 0, 90]), [0, 0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-15)
    assert quat_to_matrix(np.zeros((2, 4))).shape == (2, 3, 3)
    assert np.array_equal(quat_to_matrix([0, 0, 0, 0]), np.eye(3))


def test_animate_shows_no_progress_bar_off_a_terminal(log, tmp_path, capsys):
    """Captured output (stderr not a terminal) gets no progress bar, as with ``run``."""
    gif = tmp_path / "a.gif"
    assert cli_main([str(log), "--animate", str(gif), "--max-frames", "3"]) == 0
    out, err = capsys.readouterr()
    assert gif.stat().st_size > 1000 and f"wrote {gif}" in out
    assert err == "" and "\r" not in out
