"""Replay of swarmplan run logs: load an MCAP log, recompute metrics, plot and animate.

>>> from swarmplan.replay import load
>>> rec = load("logs/quickstart-7.mcap")  # doctest: +SKIP
>>> rec.positions.shape  # (agents, steps, 3)  # doctest: +SKIP
"""

from .metrics import AgentMetrics, compare_with_summary, compute_metrics
from .recording import Event, ObstacleTrack, Recording, RecordingError, load

__all__ = [
    "AgentMetrics",
    "Event",
    "ObstacleTrack",
    "Recording",
    "RecordingError",
    "compare_with_summary",
    "compute_metrics",
    "load",
]
