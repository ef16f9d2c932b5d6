"""The shapes' numpy distances (``shapes.DISTANCE``), written per component, give the bits of
the reductions they replace (``np.linalg.norm`` and ``max`` over the last axis): random points at several
scales, zeros of both signs, C and Fortran order."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.geometry import batch, shapes


def _sphere(p, r):  # noqa: ANN001, ANN202
    return np.linalg.norm(p, axis=-1) - r


def _box(p, half):  # noqa: ANN001, ANN202
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)


def _capsule(p, r, h):  # noqa: ANN001, ANN202
    closest = np.zeros_like(p)
    closest[..., 2] = np.clip(p[..., 2], -h, h)
    return np.linalg.norm(p - closest, axis=-1) - r


@pytest.mark.parametrize("seed", range(4))
def test_distances_equal_the_reductions_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    n, m = 300, 17
    p = rng.normal(0, 5, (n, m, 3)) * rng.choice([1e-3, 1.0, 30.0], (n, m, 1))
    p[rng.random((n, m, 3)) < 0.03] = 0.0
    p[rng.random((n, m, 3)) < 0.03] = -0.0
    if seed % 2:
        p = np.asfortranarray(p)
    r, h, half = rng.uniform(0.1, 5, m), rng.uniform(0.1, 5, m), rng.uniform(0.1, 5, (m, 3))
    for new, old, args in (
        (shapes.dist_sphere, _sphere, (r,)),
        (shapes.dist_box, _box, (half,)),
        (shapes.dist_capsule, _capsule, (r, h)),
    ):
        got, want = new(p, *args), old(p, *args)
        assert got.shape == want.shape == (n, m)
        assert got.tobytes() == want.tobytes()
    # inside and outside both present
    assert (shapes.dist_box(p, half) < 0).any() and (shapes.dist_box(p, half) > 0).any()


@pytest.mark.parametrize("shape", [(1, 1), (37, 3), (2000, 8), (500, 17)])
def test_rotated_points_equal_einsum_bit_for_bit(shape):
    from scipy.spatial.transform import Rotation

    n, m = shape
    rng = np.random.default_rng(n + m)
    rel = rng.normal(0, 10, (n, m, 3)) * rng.choice([1e-3, 1.0, 100.0], (n, m, 1))
    rel[rng.random((n, m, 3)) < 0.03] = -0.0
    rotation = Rotation.random(m, random_state=m).as_matrix()
    rotation[0] = np.eye(3)
    got = batch.rotate_rows(rel, rotation)
    want = np.einsum("nmk,mkl->nml", rel, rotation)
    assert got.shape == want.shape
    assert got.tobytes() == want.tobytes()
