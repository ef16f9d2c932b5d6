"""The kernels' compiled sort gives numpy's stable order exactly: ties in their first order,
NaN last, -0.0 equal to 0.0, on empty, short and long arrays of floats and of integers."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.runtime.compiled import kernel_module


def _argsort():
    return kernel_module("swarmplan.geometry._sort_kernel").argsort


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 9, 64, 1000])
def test_floats_sort_as_numpys_stable_sort(n: int) -> None:
    argsort = _argsort()
    rng = np.random.default_rng(n)
    a = np.round(rng.normal(size=n), 1)  # many ties
    if n >= 3:
        a[rng.integers(0, n, size=max(1, n // 5))] = np.nan
        a[rng.integers(0, n, size=max(1, n // 7))] = -0.0
        a[rng.integers(0, n, size=max(1, n // 7))] = 0.0
        a[rng.integers(0, n, size=max(1, n // 9))] = np.inf
        a[rng.integers(0, n, size=max(1, n // 9))] = -np.inf
    got = argsort(a)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, np.argsort(a, kind="stable"))


@pytest.mark.parametrize("n", [0, 1, 5, 33, 500])
def test_integers_sort_as_numpys_stable_sort(n: int) -> None:
    argsort = _argsort()
    keys = np.random.default_rng(100 + n).integers(-20, 20, size=n).astype(np.int64)
    np.testing.assert_array_equal(argsort(keys), np.argsort(keys, kind="stable"))


def test_sorted_and_reversed_runs() -> None:
    argsort = _argsort()
    a = np.arange(100, dtype=np.float64)
    np.testing.assert_array_equal(argsort(a), np.arange(100))
    np.testing.assert_array_equal(argsort(a[::-1].copy()), np.arange(99, -1, -1))
    same = np.zeros(17)
    np.testing.assert_array_equal(argsort(same), np.arange(17))


@pytest.mark.parametrize("n", [0, 1, 2, 9, 100])
def test_searches_find_numpys_indexes(n: int) -> None:
    kernels = kernel_module("swarmplan.geometry._sort_kernel")
    rng = np.random.default_rng(200 + n)
    xs = np.sort(np.round(rng.normal(size=n), 1))
    if n >= 2:
        xs[-1] = np.nan  # NaN sorts last
    probes = np.concatenate([xs, np.round(rng.normal(size=20), 1), [-np.inf, np.inf, np.nan, -0.0, 0.0]])
    for v in probes:
        assert kernels.search_left(xs, v) == np.searchsorted(xs, v, side="left"), v
        assert kernels.search_right(xs, v) == np.searchsorted(xs, v, side="right"), v
