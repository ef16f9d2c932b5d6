"""Quadrotor tracking of recorded runs: ``python -m swarmplan.track RUN.mcap``.

>>> from swarmplan.replay import load
>>> from swarmplan.track import TrackerConfig, track
>>> result = track(load("logs/quickstart-1.mcap"), TrackerConfig())  # doctest: +SKIP
>>> result.agents["uav1"].max_error_m  # doctest: +SKIP

The vehicle and gains (``TrackerConfig``, the world's ``tracker:`` section) are defined with the
world format in :mod:`swarmplan.world.tracker_config`; this package flies them.
"""

from swarmplan.track.tracking import AgentTrack, TrackResult, track
from swarmplan.world.tracker_config import PID, TrackerConfig, parse_tracker

__all__ = ["PID", "AgentTrack", "TrackResult", "TrackerConfig", "parse_tracker", "track"]
