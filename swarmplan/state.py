"""The simulation's state: every agent's kinematics and mode as arrays over agents."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MODES = ("apf", "escape", "smoothing", "arrived", "collided", "failed")
DONE_MODES = ("arrived", "collided", "failed")


@dataclass
class SwarmState:
    """Agent state at time ``t``; arrays have one row per agent in world order."""

    t: float
    step: int
    position: np.ndarray  # (N, 3)
    velocity: np.ndarray  # (N, 3)
    goal: np.ndarray  # (N, 3)
    mode: np.ndarray  # (N,) object array of mode strings
    segment: list[np.ndarray | None] = field(default_factory=list)  # waypoints being followed, per agent
    segment_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    route: list[np.ndarray | None] = field(default_factory=list)  # global path waypoints, per agent
    route_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def active(self) -> np.ndarray:
        """Agents still flying (not arrived, collided or failed)."""
        return ~np.isin(self.mode, DONE_MODES)

    def copy(self) -> SwarmState:
        return SwarmState(
            self.t,
            self.step,
            self.position.copy(),
            self.velocity.copy(),
            self.goal.copy(),
            self.mode.copy(),
            list(self.segment),
            self.segment_index.copy(),
        )
