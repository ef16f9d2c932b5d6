"""``moving_clearance`` measures unrotated sphere movers over every (point, pose) pair at once;
the values equal the per-pose loop through ``distance_and_gradient`` bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.geometry.shapes import distance_and_gradient
from swarmplan.planner import movers
from swarmplan.planner.movers import STEP, moving_clearance, positions_at
from swarmplan.sim import Simulation


def _reference(sim, pts, radius, t_lo, t_hi, cap=np.inf):  # noqa: ANN001
    """The per-pose loop (the previous code, every shape)."""
    n = len(pts)
    out = np.full(n, np.inf)
    idx = np.flatnonzero(sim.moving_mask)
    lo = np.broadcast_to(np.asarray(t_lo, dtype=float), (n,))
    hi = np.maximum(np.broadcast_to(np.asarray(t_hi, dtype=float), (n,)), lo)
    grid = lo.min() + np.arange(int(np.ceil((hi.max() - lo.min()) / STEP)) + 1) * STEP
    inside = (grid[None, :] >= lo[:, None] - 1e-9) & (grid[None, :] <= hi[:, None] + 1e-9)
    nearest = np.clip(np.round((lo - grid[0]) / STEP).astype(int), 0, len(grid) - 1)
    inside[np.arange(n), nearest] = True
    obstacles = [sim.world.obstacles[j] for j in idx]
    centers = positions_at(obstacles, grid)
    for m, o in enumerate(obstacles):
        poses, which = np.unique(centers[:, m].round(9), axis=0, return_inverse=True)
        which = which.reshape(-1)
        for u, c in enumerate(poses):
            sel = np.flatnonzero(inside[:, which == u].any(axis=1))
            sel = sel[np.linalg.norm(pts[sel] - c, axis=1) <= cap + radius + o.bounding_radius]
            if len(sel):
                out[sel] = np.minimum(out[sel], distance_and_gradient(o, pts[sel], c)[0] - radius)
    return out


@pytest.mark.parametrize("seed", range(3))
def test_vectorized_spheres_equal_the_loop(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    obstacles = [
        {
            "id": f"m{k}",
            "shape": "sphere",
            "radius": float(rng.uniform(1, 4)),
            "position": rng.uniform(20, 80, 3).round(3).tolist(),
            "motion": {"type": "linear", "velocity": rng.normal(0, 3, 3).tolist()},
        }
        for k in range(6)
    ]
    obstacles.append(  # a mover that parks: repeated poses
        {
            "id": "park",
            "shape": "sphere",
            "radius": 3.0,
            "position": [50, 50, 20],
            "motion": {"type": "waypoints", "waypoints": [[60, 50, 20]], "speed": 4, "loop": False},
        }
    )
    sim = Simulation(make_world(base_world(obstacles=obstacles)), planner="none")
    pts = rng.uniform(10, 90, (300, 3))
    t_lo = rng.uniform(0, 8, 300)
    t_hi = t_lo + rng.uniform(0, 6, 300)
    for cap in (np.inf, 5.0):
        want = _reference(sim, pts, 1.0, t_lo, t_hi, cap)
        assert np.array_equal(moving_clearance(sim, pts, 1.0, t_lo, t_hi, cap), want)
        # Small passes over the poses give the same values too.
        monkeypatch.setattr(movers, "_POSE_PAIRS", 500)
        assert np.array_equal(moving_clearance(sim, pts, 1.0, t_lo, t_hi, cap), want)
        monkeypatch.undo()
        if cap == 5.0:
            assert np.isinf(want).any() and np.isfinite(want).any()
