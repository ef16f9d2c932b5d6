"""The compiled per-step geometry (swarm-sized worlds) equals the numpy one bit for bit: the
distance field of every shape (meshes through their grid as before), the nearest static
surface and the agents' clearance, on random inputs and on the edge cases (centres, axes,
faces, inside, ties); and a swarm-sized world runs the same compiled and in numpy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import base_world, make_world, obstacles_of, random_shapes

from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.batch import ShapeBatch
from swarmplan.geometry.neighbours import agent_clearance_indexed
from swarmplan.geometry.shapes import ObstacleField
from swarmplan.runtime.compiled import COMPILED_FROM
from swarmplan.sim.obstacles import Obstacles
from swarmplan.world import load_world, parse_world

ROOT = Path(__file__).resolve().parents[1]


def _obstacles(raw):
    return obstacles_of(raw, start=(-49, -49, 49), goal=(49, 49, 49))


def _random_obstacles(rng, k=16):
    raw = random_shapes(rng, k)
    # A cube without rotation: at its centre every face is as near (ties, the first one wins).
    raw.append({"id": "cube", "shape": "box", "size": [4.0, 4.0, 4.0], "position": [3.0, -2.0, 1.0]})
    return raw


def _special_points(obstacles):
    """Each obstacle's centre, points on its axes and faces, just inside and outside."""
    pts = []
    for o in obstacles:
        R, c = o.rotation, o.position
        ext = o.size / 2 if o.shape == "box" else np.array([o.radius, o.radius, getattr(o, "height", 0) / 2])
        for local in (
            [0, 0, 0],  # the centre: zero vectors, ties between faces
            [0, 0, ext[2]],  # on the axis, at the top
            [0, 0, ext[2] + 1.0],
            [ext[0], 0, 0],  # on a face / the side
            [ext[0] - 1e-3, 0, 0],
            [ext[0], ext[1], ext[2]],  # a corner or rim
            [0.5 * ext[0], 0.5 * ext[0], 0],  # inside, equal coordinates (ties)
            [0, 0.5 * ext[1], 0.5 * ext[1]],
        ):
            pts.append(c + R @ np.asarray(local, float))
    return np.array(pts)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_field_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    obstacles = _obstacles(_random_obstacles(rng))
    ref, fast = ShapeBatch(obstacles), ShapeBatch(obstacles, compiled=True)
    pts = np.vstack([rng.uniform(-30, 30, (400, 3)), _special_points(obstacles)])
    ident = ref.identity
    assert ident.any() and not ident.all()
    for centers in (None, ref.position + rng.normal(0, 2.0, ref.position.shape)):
        d_ref, g_ref = ref.query(pts, centers)
        d, g = fast.query(pts, centers)
        assert (d_ref < 0).any() and (d_ref > 0).any()
        # The same bits, zeros' signs included (rotated bodies' products are numpy's own).
        assert d.tobytes() == d_ref.tobytes()
        assert g.tobytes() == g_ref.tobytes()


def test_compiled_field_of_the_mesh_world_equals_obstacle_field():
    """Meshes stay with their grid (numpy) in the compiled query; the primitives beside them
    are compiled."""
    world = load_world(ROOT / "worlds" / "mesh_hangar.yaml")
    obs = world.obstacles
    batch = ShapeBatch(obs, compiled=True)
    assert batch.meshes and len(batch.primitives)
    rng = np.random.default_rng(4)
    pts = rng.uniform([0, 0, 0], [240, 200, 90], (300, 3))
    centers = np.array([o.position for o in obs]) + rng.normal(size=(len(obs), 3))
    for c in (None, centers):
        d_ref, g_ref = ObstacleField(obs).query(pts, c)
        d, g = batch.query(pts, c)
        np.testing.assert_array_equal(d, d_ref)
        np.testing.assert_array_equal(g, g_ref)


def _swarm_world(n, peaks):
    agents = [
        {"id": f"a{i}", "start": [5.0 + 3.0 * i, 5.0, 20.0], "goal": [5.0 + 3.0 * i, 190.0, 20.0]}
        for i in range(n)
    ]
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [300, 200, 60]},
        agents=agents,
        obstacles=[
            {"id": "s", "shape": "sphere", "radius": 8.0, "position": [100, 100, 30]},
            {
                "id": "b",
                "shape": "box",
                "size": [20, 10, 40],
                "position": [180, 80, 20],
                "rotation": [0, 0, 30],
            },
            {"id": "c", "shape": "cylinder", "radius": 6.0, "height": 50, "position": [60, 150, 25]},
            {
                "id": "m",
                "shape": "sphere",
                "radius": 3.0,
                "position": [150, 100, 20],
                "motion": {"type": "linear", "velocity": [-2.0, 0.0, 0.0]},
            },
        ],
    )
    if peaks:
        raw["terrain"] = {"peaks": [{"center": [150, 100], "height": 15, "spread": [60, 50]}], "clearance": 5}
    return make_world(raw)


@pytest.mark.parametrize("peaks", [False, True])
def test_compiled_nearest_surface_equals_numpy(peaks):
    world = _swarm_world(COMPILED_FROM, peaks)
    obstacles = Obstacles(world, AgentParams.from_world(world))
    assert obstacles.compiled
    rng = np.random.default_rng(1)
    n = len(world.agents)
    pos = rng.uniform([0, 0, 0], [300, 200, 60], (n, 3))
    pos[0] = [100, 100, 30]  # at the sphere's centre
    pos[1] = [100, 100, 11.0]  # below the sphere: as far from it as from the ground (a tie)
    pos[2] = [60, 150, 2.0]  # on the cylinder's axis, near the ground
    q, _ = obstacles.poses(0.0)
    d, g = obstacles.distances.query(pos, q)
    idx = np.sort(rng.choice(n, n - 5, replace=False))
    idx[:3] = [0, 1, 2]
    idx = np.unique(idx)
    got = obstacles.nearest_surface(idx, pos[idx], d[idx], g[idx])
    obstacles.compiled = False
    ref = obstacles.nearest_surface(idx, pos[idx], d[idx], g[idx])
    assert (ref[0] < pos[idx, 2]).any()  # some agents are nearer an obstacle than the ground
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])


def _all_pairs_clearance(p, r):
    d = np.linalg.norm(p[:, None] - p[None], axis=-1) - (r[:, None] + r[None])
    np.fill_diagonal(d, np.inf)
    return d.min(axis=1)


@pytest.mark.parametrize("seed", range(4))
def test_compiled_clearance_equals_all_pairs(seed):
    rng = np.random.default_rng(seed)
    n = COMPILED_FROM + 50 * seed
    p = rng.uniform(0, 60, (n, 3))
    r = rng.choice([0.5, 1.0, 3.0], n)
    p[3] = p[4]  # coincident
    p[7] = p[8] = p[9]  # three at one point
    p[10] = p[11] + [r[10] + r[11], 0, 0]  # touching
    p[12] = p[13] + [0.1, 0, 0]  # overlapping
    p[20:26, 0] = 30.0  # equal x (ties in the sweep's order)
    np.testing.assert_array_equal(agent_clearance_indexed(p, r), _all_pairs_clearance(p, r))


def test_compiled_clearance_of_a_spread_swarm():
    """Agents far apart along x and a big radius among small ones (the sweep walks far)."""
    n = COMPILED_FROM + 3
    p = np.column_stack([np.arange(n) * 50.0, np.zeros(n), np.zeros(n)])
    p[-1] = [25.0, 40.0, 0.0]
    r = np.full(n, 0.5)
    r[-1] = 30.0
    np.testing.assert_array_equal(agent_clearance_indexed(p, r), _all_pairs_clearance(p, r))
    r[:] = 0.5
    np.testing.assert_array_equal(agent_clearance_indexed(p, r), _all_pairs_clearance(p, r))


def test_a_swarm_world_runs_the_same_compiled_and_in_numpy(monkeypatch):
    """The compiled path changes nothing a run does: 48 agents among rotated boxes, cylinders,
    spheres and movers, the same states and events after 150 steps."""
    import swarmplan.runtime.compiled as compiled
    from swarmplan.bench.sim import swarm_world
    from swarmplan.sim import Simulation

    raw = swarm_world(COMPILED_FROM, 8, 12, 0)
    raw["sim"]["max_time"] = 20.0

    def run() -> tuple[bytes, list, float]:
        sim = Simulation(parse_world(raw))
        sim.reset(seed=0)
        events = []
        for _ in range(150):
            events += [(e.t, e.agent, e.kind) for e in sim.step().events]
        near = min(a["min_obstacle_clearance"] or np.inf for a in sim.summary()["agents"])
        return np.concatenate([sim.state.position, sim.state.velocity]).tobytes(), events, near

    fast = run()
    assert fast[2] < 20.0  # some agents flew within the obstacles' influence
    monkeypatch.setattr(compiled, "COMPILED_FROM", 10**9)
    slow = run()
    assert fast == slow
