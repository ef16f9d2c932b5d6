"""poses_at moves all-linear obstacles in one array operation and caches waypoint paths; the
poses equal pose_at's one obstacle at a time, bit for bit."""

from __future__ import annotations

import numpy as np
from helpers import base_world, make_world

from swarmplan.world.motion import pose_at, poses_at


def test_linear_batch_and_cached_paths_equal_pose_at():
    rng = np.random.default_rng(0)
    linear = [
        {
            "id": f"l{k}",
            "shape": "sphere",
            "radius": 1.0,
            "position": rng.uniform(10, 90, 3).tolist(),
            "motion": {"type": "linear", "velocity": rng.normal(0, 3, 3).tolist()},
        }
        for k in range(5)
    ]
    path = {
        "id": "w",
        "shape": "sphere",
        "radius": 1.0,
        "position": [20, 20, 20],
        "motion": {"type": "waypoints", "waypoints": [[60, 20, 20], [60, 70, 25]], "speed": 3, "loop": True},
    }
    world = make_world(base_world(obstacles=[*linear, path]))
    movers = world.moving_obstacles
    only_linear = tuple(o for o in movers if o.motion.type == "linear")
    for t in (0.0, 0.1, 3.3, 17.9, 123.4):
        for group in (movers, only_linear, list(only_linear)):
            pos, vel = poses_at(group, t)
            for k, o in enumerate(group):
                p, v = pose_at(o, t)
                assert np.array_equal(pos[k], p) and np.array_equal(vel[k], v)
    # A cached path answers as a fresh one (and cannot be changed through the answer).
    p1, _ = pose_at(movers[-1], 41.0)
    p2, _ = pose_at(movers[-1], 41.0)
    assert np.array_equal(p1, p2)
