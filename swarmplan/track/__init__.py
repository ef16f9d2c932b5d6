"""Quadrotor tracking of recorded runs: ``python -m swarmplan.track RUN.mcap`` (issue 13, parts 2-3).

>>> from swarmplan.replay import load
>>> from swarmplan.track import TrackerConfig, track
>>> result = track(load("logs/quickstart-1.mcap"), TrackerConfig())  # doctest: +SKIP
>>> result.agents["uav1"].max_error_m  # doctest: +SKIP

Importing the package (or ``swarmplan.track.config``) loads only the config module, so the
world parser can validate a ``tracker:`` section without pulling in scipy or the replay code.
"""

from typing import Any

from .config import PID, TrackerConfig, parse_tracker

__all__ = ["PID", "AgentTrack", "TrackResult", "TrackerConfig", "parse_tracker", "track"]


def __getattr__(name: str) -> Any:
    if name in ("AgentTrack", "TrackResult", "track"):
        from . import core

        return getattr(core, name)
    raise AttributeError(f"module 'swarmplan.track' has no attribute {name!r}")
