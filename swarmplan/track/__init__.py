"""Quadrotor tracking of recorded runs: ``python -m swarmplan.track RUN.mcap`` (issue 13, parts 2-3).

>>> from swarmplan.replay import load
>>> from swarmplan.track import TrackerConfig, track
>>> result = track(load("logs/quickstart-1.mcap"), TrackerConfig())  # doctest: +SKIP
>>> result.agents["uav1"].max_error_m  # doctest: +SKIP
"""

from .config import PID, TrackerConfig, parse_tracker
from .core import AgentTrack, TrackResult, track

__all__ = ["PID", "AgentTrack", "TrackResult", "TrackerConfig", "parse_tracker", "track"]
