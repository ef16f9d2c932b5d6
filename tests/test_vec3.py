"""norm3 / dot3 give numpy's own norm and sum along a length-3 axis bit for bit (the step's
results, and so the logs, do not change when they replace them)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.geometry.vec3 import dot3, norm3


@pytest.mark.parametrize("seed", range(3))
def test_norm3_and_dot3_equal_numpy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    scale = 10.0 ** rng.uniform(-8, 4, (500, 7, 1))
    a = rng.normal(size=(500, 7, 3)) * scale
    b = rng.normal(size=(500, 1, 3)) * 30.0
    a[0, 0] = [0.0, -0.0, 0.0]
    a[1, 1] = [1e-300, 1e-300, -1e-300]
    assert np.array_equal(norm3(a), np.linalg.norm(a, axis=-1))
    assert np.array_equal(norm3(a, keepdims=True), np.linalg.norm(a, axis=-1, keepdims=True))
    assert np.array_equal(norm3(a[:, 0]), np.linalg.norm(a[:, 0], axis=1))
    assert np.array_equal(dot3(a, b), np.sum(a * b, axis=-1))
    assert np.array_equal(dot3(a, a), np.sum(a * a, axis=-1))
