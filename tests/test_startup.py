"""`bench scale`'s start-up figure: a fresh interpreter to after the first step."""

from __future__ import annotations


def test_bench_startup_names_the_heavy_imports():
    """``bench scale``'s start-up figure says which heavy libraries its first step loaded."""
    from swarmplan.bench.scale import HEAVY_IMPORTS, startup_seconds

    first, cpu, whole, loaded = startup_seconds()
    assert 0 < first < whole and cpu > 0
    assert set(loaded) <= set(HEAVY_IMPORTS)
    assert "scipy.spatial" not in loaded and "trimesh" not in loaded  # neither needed by this world
