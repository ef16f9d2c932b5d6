"""``curvatures_with_cusps`` (all paths at once) gives, array for array and bit for bit, what
``curvature_with_cusps`` gives path by path: hovering, stops and reversals, steps of exactly
the drop distance, non-finite rows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.geometry.polyline import curvature_with_cusps, curvatures_with_cusps


def _paths(seed: int, steps: int = 120, n: int = 12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    vel = rng.normal(0, 1, (steps, n, 3)) * 0.3
    vel[rng.random((steps, n)) < 0.25] = 0.0  # hovering
    vel[rng.random((steps, n)) < 0.1] *= 1e-4  # below the drop distance
    vel[40:45, 0] = -vel[35:40, 0]  # reversals
    paths = np.cumsum(vel, axis=0) + rng.normal(0, 20, (1, n, 3))
    paths[:, 1] = 0.0
    paths[::2, 1, 0] = 1e-3  # a step of exactly the drop distance, back and forth
    paths[::3, 2, 1] = paths[0, 2, 1] + 1e-3 * (1 + 1e-15)
    return paths


@pytest.mark.parametrize("seed", range(4))
def test_all_paths_at_once_equal_one_by_one(seed):
    paths = _paths(seed)
    if seed == 3:
        paths[7, 4, 2] = np.nan  # dropped from its path first, as the one-path function does
        paths[9, 5] = np.inf
    many = curvatures_with_cusps(paths)
    assert len(many) == paths.shape[1]
    for i, got in enumerate(many):
        want = curvature_with_cusps(paths[:, i], with_steps=True)
        assert len(got) == 4
        for g, w in zip(got, want, strict=True):
            assert g.dtype == w.dtype and g.shape == w.shape
            assert g.tobytes() == w.tobytes()
    assert any(c.any() for _, c, _, _ in many)  # cusps present
    assert sum(len(c) for c, _, _, _ in many) > 500


def test_short_and_empty_paths():
    assert [len(c) for c, _, _, _ in curvatures_with_cusps(np.zeros((2, 3, 3)))] == [0, 0, 0]
    assert curvatures_with_cusps(np.zeros((0, 2, 3)))[1][2].shape == (0,)
    with pytest.raises(ValueError, match="paths"):
        curvatures_with_cusps(np.zeros((4, 3)))


def test_a_turn_after_merged_slow_steps_is_read_at_the_speeds_flown():
    # Two steps of 0.6 mm along x (the first point under the 1 mm drop distance: dropped),
    # then one of 1.2 mm turned by 60 degrees. The turn is flown at the mean of 0.6 and 1.2 mm
    # per interval over 1.5 intervals; read as one interval per kept step it would show 2x.
    from swarmplan.sim.metrics import max_lateral_accel

    dt, theta = 0.05, math.radians(60.0)
    pts = np.array([[0.0, 0, 0], [6e-4, 0, 0], [1.2e-3, 0, 0]])
    pts = np.vstack([pts, pts[-1] + 1.2e-3 * np.array([math.cos(theta), math.sin(theta), 0.0])])
    curv, cusp, mean, pace = curvature_with_cusps(pts, with_steps=True)
    assert not cusp.any() and pace == pytest.approx([0.5])
    want = 2.0 * (0.5 * (6e-4 + 1.2e-3) / dt) * math.sin(0.5 * theta) / (1.5 * dt)
    assert max_lateral_accel(curv, cusp, mean, pace, dt) == pytest.approx(want, rel=1e-9)


def test_a_circle_of_single_interval_steps_has_pace_one():
    from swarmplan.sim.metrics import max_lateral_accel

    dt, R, v = 0.05, 2.0, 1.2
    t = np.arange(200) * dt
    pts = np.stack([R * np.cos(v * t / R), R * np.sin(v * t / R), np.zeros_like(t)], axis=1)
    curv, cusp, mean, pace = curvature_with_cusps(pts, with_steps=True)
    assert (pace == 1.0).all() and not cusp.any()
    assert max_lateral_accel(curv, cusp, mean, pace, dt) == pytest.approx(v * v / R, rel=1e-3)
