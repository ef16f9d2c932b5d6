"""The compiled swept checks (``geometry.swept_kernels``) decide exactly what FCL decides.

Tangent sweeps are built with a known exact distance ``r + delta`` to a primitive (through a
supporting plane at a surface point: faces, edges, corners, rims, caps), so the truth of each
check is known. The kernel must never decide against the truth, must decide every pair
outside its band, and FCL must agree with the truth outside the band (the premise that lets
the kernel stand in for it). A kernel whose bound is moved by twice the band fails the same
check. Then the public paths: ``first_hits`` against ``first_hits_fcl`` (the previous code,
FCL on every candidate) on cluttered worlds with thin bodies, fast movers, zero-length and
grazing steps, meshes; the braking margin's compiled bisection against the FCL bisection."""

from __future__ import annotations

import fcl
import numpy as np
import pytest
from helpers import base_world, make_world, without_guide

from swarmplan.geometry import _shape_kernel as S
from swarmplan.geometry import swept_kernels as K
from swarmplan.geometry.collision import CollisionWorld, _align_z, first_hits, first_hits_fcl
from swarmplan.runtime.compiled import read_only
from swarmplan.world.motion import poses_at


@pytest.fixture(autouse=True)
def _compiled(monkeypatch):
    """The compiled path under test, in worlds of any size (by default only swarm-sized
    worlds take it: ``runtime.compiled.use_compiled_checks``)."""
    monkeypatch.setattr("swarmplan.runtime.compiled.CHECKS_COMPILED_FROM", 0)


SHAPES = [
    (S.SPHERE, (2.0, 0.0, 0.0)),
    (S.SPHERE, (0.02, 0.0, 0.0)),
    (S.BOX, (0.025, 3.0, 4.0)),  # a 5 cm wall
    (S.BOX, (1.0, 1.5, 0.7)),
    (S.CYLINDER, (2.0, 5.0, 0.0)),
    (S.CYLINDER, (0.03, 4.0, 0.0)),  # a thin pole
    (S.CAPSULE, (0.5, 2.0, 0.0)),
    (S.CAPSULE, (1.0, 0.0, 0.0)),  # no straight section
]


def surface_point(rng: np.random.Generator, code: int, dims) -> tuple[np.ndarray, np.ndarray]:
    """A point on the body's surface (local frame) and an outward unit normal there (for edges,
    corners and rims any normal of the cone)."""
    d0, d1, d2 = dims
    if code == S.SPHERE:
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        return d0 * n, n
    if code == S.BOX:
        h = np.array([d0, d1, d2])
        sign = rng.choice([-1.0, 1.0], 3)
        x = rng.uniform(-h, h)
        n = np.zeros(3)
        for a in rng.permutation(3)[: rng.integers(1, 4)]:  # face, edge or corner
            x[a] = sign[a] * h[a]
            n[a] = sign[a] * rng.uniform(0.1, 1.0)
        return x, n / np.linalg.norm(n)
    if code == S.CYLINDER:
        phi = rng.uniform(0, 2 * np.pi)
        radial = np.array([np.cos(phi), np.sin(phi), 0.0])
        top = np.array([0.0, 0.0, rng.choice([-1.0, 1.0])])
        kind = rng.integers(3)
        if kind == 0:
            return d0 * radial + [0, 0, rng.uniform(-d1, d1)], radial
        if kind == 1:
            return rng.uniform(0, d0) * radial + d1 * top, top
        n = rng.uniform(0.1, 1) * radial + rng.uniform(0.1, 1) * top
        return d0 * radial + d1 * top, n / np.linalg.norm(n)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    if rng.random() < 0.5 and d1 > 0:  # the straight section
        n[2] = 0.0
        n /= np.linalg.norm(n)
        return np.array([0, 0, rng.uniform(-d1, d1)]) + d0 * n, n
    return np.array([0, 0, np.sign(n[2]) * d1]) + d0 * n, n


def tangent_sweep(rng, code, dims, r, delta, length):
    """A local-frame segment at exact distance ``r + delta`` from the body: it lies in the
    supporting plane offset by ``r + delta`` along the normal and passes through the offset
    surface point (anywhere along the segment, often at an end)."""
    x, n = surface_point(rng, code, dims)
    t = np.cross(n, rng.normal(size=3))
    t /= np.linalg.norm(t)
    c = x + n * (r + delta)
    s = rng.uniform(0, 1) if rng.random() < 0.7 else rng.choice([0.0, 1.0])
    return c - s * length * t, c + (1 - s) * length * t


def fcl_touches(code, dims, a, b, r) -> bool:
    """FCL's answer, as ``CollisionWorld`` builds it (a capsule, a sphere for a zero-length step)."""
    geometry = {
        S.SPHERE: lambda: fcl.Sphere(dims[0]),
        S.BOX: lambda: fcl.Box(*(2 * np.asarray(dims))),
        S.CYLINDER: lambda: fcl.Cylinder(dims[0], 2 * dims[1]),
        S.CAPSULE: lambda: fcl.Capsule(dims[0], 2 * dims[1]),
    }[code]()
    body = fcl.CollisionObject(geometry, fcl.Transform())
    d = b - a
    length = float(np.linalg.norm(d))
    if length < 1e-9:
        sweep = fcl.CollisionObject(fcl.Sphere(r), fcl.Transform((a + b) / 2))
    else:
        sweep = fcl.CollisionObject(fcl.Capsule(r, length), fcl.Transform(_align_z(d / length), (a + b) / 2))
    return fcl.collide(sweep, body, fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def _cases(seed: int, deltas, per: int = 25):
    rng = np.random.default_rng(seed)
    for code, dims in SHAPES:
        for delta in deltas:
            for sign in (1.0, -1.0):
                for _ in range(per):
                    r = float(rng.uniform(0.1, 1.5))
                    length = float(rng.choice([0.0, 1e-12, rng.uniform(0, 1), rng.uniform(1, 40)]))
                    a, b = tangent_sweep(rng, code, dims, r, sign * delta, length)
                    yield code, dims, a, b, r, sign * delta


DELTAS = (3e-2, 1e-3, 2e-4, 1.01 * K.BAND, K.BAND, 1e-5, 1e-7, 0.0)


def wrong_decisions(classify, seed: int = 0) -> tuple[int, int, int]:
    """(decided against the truth, decided, undecided although clear of the band by 1 %)."""
    wrong = decided = lazy = 0
    for code, dims, a, b, r, delta in _cases(seed, DELTAS):
        c = classify(*a, *b, r, code, *dims)
        if c == K.UNDECIDED:
            lazy += abs(delta) > 1.01 * K.BAND * 1.001
            continue
        decided += 1
        # delta == 0 is contact (FCL's test is <=); either answer within the band is the band's.
        truth = delta <= 0
        wrong += (c == K.HIT) != truth
    return wrong, decided, lazy


def test_kernel_decides_every_tangent_sweep_outside_the_band_and_never_wrongly():
    wrong, decided, lazy = wrong_decisions(K.classify)
    assert wrong == 0
    assert lazy == 0
    assert decided > 0.4 * len(SHAPES) * len(DELTAS) * 2 * 25


def test_a_kernel_with_a_broken_bound_is_caught():
    """The check above can fail: a kernel believing contact starts 2 bands farther out (or
    nearer) decides tangent sweeps wrongly."""

    def too_eager(ax, ay, az, bx, by, bz, r, code, d0, d1, d2):
        return K.classify(ax, ay, az, bx, by, bz, r + 2 * K.BAND, code, d0, d1, d2)

    def too_lax(ax, ay, az, bx, by, bz, r, code, d0, d1, d2):
        return K.classify(ax, ay, az, bx, by, bz, r - 2 * K.BAND, code, d0, d1, d2)

    assert wrong_decisions(too_eager)[0] > 10
    assert wrong_decisions(too_lax)[0] > 10


def test_fcl_agrees_with_exact_geometry_outside_the_band():
    """The premise: where the kernel decides (|delta| > BAND), FCL gives the same answer."""
    disagree = 0
    for code, dims, a, b, r, delta in _cases(1, (1e-3, 1.01 * K.BAND, 0.1 * K.BAND), per=15):
        disagree += fcl_touches(code, dims, a, b, r) != (delta < 0)
    assert disagree == 0


# ----------------------------------------------------------------------------- public paths


def _world(seed: int, tmp_path=None):
    """Cluttered: rotated primitives incl. 5 cm walls and 3 cm poles, fast movers, a mesh."""
    rng = np.random.default_rng(seed)
    obstacles = []
    for k in range(28):
        c = [float(rng.uniform(10, 90)), float(rng.uniform(10, 90)), float(rng.uniform(5, 45))]
        shape = ["sphere", "box", "cylinder", "capsule"][k % 4]
        o = {"id": f"o{k}", "shape": shape, "position": c, "rotation": rng.uniform(0, 90, 3).tolist()}
        thin = k % 7 == 0
        if shape == "sphere":
            o["radius"] = float(rng.uniform(1, 4))
        elif shape == "box":
            o["size"] = [0.05, *rng.uniform(4, 12, 2).tolist()] if thin else rng.uniform(1, 8, 3).tolist()
        else:
            o["radius"] = 0.03 if thin else float(rng.uniform(0.5, 3))
            o["height"] = float(rng.uniform(2, 10))
        obstacles.append(o)
    if tmp_path is not None:
        obstacles.append({"id": "mesh", "shape": "mesh", "file": "cube.stl", "position": [50.0, 50.0, 25.0]})
    for k in range(8):
        obstacles.append(
            {
                "id": f"m{k}",
                "shape": ["sphere", "box"][k % 2],
                **({"radius": 2.0} if k % 2 == 0 else {"size": [3.0, 0.1, 3.0]}),
                "position": rng.uniform(20, 80, 3).tolist(),
                "rotation": rng.uniform(0, 90, 3).tolist(),
                "motion": {"type": "linear", "velocity": rng.normal(0, 15, 3).tolist()},  # fast
            }
        )
    return make_world(base_world(obstacles=obstacles), base_dir=tmp_path or ".")


def _grazing_steps(rng, cw: CollisionWorld, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps tangent to a random static primitive at +-1e-6 .. 1e-2 m (world frame)."""
    p0, p1, radii = [], [], []
    code, rot, dims = cw._static_table
    while len(p0) < n:
        k = int(rng.integers(len(cw.static)))
        if code[k] == K.MESH:
            continue
        r = float(rng.uniform(0.3, 1.5))
        delta = float(rng.choice([1e-6, 1e-4, 1e-3, 1e-2]) * rng.choice([-1.0, 1.0]))
        length = float(rng.choice([0.0, rng.uniform(0, 6)]))
        a, b = tangent_sweep(rng, int(code[k]), dims[k], r, delta, length)
        c = cw.static[k].position
        p0.append(rot[k] @ a + c)
        p1.append(rot[k] @ b + c)
        radii.append(r)
    return np.array(p0), np.array(p1), np.array(radii)


@pytest.fixture
def mesh_dir(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(2.0, 2.0, 2.0)).export(tmp_path / "cube.stl")
    return tmp_path


@pytest.mark.parametrize("seed", range(3))
def test_first_hits_equals_fcl_on_cluttered_worlds(seed, mesh_dir, monkeypatch):
    import swarmplan.geometry.collision as collision

    w = _world(seed, mesh_dir)
    cw = CollisionWorld(w)
    mv = np.array([o.moving for o in w.obstacles])
    rng = np.random.default_rng(seed)
    fcl_rows = []
    reference = collision.first_hits_fcl

    def counting(cw_, p0, *a):
        fcl_rows.append(len(p0))
        return reference(cw_, p0, *a)

    monkeypatch.setattr(collision, "first_hits_fcl", counting)
    hits = 0
    for t in range(12):
        q0, q1 = poses_at(w.obstacles, 0.1 * t)[0][mv], poses_at(w.obstacles, 0.1 * t + 0.1)[0][mv]
        n = 200
        p0 = rng.uniform(5, 95, (n, 3))
        p0[:, 2] = rng.uniform(1.5, 48, n)
        step = rng.normal(size=(n, 3)) * rng.choice([0.0, 0.5, 2.0, 20.0], n)[:, None]  # incl. zero, fast
        radii = rng.uniform(0.3, 1.5, n)
        g0, g1, gr = _grazing_steps(rng, cw, 60)
        p0, p1, radii = np.vstack([p0, g0]), np.vstack([p0 + step, g1]), np.concatenate([radii, gr])
        got = first_hits(cw, p0, p1, radii, q0, q1)
        want = reference(cw, p0, p1, radii, q0, q1)
        assert got == want
        hits += sum(h is not None for h in want)
    assert hits > 100
    assert sum(fcl_rows) > 0  # the band and the mesh did go to FCL


def test_thin_wall_is_hit_by_a_long_step_through_the_kernel():
    c = np.array([50.0, 50.0, 25.0])
    wall = {"id": "wall", "shape": "box", "size": [0.05, 10, 10], "position": c.tolist()}
    wall["rotation"] = [0, 0, 30]
    cw = CollisionWorld(make_world(base_world(obstacles=[wall])))
    u = np.array([np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0])
    empty = np.zeros((0, 3))
    p0 = np.array([c - 9 * u, c - 9 * u, c + [0, 0, 5.09]])
    p1 = np.array([c + 9 * u, c - 0.2 * u, c + [0, 0, 5.09]])
    assert first_hits(cw, p0, p1, np.array([0.1, 0.1, 0.1]), empty, empty) == ["wall", None, "wall"]


def test_braking_bisection_equals_the_fcl_bisection():
    """``SafetyFilter._free_distances`` (compiled bisection) against the same bisection with
    FCL deciding every check, on random probes, many of them headed at bodies."""
    from swarmplan.sim import Simulation

    w = _world(3)
    sim = Simulation(w)
    sim.reset(seed=0)
    safety, cw = sim.safety, sim.obstacles.collision
    mv = sim.obstacles.moving_mask
    rng = np.random.default_rng(3)
    q0, q1 = sim.obstacles.poses(0.0)[0], sim.obstacles.poses(0.1)[0]
    start = rng.uniform(5, 95, (300, 3))
    start[:, 2] = rng.uniform(2, 48, 300)
    target = np.array([o.position for o in w.obstacles])[rng.integers(len(w.obstacles), size=300)]
    u = np.where(rng.random((300, 1)) < 0.7, target - start, rng.normal(size=(300, 3)))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    reach = rng.uniform(0.05, 30.0, 300)
    radii = rng.uniform(0.5, 1.5, 300)
    rows, free = safety._free_distances(start, u, reach, radii, q0, q1)

    def touches(length, sel):
        ends = start[sel] + u[sel] * length[:, None]
        hits = first_hits_fcl(cw, start[sel], ends, radii[sel], q0[mv], q1[mv])
        return np.array([h is not None for h in hits], dtype=bool)

    hit = np.flatnonzero(touches(reach, np.arange(300)))
    lo, hi = np.zeros(len(hit)), reach[hit].copy()
    for _ in range(6):
        mid = 0.5 * (lo + hi)
        h = touches(mid, hit)
        hi, lo = np.where(h, mid, hi), np.where(h, lo, mid)
    assert len(hit) > 50
    np.testing.assert_array_equal(rows, hit)
    np.testing.assert_array_equal(free, lo)


def test_compiled_arrivals_equal_the_numpy_test():
    """``swept_kernels.arrivals`` (used by ``sim.contacts.arrivals``) picks the agents and
    closest approaches the numpy expression does, incl. distances and speeds on the limit."""
    from swarmplan.geometry.collision import segment_segment_min_distance
    from swarmplan.geometry.vec3 import norm3

    rng = np.random.default_rng(5)
    for _ in range(50):
        n = 120
        goal = rng.uniform(0, 50, (n, 3))
        pos0 = goal + rng.normal(0, 3, (n, 3))
        pos1 = pos0 + rng.normal(0, 1, (n, 3)) * (rng.random((n, 1)) < 0.9)
        vel1 = rng.normal(0, 0.3, (n, 3))
        active = rng.random(n) < 0.8
        stop = np.where(rng.random(n) < 0.2, np.inf, 0.4)
        d = segment_segment_min_distance(pos0, pos1, goal, goal)
        tol = float(np.sort(d)[n // 3])  # one agent exactly on the tolerance
        stop[:5] = norm3(vel1[:5]) / (1.0 + 1e-9)  # speeds on the limit
        flying = np.flatnonzero(active)
        keep = (d[flying] <= tol) & (norm3(vel1[flying]) <= stop[flying] * (1.0 + 1e-9))
        rows, dist = K.arrivals(pos0, pos1, goal, vel1, active, read_only(stop), tol)  # as contacts passes it
        np.testing.assert_array_equal(rows, flying[keep])
        np.testing.assert_array_equal(dist, d[flying][keep])


def test_the_world_chooses_the_path_not_the_process():
    """A 16-agent world runs its steps on the reference paths (no numba load: its start-up stays
    short); a 64-agent world runs them compiled from its first step; and a 16-agent world run
    after it, in the same process with the kernels loaded, still calls none of them."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from swarmplan.bench.sim import swarm_world\n"
        "from swarmplan.sim import Simulation\n"
        "from swarmplan.world import parse_world\n"
        "def run(n, steps):\n"
        "    s = Simulation(parse_world(swarm_world(n, 4, 8)))\n"
        "    s.reset(seed=0)\n"
        "    for _ in range(steps):\n"
        "        s.step()\n"
        "run(16, 2)\n"
        "print('swarmplan.geometry.swept_kernels' in sys.modules)\n"
        "run(64, 1)\n"
        "K = sys.modules['swarmplan.geometry.swept_kernels']\n"
        "print(K is not None)\n"
        "def refuse(*args, **kwargs):\n"
        "    raise RuntimeError('a compiled swept check ran in a 16-agent world')\n"
        "for name in ('sweep_many', 'free_distances', 'agent_contacts', 'separation_keys', 'arrivals'):\n"
        "    setattr(K, name, refuse)\n"
        "run(16, 30)\n"
        "print('reference')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "True", "reference"]


def test_reference_and_compiled_runs_are_identical(monkeypatch):
    """A whole 24-agent run with every swept check compiled gives the same states and events as
    its default (every check on its reference path: numpy and FCL)."""
    from swarmplan.bench.sim import swarm_world
    from swarmplan.runtime import compiled as choice
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    def run() -> tuple[list, np.ndarray]:
        # Layout 2: a stuck agent, left to the field, and arrivals within the 400 steps
        # (layouts 0, 1, 3 and 4 have no event in the first 150).
        sim = Simulation(parse_world(swarm_world(24, 8, 12, 2)))
        sim.reset(seed=1)
        events = []
        for _ in range(400):
            events += [e.to_json() for e in sim.step().events]
        return events, sim.state.position.copy()

    compiled = run()  # the fixture: compiled checks at any size
    monkeypatch.setattr(choice, "CHECKS_COMPILED_FROM", choice.COMPILED_FROM)
    assert not choice.use_compiled_checks(24)
    reference = run()
    assert len(compiled[0]) > 0
    assert compiled[0] == reference[0]
    np.testing.assert_array_equal(compiled[1], reference[1])


def test_a_crowded_run_is_identical_on_both_paths(monkeypatch):
    """A 24-agent antipodal swap with wide separation ellipsoids (near misses, arrivals, escapes,
    smoothing and timeouts all happen) steps to the same bits on both paths: every step's
    positions, velocities and modes and every event, compiled checks against the reference ones."""
    from swarmplan.bench.sim import swap_world
    from swarmplan.runtime import compiled as choice
    from swarmplan.sim import Simulation
    from swarmplan.world import parse_world

    # World seed 1: with the agents' range from their current speeds, seed 0's crowd no longer
    # stalls long enough for an escape; seed 1's still has every kind of event.
    raw = swap_world(24, 1, 1, 20.0)
    raw["agent_defaults"]["separation"] = [10, 10, 5]

    def run() -> tuple[list, list]:
        sim = Simulation(without_guide(parse_world(raw)))  # the bare field: its escapes are compared
        sim.reset(seed=1)
        events, states = [], []
        while True:
            result = sim.step()
            events += [e.to_json() for e in result.events]
            s = sim.state
            states.append((s.position.tobytes(), s.velocity.tobytes(), s.mode.tolist()))
            if result.terminated or result.truncated:
                return events, states

    compiled = run()  # the fixture: compiled checks at any size
    monkeypatch.setattr(choice, "CHECKS_COMPILED_FROM", choice.COMPILED_FROM)
    assert not choice.use_compiled_checks(24)
    reference = run()
    kinds = {e["kind"] for e in compiled[0]}
    assert {"near_miss", "arrived", "escape_start", "timeout"} <= kinds
    assert compiled[0] == reference[0]
    assert len(compiled[1]) == len(reference[1]) == 200
    differ = [k for k, (a, b) in enumerate(zip(compiled[1], reference[1], strict=True)) if a != b]
    assert differ == [], f"the paths part at step {differ[:1]}"
