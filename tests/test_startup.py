"""`bench scale`'s start-up figure: a fresh interpreter to after the first step."""

from __future__ import annotations


def test_bench_startup_names_the_heavy_imports():
    """``bench scale``'s start-up figure says which heavy libraries its first step loaded."""
    from swarmplan.bench.scale import HEAVY_IMPORTS, startup_seconds

    first, cpu, whole, loaded = startup_seconds()
    assert 0 < first < whole and cpu > 0
    assert set(loaded) <= set(HEAVY_IMPORTS)
    assert "scipy.spatial" not in loaded and "trimesh" not in loaded  # neither needed by this world


def test_world_files_parse_the_same_through_libyaml():
    """Every shipped world file (and a few YAML corners) gives ``safe_load``'s data through the
    loader ``load_world`` uses; a text libyaml refuses is reported in ``safe_load``'s words."""
    from pathlib import Path

    import pytest
    import yaml

    from swarmplan.world.io import _parse

    root = Path(__file__).resolve().parent.parent
    files = sorted((root / "worlds").rglob("*.yaml"))
    assert len(files) >= 10
    corners = "a: 1e3\nb: .5\nc: 0x1F\nd: yes\ne: ~\nf: [1, -2.5e-3, .inf]\ng: '007'\nh: 2026-11-26\n"
    for text in [f.read_text(encoding="utf-8") for f in files] + [corners]:
        assert _parse(yaml, text) == yaml.safe_load(text)
    for bad in ("a: [1, 2\n", "a: b: c\n", "\tx: 1\n"):
        with pytest.raises(yaml.YAMLError) as ours:
            _parse(yaml, bad)
        with pytest.raises(yaml.YAMLError) as theirs:
            yaml.safe_load(bad)
        assert str(ours.value) == str(theirs.value)
