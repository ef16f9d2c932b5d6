"""Tree-based agent queries return exactly what the all-pairs versions return."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.geometry.collision import agent_contacts
from swarmplan.geometry.neighbours import (
    agent_clearance_indexed,
    agent_contacts_indexed,
    separation_violations,
)


@pytest.fixture(autouse=True, params=["compiled", "reference"])
def _path(request, monkeypatch):
    """Every test on both paths: the compiled kernels (swarm-sized worlds) and the reference
    path (smaller worlds), whatever the size of the test's swarm."""
    threshold = 0 if request.param == "compiled" else 10**9
    monkeypatch.setattr("swarmplan.runtime.compiled.CHECKS_COMPILED_FROM", threshold)


def _swarm(seed, n=200):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(0, 200, (8, 3))
    p0 = centers[rng.integers(0, 8, n)] + rng.normal(0, 4.0, (n, 3))
    p1 = p0 + rng.normal(0, 1.0, (n, 3))
    radii = rng.choice([0.5, 1.0, 1.5], n)
    sep = rng.choice([2.0, 3.0, 5.0], (n, 3))
    active = rng.random(n) < 0.8
    return p0, p1, radii, sep, active


@pytest.mark.parametrize("seed", range(4))
def test_indexed_agent_queries_equal_all_pairs(seed):
    p0, p1, radii, sep, active = _swarm(seed)
    for margin in (0.0, 0.5):
        ref = agent_contacts(p0, p1, radii, active, margin)
        assert len(ref) > 5
        assert agent_contacts_indexed(p0, p1, radii, active, margin) == ref
    d = np.linalg.norm(p0[:, None] - p0[None], axis=-1) - (radii[:, None] + radii[None])
    np.fill_diagonal(d, np.inf)
    np.testing.assert_array_equal(agent_clearance_indexed(p0, radii), d.min(axis=1))
    s = np.maximum(sep[:, None], sep[None])
    rr = radii[:, None] + radii[None]
    inside = np.linalg.norm((p0[:, None] - p0[None]) / (s + rr[..., None]), axis=-1) < 1.0
    np.fill_diagonal(inside, False)
    inside &= active[:, None] | active[None]
    ri, rj = np.nonzero(np.triu(inside))
    i, j = separation_violations(p0, sep, radii, active)
    assert len(ri) > 5
    np.testing.assert_array_equal(i, ri)
    np.testing.assert_array_equal(j, rj)


def test_contact_at_the_edge_of_the_reach_is_found():
    """Two agents whose steps cross at their far ends: the midpoints are as far apart as the
    reach allows and the contact is still reported."""
    p0 = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    p1 = np.array([[4.0, 0, 0], [6.0, 0, 0]])  # 2 m apart at the end of the step, midpoints 6 m
    radii = np.array([1.0, 1.01])
    active = np.array([True, True])
    assert agent_contacts(p0, p1, radii, active) == [(0, 1)]
    assert agent_contacts_indexed(p0, p1, radii, active) == [(0, 1)]


@pytest.mark.parametrize("n", [2, 5, 32, 33, 60])
def test_small_and_large_swarms_take_the_same_answers(n):
    """Around the size where the tree takes over from all pairs, the answers stay exact."""
    p0, p1, radii, sep, active = _swarm(n, n)
    p0, p1 = p0 / 10.0, p0 / 10.0 + (p1 - p0)  # dense enough for contacts among few agents
    assert agent_contacts_indexed(p0, p1, radii, active, 0.3) == agent_contacts(p0, p1, radii, active, 0.3)
    d = np.linalg.norm(p0[:, None] - p0[None], axis=-1) - (radii[:, None] + radii[None])
    np.fill_diagonal(d, np.inf)
    np.testing.assert_array_equal(agent_clearance_indexed(p0, radii), d.min(axis=1))
    s = np.maximum(sep[:, None], sep[None])
    rr = radii[:, None] + radii[None]
    inside = np.linalg.norm((p0[:, None] - p0[None]) / (s + rr[..., None]), axis=-1) < 1.0
    np.fill_diagonal(inside, False)
    inside &= active[:, None] | active[None]
    ri, rj = np.nonzero(np.triu(inside))
    i, j = separation_violations(p0, sep, radii, active)
    np.testing.assert_array_equal(i, ri)
    np.testing.assert_array_equal(j, rj)


def test_compiled_contacts_match_all_pairs_at_the_exact_threshold():
    """The compiled pairs use ``segment_segment_min_distance``'s arithmetic term for term: with
    the margin set so that a pair's sum of radii + margin lands on its computed distance (and
    one ulp beyond), both decide that pair alike. Zero-length steps included."""
    from swarmplan.geometry.collision import segment_segment_min_distance

    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(150):
        n = int(rng.integers(2, 80))
        p0 = rng.uniform(0, 30, (n, 3))
        p1 = p0 + rng.normal(0, 2, (n, 3)) * (rng.random((n, 1)) < 0.8)
        radii = rng.uniform(0.3, 1.5, n)
        active = rng.random(n) < 0.7
        i, j = np.triu_indices(n, 1)
        d = segment_segment_min_distance(p0[i], p1[i], p0[j], p1[j])
        k = int(rng.integers(len(i)))
        edge = float(d[k] - radii[i[k]] - radii[j[k]])
        for margin in (edge, float(np.nextafter(edge, np.inf)), float(np.nextafter(edge, -np.inf)), 0.4):
            assert agent_contacts_indexed(p0, p1, radii, active, margin) == agent_contacts(
                p0, p1, radii, active, margin
            )
            compared += 1
    assert compared == 600


@pytest.mark.parametrize("seed", range(3))
def test_compiled_near_miss_pairs_equal_separation_violations(seed):
    """``NearMisses`` takes its pairs from ``swept_kernels.separation_keys``: the same pairs, in
    the same order, as ``separation_violations``, incl. pairs exactly on the ellipsoid."""
    from swarmplan.geometry import swept_kernels

    p0, _, radii, sep, active = _swarm(seed, 300)
    # Two pairs placed on the ellipsoid along x: exactly on it (outside) and one ulp inside.
    scale = max(sep[0, 0], sep[1, 0]) + radii[0] + radii[1]
    p0[1] = p0[0] + [scale, 0, 0]
    scale2 = max(sep[2, 0], sep[3, 0]) + radii[2] + radii[3]
    p0[3] = p0[2] + [np.nextafter(scale2, 0.0), 0, 0]
    active[:4] = True
    i, j = separation_violations(p0, sep, radii, active)
    keys = swept_kernels.separation_keys(p0, sep, radii, active)
    assert len(i) > 20
    np.testing.assert_array_equal(keys // len(p0), i)
    np.testing.assert_array_equal(keys % len(p0), j)
