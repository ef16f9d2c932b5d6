"""Exports of a run's flown paths that vehicles load: Crazyflie polynomial trajectories,
PX4/ArduPilot missions (QGroundControl ``.plan`` and ``QGC WPL 110``) and plain CSV samples,
each checked by flying it again (``docs/export.md``).

>>> from swarmplan.replay import load
>>> from swarmplan.export import build, write
>>> exp = build(load("logs/crazyflie-room-1.mcap"), "crazyflie")  # doctest: +SKIP
>>> write(exp, "out/room")  # doctest: +SKIP
"""

from .files import FORMATS, Export, build, run_check, write
from .source import ExportError, LimitError

__all__ = ["FORMATS", "Export", "ExportError", "LimitError", "build", "run_check", "write"]
