"""The compiled potential field (the product's one implementation) equals the numpy reference
(tests/apf_reference.py, every pair, array by array) to rounding on random swarms, edge cases
included: coincident agents, equal velocities, agents inside obstacles or at their surface, at
their goal, beside the bounds, on terrain, head-on with movers, crowds of bodies, parked
agents, several agent kinds and fixed wings among them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from apf_reference import agent_term, reference_forces
from helpers import base_world, make_world

from swarmplan.flight.apf import ApfField, FieldInputs, Flyers, Swarm, current_reach, stopping_reach
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.shapes import ObstacleField

N = 80


def _world(peaks: bool, gains: dict | None = None):
    agents = [
        {"id": f"a{i}", "start": [10.0 + 2.5 * i, 10.0, 30.0], "goal": [10.0 + 2.5 * i, 280.0, 30.0]}
        for i in range(N)
    ]
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": [300, 300, 80]},
        agents=agents,
        agent_defaults={"radius": 1.0, "separation": [4, 4, 2], "min_altitude": 3.0},
        obstacles=[
            {"id": "s", "shape": "sphere", "radius": 8.0, "position": [100, 150, 30]},
            {
                "id": "b",
                "shape": "box",
                "size": [20, 10, 40],
                "position": [180, 120, 20],
                "rotation": [0, 0, 30],
            },
            {"id": "c", "shape": "cylinder", "radius": 6.0, "height": 50, "position": [60, 220, 25]},
            {"id": "k", "shape": "capsule", "radius": 4.0, "height": 20, "position": [230, 220, 30]},
            {
                "id": "m1",
                "shape": "sphere",
                "radius": 5.0,
                "position": [150, 60, 30],
                "motion": {"type": "linear", "velocity": [3.0, 1.0, 0.0]},
            },
            {
                "id": "m2",
                "shape": "sphere",
                "radius": 3.0,
                "position": [120, 200, 40],
                "motion": {"type": "linear", "velocity": [-2.0, 0.0, 0.5]},
            },
        ],
        planner={"apf": {"influence": 20.0, **(gains or {})}},
    )
    # A crowd of small bodies, static and moving: numpy sums more than 8 potentials pairwise.
    for k in range(10):
        raw["obstacles"].append(
            {
                "id": f"p{k}",
                "shape": "sphere",
                "radius": 2.0,
                "position": [140 + 8 * (k % 5), 240 + 10 * (k // 5), 30],
            }
        )
    for k in range(9):
        raw["obstacles"].append(
            {
                "id": f"q{k}",
                "shape": "sphere",
                "radius": 1.5,
                "position": [136 + 6 * k, 270, 35],
                "motion": {"type": "linear", "velocity": [0.0, -1.0, 0.2 * (k % 3)]},
            }
        )
    if peaks:
        raw["terrain"] = {"peaks": [{"center": [150, 150], "height": 25, "spread": [60, 50]}], "clearance": 5}
    return make_world(raw)


def _inputs(world, seed: int):
    """Random positions and velocities with deliberate edge cases, and the field at them."""
    rng = np.random.default_rng(seed)
    params = AgentParams.from_world(world)
    # Several agent kinds (radius, separation).
    params = dataclasses.replace(
        params,
        radius=rng.choice([0.5, 1.0, 1.5], N),
        separation=rng.choice([2.0, 4.0, 6.0], (N, 3)),
        min_altitude=rng.choice([2.0, 3.0, 10.0], N),
        speed_cruise=rng.choice([4.0, 8.0, 10.0], N),
        fixed_wing=rng.random(N) < 0.2,
        field_scale=rng.choice([1.0, 0.5, 0.05], N),  # each agent's field at its own scale
    )
    pos = rng.uniform([0.5, 0.5, 0.5], [299.5, 299.5, 79.5], (N, 3))
    goal = rng.uniform([5, 5, 5], [295, 295, 75], (N, 3))
    # Clusters: dense groups well inside each other's separation.
    pos[:30] = pos[0] + rng.normal(0, 3.0, (30, 3))
    pos[30:40] = np.array([156, 255, 32]) + rng.normal(0, 8.0, (10, 3))  # among the crowd of bodies
    goal[30:40] = pos[30:40] + rng.normal(0, 6.0, (10, 3))  # with goals near (the companion term)
    pos[40:50] = np.array([100, 150, 30]) + rng.normal(0, 9.0, (10, 3))  # in and around the sphere
    vel = rng.normal(0, 5.0, (N, 3))
    pos[5] = pos[4]  # coincident agents, also with equal velocities
    vel[5] = vel[4]
    pos[6] = pos[7]  # coincident, different velocities
    vel[8] = vel[9]  # equal velocities apart
    pos[10] = [100, 150, 30]  # at the sphere's centre
    pos[11] = [100, 150, 38.0 + params.radius[11]]  # on its surface (rho = 0)
    pos[12] = [180, 120, 20]  # at the box's centre
    pos[13] = [60, 220, 10]  # on the cylinder's axis
    pos[14] = [1.0, 150, params.radius[14]]  # at the low x face and on the ground
    pos[15] = [299.0, 299.0, 79.9]  # in the high corner
    pos[16] = [150.0 - 9.0, 60.0, 30.0]  # head-on with mover m1 along its path
    vel[16] = [3.0 + 6.0, 1.0 + 2.0, 0.0]
    goal[20] = pos[20]  # at the goal
    goal[21] = pos[21] + [3.0, 0, 0]  # inside the quadratic well
    pos[22], goal[22] = [200, 40, 6.0], [203, 40, 1.0]  # a low goal near (the goal factor scales the ground)
    pos[23], goal[23] = [200, 60, 6.0], [203, 60, 11.0]  # a goal near but above the floor
    pos[24], goal[24] = [100, 164, 30], [104, 160, 30]  # beside the sphere, goal too (companion term)
    pos[25], goal[25] = [119, 193, 41], [116, 195, 40]  # beside the mover m2 (at t), goal too
    t = 1.7
    from swarmplan.world.motion import poses_at

    q, qv = poses_at(world.obstacles, t)
    moving = np.array([o.moving for o in world.obstacles], bool)
    d, g = ObstacleField(world.obstacles).query(pos, q)
    radii = np.array([o.bounding_radius for o in world.obstacles])
    return params, pos, vel, goal, (d, g, qv * moving[:, None], moving, radii, q), rng


#: Relative tolerance of the compiled field against the reference (sums in another order).
RTOL = 1e-9


def _close(got, ref):
    scale = max(1.0, float(np.abs(ref).max()))
    np.testing.assert_allclose(got, ref, rtol=RTOL, atol=RTOL * scale)


@pytest.mark.parametrize("peaks", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_compiled_equals_reference_on_random_swarms(peaks, seed):
    world = _world(peaks, {"goal_power": (2.0, 1.5, 3.0)[seed]})
    params, pos, vel, goal, f, rng = _inputs(world, seed)
    field = ApfField(world, params)
    for case in range(4):
        # Every agent, then a subset (as when some have arrived), with targets and scales.
        idx = np.arange(N) if case == 0 else np.sort(rng.choice(N, N - 17, replace=False))
        target = None if case < 2 else goal[idx] + rng.normal(0, 5.0, (len(idx), 3))
        if case == 3:
            target[::3] = goal[idx][::3]  # some targets are the goal itself
        scale = None if case < 3 else rng.uniform(0.2, 1.0, len(idx))
        inputs = FieldInputs(f[0][idx], f[1][idx], *f[2:])
        parked = None if case < 2 else rng.random(N) < 0.3  # agents that no longer fly
        flyers = Flyers(idx, pos[idx], vel[idx], goal[idx], target, scale)
        to_go = None if case < 2 else np.linalg.norm(goal - pos, axis=1)  # priority near goals
        swarm = Swarm(pos, vel, parked, to_go)
        ref = reference_forces(world, params, flyers, inputs, swarm)
        got = field.forces(flyers, inputs, swarm)
        assert np.all(np.isfinite(ref))
        assert (
            np.linalg.norm(agent_term(world, params, world.planner_config.apf, flyers, swarm), axis=1) > 0
        ).sum() > 20
        _close(got, ref)


def _no_obstacles(n: int) -> FieldInputs:
    return FieldInputs(
        np.zeros((n, 0)),
        np.zeros((n, 0, 3)),
        np.zeros((0, 3)),
        np.zeros(0, bool),
        np.zeros(0),
        np.zeros((0, 3)),
    )


def test_pairs_at_the_edge_of_the_reach():
    """The compiled agent term dismisses a pair when the closest approach of the centres within
    the horizon is beyond the reach. Pairs straddling that edge, with the closest approach
    inside the horizon and at its end: the ones just inside contribute, the ones just outside
    do not, and the compiled field equals the reference on all of them."""
    world = _world(False)
    gains = world.planner_config.apf
    params = AgentParams.from_world(world)
    # One kind, semi-axes (6, 6, 4): along y the scaled and unscaled distances agree, so the
    # bound is tight there: the predicted term starts at |dy| = 6 e0, e0 = 1 + range / 6 with
    # the range both stopping reaches (22 m), capped at the influence (20 m).
    reach = stopping_reach(params, world.dt)[0]
    edge = 6.0 + min(2.0 * reach, gains.influence)
    assert edge == 26.0
    assert current_reach(params, stopping_reach(params, world.dt), gains.influence) == pytest.approx(edge)
    horizon = gains.horizon
    # At cruise (10 m/s) each agent's braking from its speed is its whole stopping reach, so
    # the pair's range is the full one the bound is built from (slower pairs reach less).
    v = 10.0
    pairs = []  # (x gap, lateral offset, closing speed per agent)
    for rel in (1 - 1e-6, 1 + 1e-6, 1 - 1e-12, 1 + 1e-12):
        pairs.append((v * horizon, edge * rel, v))  # closest approach at half the horizon
        # Still approaching at the horizon: closest at its end, gap 10 m along x then.
        gap_end = 10.0
        pairs.append((gap_end + 2 * v * horizon, np.sqrt((edge * rel) ** 2 - gap_end**2), v))
    pos, vel = [], []
    for k, (gap, lateral, v) in enumerate(pairs):
        row = 100.0 * k  # rows far apart: agents of different rows never interact
        pos += [[0.0, row, 30.0], [gap, row + lateral, 30.0]]
        vel += [[v, 0.0, 0.0], [-v, 0.0, 0.0]]
    n = len(pos)
    pos, vel = np.array(pos), np.array(vel)
    sub = dataclasses.replace(
        params,
        **{k: getattr(params, k)[:n] for k in ("radius", "separation", "min_altitude", "speed_cruise",
                                               "max_accel", "fixed_wing", "min_turn_radius")},
    )  # fmt: skip
    goal = pos + [0.0, 0.0, 0.0]
    idx = np.arange(n)
    flyers, swarm = Flyers(idx, pos, vel, goal), Swarm(pos, vel)
    term = agent_term(world, sub, gains, flyers, swarm)
    inside = np.abs(term[0::2]).sum(axis=1) > 0
    np.testing.assert_array_equal(inside, [True, True, False, False, True, True, False, False])
    got = ApfField(world, sub).forces(flyers, _no_obstacles(n), swarm)
    _close(got, reference_forces(world, sub, flyers, _no_obstacles(n), swarm))


def test_range_of_agents_comes_from_their_stopping_distance():
    """Two agents along an axis, both flying across it (no closing speed: only the current
    term acts), repel each other out to the separation semi-axis plus both braking distances
    from their speeds (v dt + v^2 / 2a each), at most both stopping reaches from cruise, and
    not a metre beyond (the influence distance, longer here, only caps it); at rest, only
    inside the separation ellipsoid."""
    world = _world(False, {"influence": 100.0})
    params = AgentParams.from_world(world)
    reach = 10.0 * world.dt + 10.0**2 / (2 * 5.0)  # cruise 10 m/s, 5 m/s^2
    np.testing.assert_allclose(stopping_reach(params, world.dt), reach)
    field = ApfField(world, params)
    for speed, own in ((10.0, reach), (12.0, reach), (4.0, 0.4 + 1.6), (0.0, 0.0)):
        edge = 6.0 + 2.0 * own  # semi-axis along y: separation 4 + radii 2
        vel = np.array([[speed, 0.0, 0.0], [speed, 0.0, 0.0]])
        for gap, repels in ((edge - 1e-3, True), (edge + 1e-3, False)):
            pos = np.array([[150.0, 100.0, 40.0], [150.0, 100.0 + gap, 40.0]])
            flyers = Flyers(np.array([0]), pos[:1], vel[:1], pos[:1])  # at its goal: no pull
            f = field.forces(flyers, _no_obstacles(1), Swarm(pos, vel))
            assert (f[0, 1] < 0) == repels and (f[0, 1] == 0) != repels, (speed, gap)
