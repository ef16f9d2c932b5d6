"""Replay's plots: threats drawn, escape segments in the agent's colour,
moving obstacles in a colour no agent gets and in the animation's legend, legends outside the
axes, cusps clipped and marked, convergence legend and run count, one-step segments visible."""

from __future__ import annotations

import numpy as np
import pytest
from conftest_replay import base_world, rich_log, states_from_arrays, write_log
from matplotlib.colors import to_rgb

from swarmplan.replay import analysis_plots, load, plots
from swarmplan.replay.animate import animation_figure


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    return load(rich_log(tmp_path_factory.mktemp("rich") / "rich.mcap", n_agents=4, steps=120)[0])


def _gids(ax) -> set[str]:
    arts = list(ax.lines) + list(ax.collections) + list(ax.patches)
    return {a.get_gid() for a in arts if a.get_gid()}


def _labels(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _zigzag_log(path, modes=None, optimizer=None):
    """One agent along x with one sharp turn-back at step 50 (a cusp) and gentle bends elsewhere."""
    n = 101
    times = np.round(np.arange(n) * 0.1, 10)
    x = np.where(np.arange(n) <= 50, np.arange(n) * 1.0, 100.0 - np.arange(n) * 1.0 + 0.5)
    y = 3.0 * np.sin(np.arange(n) / 15.0) + np.where(np.arange(n) > 50, 2.0, 0.0)
    pos = np.stack([x, y, np.full(n, 10.0)], axis=1)[None]
    goal = pos[0, -1].tolist()
    world = base_world([{"id": "a1", "start": pos[0, 0].tolist(), "goal": goal}])
    states = states_from_arrays(times, ["a1"], pos, modes=modes, goals=[goal])
    return load(write_log(path, world, states, optimizer=optimizer))


def test_threats_are_drawn_in_both_views_with_a_legend_entry_per_kind(rich):
    world = dict(rich.world)
    world["threats"] = rich.world["threats"] + [
        {"kind": "missile", "position": [10, 10, 0], "r_min": 5, "r_max": 20, "weight": 0.2},
        {"kind": "weather", "position": [-10, 10, 0], "r_min": 5, "r_max": 20, "weight": 0.2},
    ]
    rec = type(rich)(**{**rich.__dict__, "world": world})
    for fig in (plots.plot_top(rec), plots.plot_3d(rec)):
        ax = fig.axes[0]
        assert {"threat:0", "threat:1", "threat:2"} <= _gids(ax)
        labels = _labels(ax)
        for kind in ("radar", "missile", "weather"):
            assert f"threat: {kind} (core r_min)" in labels


def test_escape_segments_keep_the_agent_colour(rich):
    colors = plots.agent_colors(rich.n_agents)
    for fig in (plots.plot_top(rich), plots.plot_3d(rich)):
        lines = {line.get_gid(): line for line in fig.axes[0].lines}
        for i, aid in enumerate(rich.agent_ids):
            esc = lines[f"mode:escape:{aid}"]
            assert to_rgb(esc.get_color()) == pytest.approx(to_rgb(colors[i]))
            assert esc.get_linewidth() > lines[f"path:{aid}"].get_linewidth()
            assert esc.get_path_effects()  # outlined: distinct from the thin nominal path


@pytest.mark.parametrize("n", [2, 4, 10, 12, 20])
def test_moving_obstacles_have_a_colour_no_agent_has(n):
    mov = np.asarray(plots.MOVING_COLOR)
    gaps = [np.abs(mov - np.asarray(to_rgb(c))).sum() for c in plots.agent_colors(n)]
    assert min(gaps) > 0.3, min(gaps)


def test_animation_legend_lists_moving_obstacles_and_agent_modes(rich):
    fig, draw = animation_figure(rich, dpi=40)
    draw(rich.n_steps // 4 + 2)  # during the escapes
    labels = _labels(fig.axes[0])
    assert any(lab.startswith("moving obstacle ") for lab in labels)
    assert "agent escaping" in labels and "agent flying (APF)" in labels
    assert labels[: rich.n_agents] == rich.agent_ids


@pytest.mark.parametrize("kind", ["plot_top", "plot_3d"])
def test_legend_is_outside_the_axes_and_lists_start_and_goal(rich, kind):
    fig = getattr(plots, kind)(rich)
    fig.canvas.draw()
    ax = fig.axes[0]
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1 - 1
    assert {"start", "goal"} <= set(_labels(ax))


def test_curvature_cusp_is_clipped_and_marked(tmp_path):
    rec = _zigzag_log(tmp_path / "cusp.mcap")
    fig = analysis_plots.plot_curvature(rec)
    ax = fig.axes[0]
    line = next(ln for ln in ax.lines if ln.get_gid() == "path:a1")
    cusp = next(ln for ln in ax.lines if ln.get_gid() == "cusp:a1")
    top = ax.get_ylim()[1]
    assert np.nanmax(line.get_ydata()) <= top
    assert len(cusp.get_xdata()) >= 1 and abs(cusp.get_xdata()[0] - 5.0) <= 0.2  # the turn-back at t = 5 s
    assert any(lbl.startswith("cusp: ") for lbl in _labels(ax))
    # the gentle bends are not flattened: they use a visible part of the axis
    assert np.nanpercentile(line.get_ydata(), 90) > 0.05 * top


def test_curvature_without_cusp_is_not_clipped(tmp_path):
    times = np.round(np.arange(200) * 0.1, 10)
    ang = times * 0.2
    pos = np.stack([30 * np.cos(ang), 30 * np.sin(ang), np.full_like(ang, 10.0)], axis=1)[None]
    world = base_world([{"id": "c", "start": pos[0, 0].tolist(), "goal": pos[0, -1].tolist()}])
    rec = load(write_log(tmp_path / "c.mcap", world, states_from_arrays(times, ["c"], pos)))
    ax = analysis_plots.plot_curvature(rec).axes[0]
    assert not any((ln.get_gid() or "").startswith("cusp:") for ln in ax.lines)
    assert not any(lbl.startswith("cusp") for lbl in _labels(ax))


def _run(t, purpose, conv):
    return {"t": t, "agent": "a1", "algorithm": "iba_abc", "purpose": purpose, "evaluations": 10,
            "iterations": len(conv), "best_cost": conv[-1], "wall_ms": 1.0, "convergence": conv}  # fmt: skip


def test_convergence_legend_and_run_count(tmp_path):
    one = _zigzag_log(tmp_path / "one.mcap", optimizer=[_run(0.0, "global", [5.0, 4.0, 3.9])])
    ax = analysis_plots.plot_convergence(one).axes[0]
    assert ax.get_title() == "optimizer convergence: 1 run (iba_abc)"
    assert _labels(ax) == ["global plan", "a1"]
    runs = [
        _run(0.0, "global", [5.0, 4.0]),
        _run(2.0, "escape", [9.0, 1.0]),
        _run(3.0, "smoothing", [2.0, 1.5]),
    ]
    three = _zigzag_log(tmp_path / "three.mcap", optimizer=runs)
    ax = analysis_plots.plot_convergence(three).axes[0]
    assert ax.get_title() == "optimizer convergence: 3 runs (iba_abc)"
    assert _labels(ax) == ["escape", "smoothing", "global plan", "a1"]


def test_one_step_smoothing_segment_is_visible(tmp_path):
    modes = [["apf"] * 101]
    modes[0][20] = "smoothing"
    rec = _zigzag_log(tmp_path / "s.mcap", modes=modes)
    for fig in (plots.plot_top(rec), plots.plot_3d(rec)):
        ax = fig.axes[0]
        assert "mode-dot:smoothing:a1" in _gids(ax)
        assert "smoothing (halo) (agent colour)" in _labels(ax)


def test_long_segments_get_no_dot(rich):
    gids = _gids(plots.plot_top(rich).axes[0])
    assert "mode:escape:uav1" in gids and not any(g.startswith("mode-dot:escape") for g in gids)


def test_curvature_line_shows_the_turn_flown_and_each_fixed_wings_limit(tmp_path):
    """A multirotor turning by 0.05 rad every other 1 m step (per step: 0.05 and 0 1/m in turn)
    flies a curvature of 0.025 1/m, which the line shows; a fixed wing's limit (1 / 40 m) is a
    dashed line, a multirotor has none (its limit is a lateral acceleration)."""
    n = 200
    times = np.round(np.arange(n) * 0.1, 10)
    heading = np.concatenate([[0.0], np.cumsum(np.where(np.arange(n - 1) % 2 == 0, 0.05, 0.0))])[:-1]
    steps = np.stack([np.cos(heading), np.sin(heading), np.zeros(n - 1)], axis=1)
    rotor = np.vstack([[0.0, 0.0, 10.0], [0.0, 0.0, 10.0] + np.cumsum(steps, axis=0)])
    ang = np.arange(n) * 0.01  # 1 m steps on a circle of 100 m
    wing = np.stack([100 * np.sin(ang), 100 - 100 * np.cos(ang), np.full(n, 20.0)], axis=1)
    pos = np.stack([rotor, wing])
    agents = [
        {"id": "mr", "start": rotor[0].tolist(), "goal": rotor[-1].tolist()},
        {"id": "fw", "model": "fixed_wing", "min_turn_radius": 40.0, "start": wing[0].tolist(),
         "goal": wing[-1].tolist(), "speed": {"min": 8.0, "max": 15.0, "cruise": 10.0}},
    ]  # fmt: skip
    world = base_world(agents, bounds={"min": [-300, -300, 0], "max": [300, 300, 50]})
    goals = [rotor[-1].tolist(), wing[-1].tolist()]
    states = states_from_arrays(times, ["mr", "fw"], pos, goals=goals)
    rec = load(write_log(tmp_path / "turns.mcap", world, states))
    ax = analysis_plots.plot_curvature(rec).axes[0]
    lines = {ln.get_gid(): ln for ln in ax.lines if ln.get_gid()}
    assert [g for g in lines if g.startswith("limit:")] == ["limit:0.025"]
    assert lines["limit:0.025"].get_ydata()[0] == pytest.approx(0.025)
    flown = np.asarray(lines["path:mr"].get_ydata())[20:-20]  # a whole window on either side
    assert np.allclose(flown, 0.025, rtol=0.06), (flown.min(), flown.max())
    step = np.asarray(lines["step:mr"].get_ydata())
    assert step.max() == pytest.approx(0.05, rel=1e-3) and step.min() < 1e-9  # per step: in turn
    circle = np.asarray(lines["path:fw"].get_ydata())[20:-20]
    assert np.allclose(circle, 0.01, rtol=1e-3)
    assert any(lbl.startswith("fixed-wing limit 0.025") for lbl in _labels(ax))
