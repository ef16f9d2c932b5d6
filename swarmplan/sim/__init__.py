"""The simulator: :class:`Simulation` (``reset`` / ``step``) and the pieces it orchestrates."""

from swarmplan.core import Event, PlannedSegment, Planner, ResetResult, StepResult
from swarmplan.sim.contacts import CRASH_DEPTH
from swarmplan.sim.env import Simulation

__all__ = ["CRASH_DEPTH", "Event", "PlannedSegment", "Planner", "ResetResult", "Simulation", "StepResult"]
