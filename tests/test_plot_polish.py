"""What the replay plots say about themselves: movers' pose time and colours, terrain heights,
both threat rings, path points inside a threat core, starts unlike the animation's agents."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from conftest_replay import base_world, rich_log, states_from_arrays, write_log  # noqa: E402

from swarmplan.replay import load, plots  # noqa: E402
from swarmplan.replay.animate import animation_figure  # noqa: E402


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    return load(rich_log(tmp_path_factory.mktemp("polish") / "rich.mcap")[0])


def _labels(ax) -> list[str]:
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend else []


@pytest.mark.parametrize("kind", ["plot_3d", "plot_top"])
def test_movers_say_when_they_are_drawn_and_have_their_own_colour(rich, kind):
    fig = getattr(plots, kind)(rich)
    ax = fig.axes[0]
    moving = [lab for lab in _labels(ax) if lab.startswith("moving obstacle ")]
    oid = rich.moving_obstacles[0]["id"]
    assert moving and moving[0].startswith(f"moving obstacle {oid} at t = ")
    assert moving[0].endswith("(last pose)")
    track = next(line for line in ax.lines if line.get_gid() == f"track:{oid}")
    np.testing.assert_allclose(plots.mover_color(0), np.asarray(track.get_color())[:3])
    at_step = plots.plot_top(rich, step=10).axes[0]  # drawn at a step: that step's time
    assert any(f"at t = {rich.times[10]:.1f} s" in lab for lab in _labels(at_step))


def test_mover_colours_differ_from_each_other_and_from_the_agents():
    movers = [plots.mover_color(m) for m in range(len(plots.MOVING_COLORS))]
    for a, b in itertools.combinations(movers, 2):
        assert np.abs(a - b).sum() > 0.2
    agents = [np.asarray(c)[:3] for c in plots.agent_colors(20)]
    assert min(np.abs(m - a).sum() for m in movers for a in agents) > 0.25


def test_terrain_contours_carry_their_heights(rich):
    ax = plots.plot_top(rich).axes[0]
    heights = [t.get_text() for t in ax.texts if t.get_text().endswith(" m")]
    assert len(heights) >= 2


@pytest.mark.parametrize("kind", ["plot_3d", "plot_top"])
def test_both_threat_rings_are_in_the_legend(rich, kind):
    labels = _labels(getattr(plots, kind)(rich).axes[0])
    assert "threat: radar (core r_min)" in labels and "threat outer ring (r_max)" in labels


def test_path_points_inside_a_threat_core_are_marked(tmp_path):
    threat = {"kind": "radar", "position": [0, 0, 10], "r_min": 4, "r_max": 15}
    world = base_world([{"id": "a", "start": [-20, 0, 10], "goal": [20, 0, 10]}], threats=[threat])
    times = np.arange(41) * 0.1
    pos = np.stack([np.linspace(-20, 20, 41), np.zeros(41), np.full(41, 10.0)], axis=1)[None]
    states = states_from_arrays(times, ["a"], pos, goals=[[20, 0, 10]])
    rec = load(write_log(tmp_path / "c.mcap", world, states))
    ax = plots.plot_top(rec).axes[0]
    crosses = next(line for line in ax.lines if line.get_gid() == "core:a")
    assert len(crosses.get_xdata()) == int(np.sum(np.abs(pos[0, :, 0]) < 4))
    assert "inside a threat core" in _labels(ax)


def test_starts_do_not_look_like_the_animations_agents(rich):
    fig, draw = animation_figure(rich)
    draw(5)
    ax = fig.axes[0]
    starts = [line for line in ax.lines if (line.get_gid() or "").startswith("start:")]
    assert starts and {line.get_marker() for line in starts} == {plots.START_MARKER}
    assert plots.START_MARKER != "o"  # the animation's agents are circles
    assert "start" in _labels(ax)


def test_the_track_plot_shows_the_obstacles_within_the_world_bounds(tmp_path, monkeypatch):
    from conftest_replay import straight_past_sphere_log
    from matplotlib.figure import Figure

    from swarmplan.track import TrackerConfig, track
    from swarmplan.track.output import plot

    rec = load(straight_past_sphere_log(tmp_path / "s.mcap")[0])
    shown = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: shown.append(fig))
    plot(track(rec, TrackerConfig()), tmp_path / "t.png", rec=rec)
    ax3 = shown[0].axes[0]
    assert "obstacle:ball" in {c.get_gid() for c in ax3.collections}
    lo, hi = rec.world["bounds"]["min"], rec.world["bounds"]["max"]
    np.testing.assert_allclose(ax3.get_zlim(), (lo[2], hi[2]))
