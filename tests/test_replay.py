"""Replay: loading, recomputed metrics with known answers, plots, animation, CLI."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import (  # noqa: E402
    base_world,
    circle_positions,
    rich_log,
    states_from_arrays,
    straight_past_sphere_log,
    write_log,
)

from swarmplan.cli.replay import main as cli_main  # noqa: E402
from swarmplan.replay import compare_with_summary, compute_metrics, load  # noqa: E402
from swarmplan.replay.recording import RecordingError  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------- loading


def test_round_trip_arrays(tmp_path):
    path, pos, ids = rich_log(tmp_path / "rich.mcap", n_agents=3, steps=120)
    rec = load(path)
    assert not rec.truncated
    assert rec.agent_ids == ids
    assert rec.positions.shape == (3, 120, 3)
    np.testing.assert_allclose(rec.positions, pos, atol=1e-12)
    np.testing.assert_allclose(rec.times, np.round(np.arange(120) * 0.1, 10))
    assert rec.modes.shape == (3, 120)
    assert set(np.unique(rec.modes)) == {"apf", "escape", "smoothing", "arrived"}
    assert rec.modes[0, -1] == "arrived"
    assert np.isfinite(rec.velocities).all()
    np.testing.assert_allclose(rec.goals, pos[:, -1])
    assert rec.world["name"] == "synthetic"
    assert list(rec.obstacle_tracks) == ["intruder"]
    tr = rec.obstacle_tracks["intruder"]
    np.testing.assert_allclose(tr.positions[:, 0], 30 - 2 * rec.times)
    assert tr.orientations.shape == (120, 4)
    assert len(rec.events) == 4 * 3
    assert len(rec.optimizer_runs) == 2 * 3
    assert rec.optimizer_runs[0]["convergence"][0] == pytest.approx(100.0)
    assert rec.summary is not None and rec.summary["success"] is True
    assert rec.dt == pytest.approx(0.1)


def test_load_errors(tmp_path):
    with pytest.raises(RecordingError):
        load(tmp_path / "missing.mcap")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not an mcap file at all" * 10)
    with pytest.raises(RecordingError):
        load(junk)


def test_truncated_log_replays_up_to_last_chunk(tmp_path):
    full, pos, ids = rich_log(tmp_path / "full.mcap", n_agents=2, steps=400, chunk_size=4096)
    data = Path(full).read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    rec = load(cut)
    assert rec.truncated
    assert rec.summary is None
    assert 20 < rec.n_steps < 400
    np.testing.assert_allclose(rec.positions, pos[:, : rec.n_steps], atol=1e-12)
    # the CLI says so, and still replays
    out = subprocess.run(
        [sys.executable, "-m", "swarmplan.replay", str(cut)], capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    assert "NOTICE" in out.stdout and "cut short" in out.stdout
    assert "uav1" in out.stdout


def test_unfinished_writer_is_read_by_streaming(tmp_path):
    path, pos, ids = rich_log(
        tmp_path / "unfinished.mcap", n_agents=2, steps=300, finish=False, chunk_size=4096
    )
    rec = load(path)
    assert rec.truncated and rec.n_steps > 0
    np.testing.assert_allclose(rec.positions, pos[:, : rec.n_steps], atol=1e-12)


# ---------------------------------------------------------------------- metrics with exact answers


def test_straight_past_sphere_exact(tmp_path):
    path, clearance = straight_past_sphere_log(tmp_path / "s.mcap", distance=3.0)
    rec = load(path)
    (m,) = compute_metrics(rec)
    assert m.arrived and m.arrival_time == pytest.approx(10.0)
    assert m.path_length == pytest.approx(10.0, abs=1e-9)
    assert m.min_clearance == pytest.approx(clearance, abs=1e-12) == pytest.approx(1.5)
    assert m.closest_body == "ball"
    assert m.max_curvature == pytest.approx(0.0, abs=1e-9)
    assert m.collisions == 0
    problems, n = compare_with_summary(rec, [m])
    assert problems == [] and n >= 8


def _one_agent_line(tmp_path, name, obstacles, y=5.0, z=0.0, obstacle_states=None, radius=0.5, n=101):
    times = np.round(np.arange(n) * 0.1, 10)
    x = -5.0 + times
    pos = np.stack([x, np.full_like(x, y), np.full_like(x, z)], axis=1)[None]
    goal = [5.0, y, z]
    world = base_world(
        [{"id": "a", "start": pos[0, 0].tolist(), "goal": goal, "radius": radius}],
        obstacles,
        bounds={"min": [-20, -20, -20], "max": [20, 20, 20]},
    )
    states = states_from_arrays(times, ["a"], pos, goals=[goal])
    return load(write_log(tmp_path / f"{name}.mcap", world, states, obstacle_states))


@pytest.mark.parametrize(
    "obstacle, y, z, expected",
    [
        # box 2x2x2 yawed 45 deg: its corner points at the path, sqrt(2) from the centre
        ({"shape": "box", "size": [2, 2, 2], "rotation": [0, 0, 45]}, 5.0, 0.0, 5.0 - math.sqrt(2)),
        # box, no rotation, long in x: face at y = 1
        ({"shape": "box", "size": [20, 2, 2]}, 5.0, 0.0, 4.0),
        # cylinder r=1, height 4 along z; the path passes above its top cap at z = 5
        ({"shape": "cylinder", "radius": 1, "height": 4}, 0.0, 5.0, 3.0),
        # same cylinder rolled 90 deg: axis along y, the path (z=5) passes over its side
        ({"shape": "cylinder", "radius": 1, "height": 4, "rotation": [90, 0, 0]}, 0.0, 5.0, 4.0),
        # capsule r=1, straight section 4, pitched 90 deg: axis along x; path at y=5
        ({"shape": "capsule", "radius": 1, "height": 4, "rotation": [0, 90, 0]}, 5.0, 0.0, 4.0),
        # capsule upright: the path at z = 5 passes 1 m above the top cap (2 + 1 = 3)
        ({"shape": "capsule", "radius": 1, "height": 4}, 0.0, 5.0, 2.0),
        ({"shape": "sphere", "radius": 2}, 5.0, 0.0, 3.0),
    ],
)
def test_clearance_primitives_exact(tmp_path, obstacle, y, z, expected):
    obst = {"id": "o", "position": [0.0, 0.0, 0.0], **obstacle}
    rec = _one_agent_line(tmp_path, obstacle["shape"], [obst], y=y, z=z)
    (m,) = compute_metrics(rec)
    assert m.min_obstacle_clearance == pytest.approx(expected - 0.5, abs=1e-9)
    assert m.collisions == 0


def test_clearance_mesh_exact(tmp_path):
    import trimesh

    box = trimesh.creation.box(extents=[2, 2, 2])
    box.apply_translation([0.0, 1.0, 0.0])  # faces at y = 0 and y = 2
    obst = {
        "id": "m",
        "shape": "mesh",
        "position": [0, 1, 0],
        "vertices": box.vertices.tolist(),
        "faces": box.faces.tolist(),
    }
    rec = _one_agent_line(tmp_path, "mesh", [obst], y=5.0)
    (m,) = compute_metrics(rec)
    assert m.min_obstacle_clearance == pytest.approx(5.0 - 2.0 - 0.5, abs=1e-6)


def test_clearance_moving_obstacle_uses_track(tmp_path):
    # sphere r=1 keeping pace with the agent in x, nearest at t=5: (0, 3, 0) vs agent (0, 5, 0)
    times = np.round(np.arange(101) * 0.1, 10)
    states = [
        {"t": float(t), "obstacles": [{"id": "mv", "position": [t - 5.0, 3.0 - abs(t - 5.0), 0.0],
                                       "orientation": [0, 0, 0, 1]}]}
        for t in times
    ]  # fmt: skip
    obst = {
        "id": "mv",
        "shape": "sphere",
        "radius": 1.0,
        "position": [0, 8, 0],
        "motion": {"type": "waypoints"},
    }
    rec = _one_agent_line(tmp_path, "moving", [obst], y=5.0, obstacle_states=states)
    (m,) = compute_metrics(rec)
    assert m.min_obstacle_clearance == pytest.approx(5.0 - 3.0 - 1.0 - 0.5, abs=1e-9)


def test_collision_episodes_and_agent_clearance(tmp_path):
    # agent a flies through a sphere (1 episode); b and c pass head-on 2 m apart
    times = np.round(np.arange(101) * 0.1, 10)
    x = -5.0 + times
    a = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    b = np.stack([x, np.full_like(x, 10.0), np.zeros_like(x)], axis=1)
    c = np.stack([-x, np.full_like(x, 12.0), np.zeros_like(x)], axis=1)
    pos = np.stack([a, b, c])
    goals = [p[-1].tolist() for p in pos]
    world = base_world(
        [{"id": i, "start": p[0].tolist(), "goal": g} for i, p, g in zip("abc", pos, goals, strict=True)],
        [{"id": "ball", "shape": "sphere", "radius": 1.0, "position": [0, 0, 0]}],
    )
    rec = load(
        write_log(tmp_path / "c.mcap", world, states_from_arrays(times, list("abc"), pos, goals=goals))
    )
    ma, mb, mc = compute_metrics(rec)
    assert ma.collisions == 1 and ma.collision_bodies == ["ball"]
    assert ma.min_obstacle_clearance == pytest.approx(-1.5)
    assert mb.collisions == 0 and mc.collisions == 0
    assert mb.min_agent_clearance == pytest.approx(2.0 - 1.0) == mc.min_agent_clearance
    assert mb.closest_body == "c"


def test_curvature_of_circle(tmp_path):
    times = np.round(np.arange(300) * 0.1, 10)
    R = 20.0
    p = circle_positions(times, (0, 0), R, 0.2, 10.0)[None]  # 4 m/s on a 20 m circle
    world = base_world([{"id": "c", "start": p[0, 0].tolist(), "goal": [100, 100, 10]}], [])
    rec = load(
        write_log(tmp_path / "circ.mcap", world, states_from_arrays(times, ["c"], p, goals=[[100, 100, 10]]))
    )
    (m,) = compute_metrics(rec)
    assert m.max_curvature == pytest.approx(1.0 / R, rel=0.01)
    assert m.path_length == pytest.approx(R * 0.2 * times[-1], rel=1e-3)
    assert not m.arrived and m.arrival_time is None


def test_summary_disagreement_is_reported(tmp_path):
    path, _ = straight_past_sphere_log(tmp_path / "s.mcap")
    rec = load(path)
    rec.summary["agents"][0]["path_length"] = 12.0
    rec.summary["agents"][0]["collisions"] = 2
    problems, _ = compare_with_summary(rec, compute_metrics(rec))
    assert any("path_length" in p for p in problems)
    assert any("collisions" in p for p in problems)
    assert any("success" in p for p in problems) is False


# ---------------------------------------------------------------------- plots


def _image_stats(path):
    from PIL import Image

    img = np.asarray(Image.open(path).convert("RGB"), float)
    non_bg = np.mean(np.any(np.abs(img - 255.0) > 10, axis=2))
    return img.std(), non_bg


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    path, pos, ids = rich_log(tmp_path_factory.mktemp("rich") / "rich.mcap", n_agents=3, steps=150)
    return load(path)


@pytest.mark.parametrize("kind", ["plot_3d", "plot_top", "plot_curvature", "plot_convergence"])
def test_plots_non_trivial(rich, tmp_path, kind):
    from swarmplan.replay import analysis_plots, plots

    module = analysis_plots if kind in ("plot_curvature", "plot_convergence") else plots
    fig = getattr(module, kind)(rich)
    out = plots.save(fig, str(tmp_path / f"{kind}.png"))
    std, non_bg = _image_stats(out)
    assert std > 20 and non_bg > 0.05, (std, non_bg)
    if kind != "plot_convergence":
        assert plots.agent_paths_in(fig) == rich.agent_ids
        one = getattr(module, kind)(rich, agents=["uav2"])
        assert plots.agent_paths_in(one) == ["uav2"]
    else:
        runs = [line for line in fig.axes[0].lines if (line.get_gid() or "").startswith("run:")]
        assert len(runs) == len(rich.optimizer_runs)


def test_plot_3d_draws_every_obstacle_and_mode(rich):
    from swarmplan.replay import plots

    fig = plots.plot_3d(rich)
    ax = fig.axes[0]
    gids = {c.get_gid() for c in ax.collections} | {line.get_gid() for line in ax.lines}
    for o in rich.obstacles:
        assert f"obstacle:{o['id']}" in gids
    assert {"mode:escape:uav1", "mode:smoothing:uav1", "goal:uav3", "start:uav3", "terrain"} <= gids
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:3] == rich.agent_ids and "escape (optimizer) (agent colour)" in labels


def test_animation_gif(rich, tmp_path):
    from PIL import Image

    from swarmplan.replay.animate import animate, frame_steps

    steps = frame_steps(rich, fps=10, max_frames=6)
    assert len(steps) == 6 and steps[0] == 0 and steps[-1] == rich.n_steps - 1
    assert len(frame_steps(rich, fps=10, max_frames=1000, speed=5.0)) == math.ceil(rich.duration / 5 * 10) + 1
    out = animate(rich, str(tmp_path / "a.gif"), max_frames=6, progress=False, dpi=50)
    im = Image.open(out)
    assert im.n_frames == 6


# ---------------------------------------------------------------------- CLI


def test_cli_report_and_options(tmp_path, capsys):
    path, _, _ = rich_log(tmp_path / "r.mcap", n_agents=3, steps=120)
    plot = tmp_path / "p.png"
    code = cli_main([path, "--at", "5.04", "--agent", "uav2", "--events", "--plot-2d", str(plot)])
    out = capsys.readouterr().out
    assert code == 0
    assert "run: synthetic  seed 3  optimizer rscdwoa" in out
    assert "state at t = 5.000 s (step 50" in out
    table = out.split("metrics recomputed")[1].split("agreement")[0].strip().splitlines()[2:]
    assert [row.split()[0] for row in table] == ["uav2"]
    assert "escape_start" in out
    assert plot.exists() and plot.stat().st_size > 10_000


def test_cli_agreement_and_strict(tmp_path, capsys):
    path, _ = straight_past_sphere_log(tmp_path / "s.mcap")
    assert cli_main([path, "--strict"]) == 0
    assert "agreement with /summary: OK" in capsys.readouterr().out
    # a log whose summary lies
    rec = load(path)
    summ = dict(rec.summary, agents=[dict(rec.summary["agents"][0], min_clearance=0.2)])
    bad = write_log(
        tmp_path / "bad.mcap",
        rec.world,
        states_from_arrays(
            rec.times, rec.agent_ids, rec.positions, modes=rec.modes.tolist(), goals=rec.goals
        ),
        summary=summ,
    )
    assert cli_main([bad]) == 0
    out = capsys.readouterr().out
    assert "DISAGREEMENT" in out and "min_clearance recomputed 1.5 vs recorded 0.2" in out
    assert cli_main([bad, "--strict"]) == 1


def test_cli_exit_codes(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(os.urandom(300))
    for target in (junk, tmp_path / "missing.mcap"):
        out = subprocess.run(
            [sys.executable, "-m", "swarmplan.replay", str(target)], capture_output=True, text=True, cwd=ROOT
        )
        assert out.returncode == 2
        assert "cannot read" in out.stderr and "Traceback" not in out.stderr
    path, _ = straight_past_sphere_log(tmp_path / "s.mcap")
    assert cli_main([path, "--agent", "nobody"]) == 2
