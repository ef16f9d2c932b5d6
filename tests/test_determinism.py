"""Same seed and world, same log (README): every message of every channel is
identical except the wall-clock timings ``wall_ms`` (/optimizer), ``wall_time`` and
``escape_planning_ms`` (/summary)."""

from __future__ import annotations

from pathlib import Path

from helpers import read_log

ROOT = Path(__file__).resolve().parents[1]
WALL_CLOCK = {"/optimizer": {"wall_ms"}, "/summary": {"wall_time", "escape_planning_ms"}}


def _strip(x, keys: set[str]):
    if isinstance(x, dict):
        return {k: _strip(v, keys) for k, v in x.items() if k not in keys}
    if isinstance(x, (list, tuple)):
        return [_strip(v, keys) for v in x]
    return x


def test_same_seed_same_log_but_wall_clock(tmp_path):
    from swarmplan.cli.run import main as run_main

    world = ROOT / "worlds" / "traps" / "u_pocket.yaml"  # an escape: optimizer runs are logged too
    logs = [tmp_path / f"run{k}.mcap" for k in range(2)]
    for log in logs:
        # the bare field's trap (the guide leads out of it without escapes)
        assert run_main([str(world), "--out", str(log), "--no-guide", "--quiet"]) == 0
    a, b = (read_log(log) for log in logs)
    assert sorted(a) == sorted(b)
    assert {"/agents/state", "/events", "/optimizer", "/summary"} <= set(a)
    assert a["/optimizer"] and a["/events"]
    for topic in a:
        keys = WALL_CLOCK.get(topic, set())
        assert _strip(a[topic], keys) == _strip(b[topic], keys), topic
    # the exceptions are real fields of the contract, present where the README says
    assert all("wall_ms" in m for _t, m in a["/optimizer"])
    summary = a["/summary"][-1][1]
    assert "wall_time" in summary and all("escape_planning_ms" in r for r in summary["agents"])
