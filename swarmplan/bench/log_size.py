"""How a run's log grows: per channel, the largest message in the second and in the last tenth
of the run (a channel whose messages grow with the run's length shows a ratio well above 1),
and the file's bytes per agent-step."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def message_growth(path: Path) -> dict[str, tuple[int, int]]:
    """Per topic: (largest message in the second tenth of the run's time, largest in the last
    tenth), in bytes; topics with no message in either tenth are left out."""
    from mcap.reader import make_reader

    sizes: list[tuple[str, int, int]] = []
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            sizes.append((channel.topic, message.log_time, len(message.data)))
    end = max((t for _, t, _ in sizes), default=0)
    if end <= 0:
        return {}
    out: dict[str, list[int]] = {}
    for topic, t, n in sizes:
        tenth = min(9, int(10 * t / end))
        if tenth in (1, 9):
            row = out.setdefault(topic, [0, 0])
            k = 0 if tenth == 1 else 1
            row[k] = max(row[k], n)
    return {topic: (a, b) for topic, (a, b) in out.items() if a and b}


def growth_table(path: Path, agents: int, steps: int) -> dict[str, Any]:
    """The worst ratio of the last tenth's largest message to the second tenth's (and its
    topic), every topic's pair, and the file's bytes per agent-step."""
    growth = message_growth(path)
    worst = max(growth, key=lambda k: growth[k][1] / growth[k][0], default=None)
    return {
        "growth": growth,
        "worst_topic": worst,
        "worst_ratio": growth[worst][1] / growth[worst][0] if worst else 0.0,
        "bytes_per_agent_step": path.stat().st_size / max(1, agents * steps),
        "file_bytes": path.stat().st_size,
    }
