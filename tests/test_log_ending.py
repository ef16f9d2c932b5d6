"""The end of a log: the last step's messages appear once per channel, whether or not the last
step falls on a time the throttled Foxglove channels (every 0.2 s, paths every 1 s) are due."""

from __future__ import annotations

from collections import Counter

import pytest
from helpers import crossing_with_drone, make_world, read_log, run_to_end

# Written with every step, or with every scene update: at most one message per time each.
PER_STEP = ("/agents/state", "/obstacles/state", "/tf", "/scene", "/agents/speed")
THROTTLED = ("/tf", "/scene", "/agents/speed", "/scene/paths", "/scene/paths/overview")


def _log(tmp_path, max_time: float):
    raw = crossing_with_drone(max_time)
    path = tmp_path / f"end-{max_time}.mcap"
    _, summary, _ = run_to_end(make_world(raw), seed=0, log_path=path, foxglove=True)
    return summary, read_log(path)


@pytest.mark.parametrize(
    ("max_time", "on_boundary"),
    [(2.0, True), (2.1, False), (3.0, True)],  # 2.0 and 3.0: /tf, /scene (and paths at 3.0) are due
)
def test_the_last_step_is_written_once_per_channel(tmp_path, max_time, on_boundary):
    summary, log = _log(tmp_path, max_time)
    last = log["/agents/state"][-1][0]
    assert last == round(summary["sim_time"] * 1e9) == round(max_time * 1e9)
    for topic in PER_STEP:
        counts = Counter(t for t, _ in log[topic])
        assert max(counts.values()) == 1, (topic, [t for t, k in counts.items() if k > 1])
    # The scene ends in the final state: every throttled channel has a message at the last step.
    for topic in THROTTLED:
        times = [t for t, _ in log[topic]]
        assert times.count(last) == 1, (topic, times[-3:])
    # On a boundary the last scene is the regular one; off it, the final scene follows the last
    # regular one (less than 0.2 s earlier).
    gap = last - log["/scene"][-2][0]
    assert gap == round(0.2e9) if on_boundary else 0 < gap < round(0.2e9)
    assert len(log["/agents/state"]) == summary["steps"] + 1
