"""AFSA and IAFSA (paper 002): operators on simple cases and a sanity comparison with random search."""

from pathlib import Path

import numpy as np
import pytest

from swarmplan.optimizers import make
from swarmplan.optimizers.base import Problem
from swarmplan.optimizers.fish_swarm import (
    best_in_view,
    in_view,
    neighbours,
    refractive_opposite,
    swarm_centres,
)

LOWER, UPPER = -5.12 * np.ones(10), 5.12 * np.ones(10)
SEEDS = (0, 1, 2)


def sphere(X):
    return np.sum(X**2, axis=1)


def test_refractive_opposite_formula():
    a, b = np.array([-2.0, 0.0]), np.array([4.0, 10.0])
    X = np.array([[-2.0, 0.0], [1.0, 5.0], [3.0, 9.0]])
    # chi = 1 is the plain opposite a + b - x
    np.testing.assert_allclose(refractive_opposite(X, a, b, 1.0), a + b - X)
    # eq 26: reflection through the centre, stretched by 1 / chi
    chi = 0.95
    np.testing.assert_allclose(refractive_opposite(X, a, b, chi), (a + b) / 2 - (X - (a + b) / 2) / chi)


def test_rol_initialisation_keeps_best_of_points_and_their_refractive_opposites():
    batches = []

    def cost(X):
        batches.append(X.copy())
        return sphere(X - 1.0)

    opt = make("iafsa")
    n = opt.population
    lower, upper = -np.ones(3), 3.0 * np.ones(3)
    opt.minimize(cost, lower, upper, max_evals=2 * n, seed=0)
    first = batches[0]
    assert first.shape == (2 * n, 3)  # P1 and P1* evaluated as one batch
    P1, P1s = first[:n], first[n:]
    expected = np.clip(refractive_opposite(P1, lower, upper, 0.95), lower, upper)
    np.testing.assert_allclose(P1s, expected)


def test_rol_population_is_the_best_half():
    batches = []

    def cost(X):
        batches.append(X.copy())
        return sphere(X)

    opt = make("iafsa")
    problem = Problem(cost, LOWER, UPPER, 10_000)
    state = opt.setup(problem, np.random.default_rng(1), None)
    assert problem.evaluations == 2 * opt.population
    np.testing.assert_allclose(np.sort(state.F), np.sort(sphere(batches[0]))[: opt.population])
    assert state.best_F == state.F.min() == problem.best_f


def test_crowding_factor_blocks_moving_to_an_over_crowded_centre():
    rng = np.random.default_rng(0)
    U = 0.5 + 0.01 * rng.standard_normal((20, 4))  # everybody sees everybody
    F = rng.random(20)
    mask = neighbours(U, 0.2)
    assert mask.sum(axis=1).min() == 19
    _, swarm_ok = swarm_centres(U, mask, delta=0.618)
    _, follow_ok = best_in_view(F, mask, delta=0.618)
    assert not swarm_ok.any() and not follow_ok.any()  # 19/20 >= 0.618: crowded
    centres, swarm_ok = swarm_centres(U, mask, delta=1.0)
    assert swarm_ok.all()  # 19/20 < 1: not crowded
    np.testing.assert_allclose(centres[0], U[1:].mean(axis=0))


def test_following_needs_a_better_fish_in_view():
    U = np.array([[0.1, 0.1], [0.15, 0.1], [0.9, 0.9], [0.5, 0.5]])
    F = np.array([2.0, 1.0, 0.0, 3.0])
    mask = neighbours(U, 0.1)
    j, ok = best_in_view(F, mask, delta=0.618)
    assert ok.tolist() == [True, False, False, False]  # only fish 0 sees a better fish (1)
    assert j[0] == 1


def test_swarm_needs_fish_in_view():
    U = np.array([[0.0, 0.0], [1.0, 1.0]])
    _, ok = swarm_centres(U, neighbours(U, 0.5), delta=0.618)
    assert not ok.any()


def test_regeneration_never_replaces_the_best_fish():
    opt = make("iafsa")
    problem = Problem(sphere, LOWER, UPPER, 10_000)
    rng = np.random.default_rng(4)
    state = opt.setup(problem, rng, None)
    best = int(np.argmin(state.F))
    keep = state.U[best].copy()
    idx = opt.regenerate(state, problem, rng, iteration=40)  # round(1 + 40/10) = 5 draws
    assert 1 <= idx.size <= 5 and best not in idx
    np.testing.assert_array_equal(state.U[best], keep)
    np.testing.assert_allclose(state.F, sphere(problem.lower + state.U * problem.span))


def test_regeneration_is_translation_invariant():
    # eq 34 about the box centre: the same state on a box moved by +300 regenerates the same
    # fish moved by +300 (the printed X_gm (1 + z) scales with the distance from the origin)
    out = {}
    for shift in (0.0, 300.0):
        opt = make("iafsa")

        def cost(X, shift=shift):
            return sphere(X - shift - 1.0)

        problem = Problem(cost, LOWER + shift, UPPER + shift, 10_000)
        rng = np.random.default_rng(4)
        state = opt.setup(problem, rng, None)
        idx = opt.regenerate(state, problem, rng, iteration=40)
        out[shift] = (idx, problem.lower + state.U[idx] * problem.span)
    np.testing.assert_array_equal(out[0.0][0], out[300.0][0])
    np.testing.assert_allclose(out[300.0][1], out[0.0][1] + 300.0, atol=1e-9)
    with pytest.raises(ValueError, match="regen_centre"):
        make("iafsa", regen_centre="corner")


@pytest.mark.parametrize("name", ["afsa", "iafsa"])
def test_fish_stay_in_box(name):
    seen = []

    def cost(X):
        seen.append(X.copy())
        return np.sum((X - 4.9) ** 2, axis=1)

    lower, upper = -np.ones(4), 5.0 * np.ones(4)
    make(name).minimize(cost, lower, upper, max_evals=3000, seed=3)
    X = np.concatenate(seen)
    assert np.all((X >= lower) & (X <= upper))


@pytest.mark.parametrize(
    "name, params, bad",
    [
        ("afsa", {"delta": 0.0}, "delta"),
        ("afsa", {"try_number": 0}, "try_number"),
        ("afsa", {"visual": -1.0}, "visual"),
        ("afsa", {"visual_unit": "box"}, "visual_unit"),
        ("afsa", {"direction": "sphere"}, "direction"),
        ("iafsa", {"random_move": "far"}, "random_move"),
        ("iafsa", {"chi": 0.0}, "chi"),
        ("iafsa", {"hbar": -2.0}, "hbar"),
        ("iafsa", {"k": 0}, "k"),
    ],
)
def test_invalid_parameters_name_the_parameter(name, params, bad):
    with pytest.raises(ValueError, match=bad):
        make(name, **params)


def test_defaults_follow_the_paper():
    p = make("iafsa").params
    assert (p["population"], p["chi"], p["hbar"], p["try_number"], p["delta"], p["b"]) == (
        50,
        0.95,
        2.0,
        5,
        0.618,
        -0.4,
    )
    # AFSA: 002 section 4.1, the settings under which 002 compares AFSA with IAFSA (Visual 50,
    # Step 6, Try_Num 5 on [-100, 100]), along the box diagonal as IAFSA's
    p = make("afsa").params
    got = (p["population"], p["visual"], p["step"], p["try_number"], p["delta"])
    assert got == (50, 0.25, 0.03, 5, 0.618)
    assert p["visual_unit"] == make("iafsa").params["visual_unit"] == "diagonal"
    assert (p["prey_region"], p["random_move"]) == ("ball", "step")


@pytest.mark.parametrize("d", [1, 4, 16])
def test_visual_unit_diagonal_scales_visual_and_step_by_sqrt_d(d):
    """``visual_unit="diagonal"``: the unit-box Visual / Step / V0 are the fractions times the
    diagonal ``sqrt(d)``; ``"width"``: the fractions themselves (the old reading)."""
    problem = Problem(sphere, np.zeros(d), np.ones(d), 1000)
    for unit, f in (("width", 1.0), ("diagonal", np.sqrt(d))):
        opt = make("afsa", visual=0.3, step=0.04, visual_unit=unit)
        state = opt.setup(problem, np.random.default_rng(0), None)
        vis, stp = opt._visual_step(state, problem, np.random.default_rng(1))
        assert vis == pytest.approx(0.3 * f) and stp == pytest.approx(0.04 * f)
        iopt = make("iafsa", v0=0.3, visual_unit=unit)
        state = iopt.setup(problem, np.random.default_rng(0), None)
        state.U[:] = state.best_U  # Dis_i = 0: Visual_i = V0
        vis, stp = iopt._visual_step(state, problem, np.random.default_rng(1))
        np.testing.assert_allclose(vis, 0.3 * f)
        np.testing.assert_allclose(stp, 0.3 * f / 2.0)


def test_prey_tries_reach_the_diagonal_visual_field():
    """Default units: in d = 16 the tries go up to ``Visual * sqrt(16)`` away (beyond the
    width-fraction ``Visual``), never further."""
    d, batches = 16, []

    def cost(X):
        batches.append(X.copy())
        return np.zeros(len(X)) if len(batches) == 1 else np.ones(len(X))

    x0 = np.full((2, d), 0.5)
    opt = make("afsa", population=2, try_number=10, visual=0.1, step=0.01)
    problem = Problem(cost, np.zeros(d), np.ones(d), 10_000)
    state = opt.setup(problem, np.random.default_rng(5), x0)
    opt._generation(state, problem, np.random.default_rng(6))
    dist = np.linalg.norm(np.concatenate(batches[1:11]) - 0.5, axis=1)
    assert dist.max() <= 0.4 + 1e-12 and dist.max() > 0.1


@pytest.mark.parametrize("direction", ["cube", "normal"])
def test_compiled_prey_tries_draw_what_in_view_draws(direction):
    """The kernels' eq 16 offsets are ``in_view``'s, number for number from the same stream."""
    from swarmplan.optimizers._fish_swarm_kernels import (
        BALL_CUBE_DIRECTION,
        BALL_NORMAL_DIRECTION,
        prey_tries,
    )

    n, d = 6, 5
    U = np.full((n, d), 0.5)
    vis = np.linspace(0.05, 0.3, n)
    expected = in_view(np.random.default_rng(9), (n, d), vis, "ball", direction)
    rng = np.random.default_rng(9)  # the generation's draws
    if direction == "normal":
        G, lens = rng.standard_normal((n, d)), rng.random(n)
    else:
        G = rng.random((n, d + 1))
        lens = np.ascontiguousarray(G[:, d])  # as the optimizer passes it: one compiled signature
    mode = BALL_NORMAL_DIRECTION if direction == "normal" else BALL_CUBE_DIRECTION
    T, X = np.empty((n, d)), np.empty((n, d))
    prey_tries(U, np.arange(n), vis, G, lens, mode, T, X, np.zeros(d), np.ones(d))
    np.testing.assert_allclose(T - 0.5, expected, atol=1e-12)
    assert np.all(np.linalg.norm(expected, axis=1) <= vis + 1e-12)


def test_random_move_visual_is_the_texts_reading():
    """``random_move="visual"`` (002's text, the textbook codes): the random behaviour (eq 21)
    moves up to ``Visual``; the default (eq 21 as printed) at most ``Step``."""
    d = 10

    def moves(random_move):
        batches = []

        def cost(X):
            batches.append(X.copy())
            return np.zeros(len(X)) if len(batches) == 1 else np.ones(len(X))

        x0 = np.array([np.full(d, 0.3), np.full(d, 0.7)])
        params = {"visual": 0.3, "step": 0.01, "visual_unit": "width", "random_move": random_move}
        opt = make("afsa", population=2, try_number=2, **params)
        problem = Problem(cost, np.zeros(d), np.ones(d), 10_000)
        state = opt.setup(problem, np.random.default_rng(5), x0)
        opt._generation(state, problem, np.random.default_rng(6))
        return np.linalg.norm(batches[-1] - x0, axis=1)

    assert moves("step").max() <= 0.01 + 1e-12
    assert 0.01 < moves("visual").max() <= 0.3 + 1e-12


# Measured on sphere d=10, 20000 evals, seeds 0-2: random 9.4-12.5, afsa 1.5-2.9 (6.1-10.6 with
# 002's CEC settings in box widths, before the scale fixes), iafsa <= 2e-4.
def test_afsa_beats_random_search_on_sphere():
    rnd = [make("random").minimize(sphere, LOWER, UPPER, max_evals=20000, seed=s).f for s in SEEDS]
    afsa = [make("afsa").minimize(sphere, LOWER, UPPER, max_evals=20000, seed=s).f for s in SEEDS]
    assert np.mean(afsa) < 0.5 * np.mean(rnd)
    assert max(afsa) < 6.0  # fails with the CEC settings in box widths


def test_iafsa_beats_random_search_on_sphere():
    for seed in SEEDS:
        rnd = make("random").minimize(sphere, LOWER, UPPER, max_evals=20000, seed=seed)
        res = make("iafsa").minimize(sphere, LOWER, UPPER, max_evals=20000, seed=seed)
        assert res.evaluations == 20000
        assert res.f < 0.01 < rnd.f


@pytest.mark.parametrize("name", ["afsa", "iafsa"])
def test_prey_tries_and_random_moves_stay_in_the_visual_field(name):
    """Paper 002: a prey try is "within the visual range (d_ij <= Visual)" (eq 16) and the
    random behaviour (eq 21) moves at most ``Step``. Two fish far apart (nobody in view), a
    cost that makes every try fail: the batches after the initial one are the ``try_number``
    rounds of tries and then the random moves. (The earlier per-coordinate cube put tries up to
    ``sqrt(d) * Visual`` away.)"""
    d, visual, step = 10, 0.2, 0.05
    params = {"population": 2, "try_number": 3, "visual_unit": "width"}
    if name == "afsa":
        params.update(visual=visual, step=step)
    else:  # IAFSA: Visual = spiral + V0 per fish; far from the bulletin-board fish it can be large
        params.update(v0=visual)
    batches = []

    def cost(X):
        batches.append(X.copy())
        return np.zeros(len(X)) if len(batches) == 1 else np.ones(len(X))

    lower, upper = np.zeros(d), np.ones(d)
    x0 = np.array([np.full(d, 0.3), np.full(d, 0.7)])
    opt = make(name, **params)
    problem = Problem(cost, lower, upper, 10_000)
    rng = np.random.default_rng(5)
    state = opt.setup(problem, rng, x0 if name == "afsa" else None)
    U0 = state.U.copy()
    vis, stp = opt._visual_step(state, problem, np.random.default_rng(6))
    vis = np.broadcast_to(np.abs(vis), (2,))
    stp = np.broadcast_to(np.abs(stp), (2,))
    rng_gen = np.random.default_rng(6)  # the same draws _visual_step makes inside the generation
    n_before = len(batches)
    opt._generation(state, problem, rng_gen)
    new = batches[n_before:]
    assert len(new) == 3 + 1  # three rounds of tries (all fail), then the two random moves
    for tries in new[:3]:
        assert tries.shape == (2, d)
        assert np.all(np.linalg.norm(tries - U0, axis=1) <= vis + 1e-9)
    assert np.all(np.linalg.norm(new[3] - U0, axis=1) <= stp + 1e-9)


def test_prey_region_cube_is_the_earlier_reading():
    """``prey_region="cube"`` keeps the per-coordinate reading, whose tries leave the ball."""
    d = 10
    batches = []

    def cost(X):
        batches.append(X.copy())
        return np.zeros(len(X)) if len(batches) == 1 else np.ones(len(X))

    x0 = np.array([np.full(d, 0.3), np.full(d, 0.7)])
    params = {"visual": 0.2, "step": 0.05, "prey_region": "cube", "visual_unit": "width"}
    opt = make("afsa", population=2, try_number=3, **params)
    problem = Problem(cost, np.zeros(d), np.ones(d), 10_000)
    state = opt.setup(problem, np.random.default_rng(5), x0)
    U0 = state.U.copy()
    opt._generation(state, problem, np.random.default_rng(6))
    tries = np.concatenate([b - U0 for b in batches[1:4]])
    assert np.abs(tries).max() <= 0.2 + 1e-12 and np.linalg.norm(tries, axis=1).max() > 0.2
    with pytest.raises(ValueError, match="prey_region"):
        make("afsa", prey_region="sphere")


def test_compiled_view_matches_the_numpy_definitions():
    """``fish_view`` (one compiled pass) = ``neighbours`` + ``swarm_centres`` + ``best_in_view``."""
    from swarmplan.optimizers._fish_swarm_kernels import fish_view

    rng = np.random.default_rng(3)
    for n, d, vis in ((30, 3, 0.3), (20, 4, rng.random(20) * 0.5), (12, 2, 2.0)):
        U, F = rng.random((n, d)), rng.random(n)
        F[3] = F[5]  # a tie in view
        visual = np.broadcast_to(np.asarray(vis, dtype=float), (n,)).copy()
        centres, best = np.empty((n, d)), np.empty(n, dtype=np.int64)
        flags = np.empty((2, n), dtype=bool)
        fish_view(U, F, np.einsum("ij,ij->i", U, U), U @ U.T, visual, 0.618, centres, best, flags)
        mask = neighbours(U, visual)
        c, sw = swarm_centres(U, mask, 0.618)
        j, fo = best_in_view(F, mask, 0.618)
        np.testing.assert_array_equal(flags[0], sw)
        np.testing.assert_array_equal(flags[1], fo)
        np.testing.assert_array_equal(best[fo], j[fo])
        np.testing.assert_allclose(centres[sw], c[sw], rtol=1e-12)
        assert sw.any() or n == 12  # the view is exercised (n = 12: everyone sees everyone, crowded)


@pytest.mark.parametrize("name", ["afsa", "iafsa"])
def test_every_fish_ends_at_an_evaluated_move_with_its_cost(name):
    """The compiled move/selection path: after a generation every fish is at one of the
    points evaluated in its last batch, with that point's cost, and the swarm's costs are what
    the cost function returned."""
    batches = []

    def cost(X):
        batches.append(X.copy())
        return sphere(X)

    opt = make(name, population=20)
    problem = Problem(cost, LOWER, UPPER, 100_000)
    rng = np.random.default_rng(7)
    state = opt.setup(problem, rng, None)
    for _ in range(5):
        opt._generation(state, problem, rng)
        last = batches[-1]
        X = LOWER + state.U * (UPPER - LOWER)
        for i in range(len(X)):
            hit = np.flatnonzero(np.all(np.isclose(last, X[i], atol=1e-9), axis=1))
            assert hit.size, f"fish {i} is not at a point of its last batch"
            assert np.isclose(state.F[i], sphere(last[hit[:1]])[0])


@pytest.mark.parametrize("name", ["afsa", "iafsa"])
def test_registry_fish_leave_the_warm_start_in_the_mountains_path_problem(name):
    """docs/comparison.md flies ``afsa`` with registry defaults in iafsa_mountains: its plans
    must not be the warm start (section 4.2's Visual 0.5 along the diagonal gave cost 245.25,
    the warm start's, on every seed: every try an infeasible path)."""
    from swarmplan.planner.global_path import agent_problem, global_config
    from swarmplan.world import load_world

    world = load_world(Path(__file__).parents[1] / "worlds" / "papers" / "iafsa_mountains.yaml")
    prob = agent_problem(world, world.agents[0], global_config(world))
    enc = prob.encoding
    x0 = enc.warm_start()
    warm = float(np.min(prob.cost(x0)))
    for seed in range(3):
        res = make(name).minimize(prob.cost, enc.lower, enc.upper, max_evals=3000, seed=seed, x0=x0)
        assert res.f < warm - 1.0, f"{name} seed {seed}: {res.f} vs warm start {warm}"
