"""The turn-ahead guard's clearance: compiled (``sim._guard_kernel.clearances``) and numpy
(``sim.guard_clearance.guard_clearance``) give the same bits on random points, bodies of every
primitive shape (rotated or not), movers and terrain; the movers' predicted centres kept from
step to step are those of their motion at each step."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import obstacles_of
from test_distance_kernels import ROOT, _random_obstacles

from swarmplan.geometry.batch import ShapeBatch
from swarmplan.runtime.compiled import kernel_module
from swarmplan.sim.guard_clearance import MoverCentres, guard_clearance
from swarmplan.world import load_world
from swarmplan.world.motion import poses_at


def _case(seed: int):
    rng = np.random.default_rng(seed)
    obstacles = obstacles_of(_random_obstacles(rng), start=(-49, -49, 49), goal=(49, 49, 49))
    field = ShapeBatch(obstacles)
    m = len(obstacles)
    cols = rng.permutation(m)
    static, movers = np.sort(cols[: m // 2]), cols[m // 2 : m // 2 + 4]
    n, steps = 3000, 40
    points = rng.uniform(-30, 30, (n, 3))
    points[:20] = np.array([o.position for o in obstacles])[rng.integers(m, size=20)]  # centres
    radii = rng.uniform(0.5, 3.0, n)
    extra = rng.uniform(0.0, 4.0, n)
    ground = rng.uniform(-40, 10, n)
    origin = np.array([obstacles[j].position for j in movers], dtype=float)
    centers = origin[None] + rng.normal(0, 8, (steps, len(movers), 3))
    row = rng.integers(steps, size=n)
    bmin, bmax = np.array([-35.0, -32.0, -31.0]), np.array([33.0, 34.0, 30.0])
    return field, (points, radii, extra, ground, bmin, bmax, static, movers, origin, centers, row)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_guard_clearance_equals_numpy(seed: int) -> None:
    field, args = _case(seed)
    want = guard_clearance(field, *args)
    b = field.bodies
    got = kernel_module("swarmplan.sim._guard_kernel").clearances(
        *args, (b.code, b.prm, field.position, field.rotation, field.identity)
    )
    assert (want < 0).any() and (want > 0).any()
    assert not field.identity.all() and field.identity.any()
    assert got.tobytes() == want.tobytes()


def test_compiled_guard_clearance_without_bodies() -> None:
    """Bounds and ground alone (no body near): the same bits, and the exact values."""
    field, (points, radii, extra, ground, bmin, bmax, *_rest) = _case(0)
    none = np.zeros(0, dtype=np.int64)
    args = (points, radii, extra, ground, bmin, bmax, none, none, np.zeros((0, 3)), np.zeros((1, 0, 3)),
            np.zeros(len(points), dtype=np.int64))  # fmt: skip
    b = field.bodies
    got = kernel_module("swarmplan.sim._guard_kernel").clearances(
        *args, (b.code, b.prm, field.position, field.rotation, field.identity)
    )
    assert got.tobytes() == guard_clearance(field, *args).tobytes()
    inside = np.minimum(points - bmin, bmax - points).min(axis=1)
    np.testing.assert_array_equal(got, np.minimum(points[:, 2] - ground, inside) - radii)


def test_predicted_centres_are_the_movers_poses_at_each_step() -> None:
    world = load_world(ROOT / "worlds" / "fixed_wing.yaml")
    centres = MoverCentres(world)
    movers = world.moving_obstacles
    for first, last in (
        (3, 40),
        (4, 41),
        (4, 45),
        (10, 12),
        (2, 30),
        (200, 260),
        (198, 250),
        (199, 262),
        (300, 301),
    ):
        table, base = centres.at_steps(first, last)
        assert base == first and base + len(table) >= last + 1
        want = np.stack([poses_at(movers, k * world.dt)[0] for k in range(base, base + len(table))])
        assert table.tobytes() == want.tobytes()


def test_a_fixed_wing_world_logs_the_same_compiled_and_in_numpy(monkeypatch, tmp_path) -> None:
    """Worlds with fixed wings run their per-step work compiled at any size; the log (every
    state, event and summary, wall clock frozen) is the one numpy and FCL make, bit for bit,
    through turns the guard makes among pillars and two patrolling intruders."""
    import importlib.util

    import swarmplan.runtime.compiled as compiled
    from swarmplan.flight.kinematics import AgentParams
    from swarmplan.io.runner import apply_overrides, simulate
    from swarmplan.sim.obstacles import Obstacles

    spec = importlib.util.spec_from_file_location("golden", ROOT / "tests" / "golden" / "golden.py")
    golden = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(golden)
    world = apply_overrides(load_world(ROOT / "worlds" / "fixed_wing_crossing.yaml"), None, 25.0)

    assert Obstacles(world, AgentParams.from_world(world)).compiled

    def log(name: str) -> tuple[dict, int]:
        with golden.frozen_clock():
            summary = simulate(world, 0, tmp_path / f"{name}.mcap")
        guarded = sum(a["guard_steps"] for a in summary["agents"])
        return golden.describe(tmp_path / f"{name}.mcap"), guarded

    fast = log("compiled")
    assert fast[1] > 0  # the guard turned some of them
    monkeypatch.setattr(compiled, "FIXED_WINGS_COMPILED", False)
    assert not Obstacles(world, AgentParams.from_world(world)).compiled
    assert log("numpy") == fast


@pytest.mark.parametrize("seed", range(3))
def test_the_guard_in_one_pass_equals_rollouts_and_clearances(seed: int) -> None:
    """``_guard_kernel.first_safe`` and ``least_clearances`` (the rollout and the clearances in
    one pass, a manoeuvre left at its first position too close, bodies measured again only where
    they could be nearer than what is asked) answer what rolling every manoeuvre out
    (``_fixed_wing_kernel.rollouts``: the horizon and a step more for each step it settles) and
    measuring every position it flew (``clearances``) answers: the clearance where each aircraft
    is, its first manoeuvre that keeps the required clearance at every predicted position (-1:
    none), each manoeuvre's least clearance and the steps it keeps the required one, bit for bit."""
    from swarmplan.flight.lookahead import _MANOEUVRES, _TURN, _UP

    rng = np.random.default_rng(100 + seed)
    raw = _random_obstacles(rng)
    raw.append({"id": "egg", "shape": "ellipsoid", "semi_axes": [6.0, 3.0, 2.0], "position": [-8.0, 9.0, 2.0],
                "rotation": [10.0, 20.0, 30.0]})  # fmt: skip
    obstacles = obstacles_of(raw, start=(-49, -49, 49), goal=(49, 49, 49))
    field = ShapeBatch(obstacles)
    m = len(obstacles)
    cols = rng.permutation(m)
    static, movers = np.sort(cols[: m - 4]), cols[m - 4 :]
    n, steps, c = 60, 45, len(_MANOEUVRES)
    pos = rng.uniform(-30, 30, (n, 3))
    heading = rng.normal(size=(n, 3)) * [1.0, 1.0, 0.2]
    vel = heading / np.linalg.norm(heading, axis=1)[:, None] * rng.uniform(2.0, 6.0, (n, 1))
    kappa = rng.uniform(-0.05, 0.05, (n, 2))
    which = np.broadcast_to(np.arange(c), (n, c))
    up = _UP[which]
    # Climbs and dives level off at heights a few metres to tens of metres away (some reached
    # within the horizon, some not); level manoeuvres: nan.
    levels = pos[:, 2:3] + np.stack([-rng.uniform(2, 40, n), rng.uniform(2, 40, n)], axis=1)
    top = np.where(up > 0, levels[:, 1:], np.where(up < 0, levels[:, :1], np.nan))
    turn, top = np.ascontiguousarray(_TURN[which]), np.ascontiguousarray(top)
    amax, radius = rng.uniform(1, 3, n), rng.uniform(4, 15, n)
    climb = np.radians(rng.uniform(8, 20, n))
    roll = np.where(rng.random(n) < 0.3, np.inf, rng.uniform(0.3, 2.0, n))
    dt = 0.1
    radii, extra = rng.uniform(0.3, 1.5, n), rng.uniform(0.0, 2.0, n)
    required = rng.uniform(0.0, 1.0, n)
    origin = np.array([obstacles[j].position for j in movers], dtype=float)
    centers = origin[None] + np.cumsum(rng.normal(0, 0.3, (2 * steps + 5, len(movers), 3)), axis=0)
    rows = np.arange(2, 2 * steps + 3)
    bmin, bmax = np.array([-45.0, -44.0, -40.0]), np.array([44.0, 45.0, 41.0])
    b = field.bodies
    bodies = (b.code, b.prm, field.position, field.rotation, field.identity)
    gk = kernel_module("swarmplan.sim._guard_kernel")
    fk = kernel_module("swarmplan.flight._fixed_wing_kernel")

    flight = (pos, vel, kappa, turn, top, amax, radius, climb, roll)
    scene = (bmin, bmax, static, movers, origin, centers, bodies)
    here, first = gk.first_safe((*flight, dt), rows, radii, extra, required, scene)

    path, used = fk.rollouts(*flight, steps, dt)
    assert path.shape == (n, c, 2 * steps, 3)
    assert (used >= steps).all() and (used <= 2 * steps).all()
    assert (used > steps).any() and (used == steps).any()
    rep = lambda a: np.repeat(a, c * 2 * steps)  # noqa: E731
    clear = gk.clearances(
        path.reshape(-1, 3), rep(radii), rep(extra), np.zeros(n * c * 2 * steps), bmin, bmax, static, movers,
        origin, centers, np.tile(rows[1:], n * c), bodies,
    ).reshape(n, c, 2 * steps)  # fmt: skip
    flown = np.arange(2 * steps) < used[..., None]
    least_flown = np.where(flown, clear, np.inf).min(axis=2)
    safe = least_flown >= required[:, None]
    want_here = gk.clearances(pos, radii, extra, np.zeros(n), bmin, bmax, static, movers, origin, centers,
                              np.full(n, rows[0]), bodies)  # fmt: skip
    assert here.tobytes() == want_here.tobytes()
    np.testing.assert_array_equal(first, np.where(safe.any(axis=1), np.argmax(safe, axis=1), -1))
    least, kept = gk.least_clearances((*flight, dt), rows[1:], radii, extra, required, scene)
    assert least.tobytes() == least_flown.tobytes()
    short = (clear < required[:, None, None]) & flown
    np.testing.assert_array_equal(kept, np.where(short.any(axis=2), np.argmax(short, axis=2), used))
    # Every kind of answer occurs: none safe, the first, a later one.
    assert (first == -1).any() and (first == 0).any() and (first > 0).any(), np.bincount(first + 1)
