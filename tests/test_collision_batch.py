"""The batched swept check (``first_hits``) and the candidate narrow phase of ``sweep_static``
name the same body as the broadphase manager's check they replaced, on cluttered random
worlds (rotated boxes, cylinders, capsules, spheres, movers), many steps grazing bodies."""

from __future__ import annotations

import fcl
import numpy as np
import pytest
from helpers import base_world, make_world

from swarmplan.geometry.collision import CollisionWorld, first_hits


def _world(seed: int):
    rng = np.random.default_rng(seed)
    obstacles = []
    for k in range(30):
        c = rng.uniform(10, 90, 3).tolist()
        c[2] = float(rng.uniform(5, 45))
        shape = ["sphere", "box", "cylinder", "capsule"][k % 4]
        o = {"id": f"o{k}", "shape": shape, "position": c, "rotation": rng.uniform(0, 90, 3).tolist()}
        if shape == "sphere":
            o["radius"] = float(rng.uniform(1, 4))
        elif shape == "box":
            o["size"] = rng.uniform(1, 8, 3).tolist()
        else:
            o["radius"], o["height"] = float(rng.uniform(0.5, 3)), float(rng.uniform(2, 10))
        obstacles.append(o)
    for k in range(6):
        obstacles.append(
            {
                "id": f"m{k}",
                "shape": "sphere",
                "radius": 2.0,
                "position": rng.uniform(20, 80, 3).tolist(),
                "motion": {"type": "linear", "velocity": rng.normal(0, 3, 3).tolist()},
            }
        )
    return make_world(base_world(obstacles=obstacles))


def _reference_static(cw: CollisionWorld, p0: np.ndarray, p1: np.ndarray, radius: float) -> str | None:
    """The previous sweep_static: the broadphase manager decides, bounding spheres name."""
    obj = cw._swept_object(p0, p1, radius)
    data = fcl.CollisionData(request=cw._request)
    cw._manager.collide(obj, data, fcl.defaultCollisionCallback)
    if not data.result.is_collision:
        return None
    reach = np.linalg.norm(cw._static_centers - (p0 + p1) / 2, axis=1) - cw._static_radii
    half = np.linalg.norm(p1 - p0) / 2 + radius + 1e-6
    for k in np.flatnonzero(reach <= half):
        if cw._collides(obj, cw._static_objs[k]):
            return cw.static[k].id
    return cw.static[int(np.argmin(reach))].id


@pytest.mark.parametrize("seed", range(3))
def test_batched_and_candidate_checks_name_the_manager_s_body(seed):
    w = _world(seed)
    cw = CollisionWorld(w)
    rng = np.random.default_rng(100 + seed)
    n = 400
    # Steps aimed at bodies' surfaces (many graze them) and random ones.
    targets = cw._static_centers[rng.integers(len(cw.static), size=n)]
    p0 = targets + rng.normal(0, 4, (n, 3))
    p1 = p0 + rng.normal(0, 1.5, (n, 3))
    p1[::7] = p0[::7]  # standing agents: a sphere, not a capsule
    radii = rng.uniform(0.3, 1.5, n)
    q0 = np.array([o.position for o in cw.moving])
    q1 = q0 + rng.normal(0, 0.5, q0.shape)
    got = first_hits(cw, p0, p1, radii, q0, q1)
    hits = 0
    for i in range(n):
        if p1[i][2] < radii[i] or p0[i][2] < radii[i] or (p1[i] < 0).any() or (p1[i] > [100, 100, 50]).any():
            continue  # ground or bounds first: no body to name
        static = _reference_static(cw, p0[i], p1[i], radii[i])
        assert cw.sweep_static(p0[i], p1[i], radii[i]) == static
        want = static or cw.sweep_moving(p0[i], p1[i], radii[i], q0, q1)
        assert got[i] == want, i
        hits += want is not None
    assert 50 < hits < n - 50  # the steps do touch bodies (and miss them)
