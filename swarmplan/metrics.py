"""Per-agent run metrics: path length, clearance, curvature, arrival, events counts."""

from __future__ import annotations

import numpy as np


def path_curvature(points: np.ndarray, min_step: float = 1e-3) -> np.ndarray:
    """Discrete curvature (1/m) at the interior vertices of a polyline: turning angle / mean step.

    Steps shorter than ``min_step`` are dropped first (hovering, arrival) so noise cannot
    produce huge curvatures.
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) < 3:
        return np.zeros(0)
    d = np.diff(pts, axis=0)
    n = np.linalg.norm(d, axis=1)
    keep = n > min_step
    d, n = d[keep], n[keep]
    if len(d) < 2:
        return np.zeros(0)
    u = d / n[:, None]
    cosang = np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0)
    return np.arccos(cosang) / (0.5 * (n[1:] + n[:-1]))


class RunMetrics:
    """Accumulates what ``/summary`` reports, step by step."""

    def __init__(self, ids: tuple[str, ...], n_obstacles: int):
        n = len(ids)
        self.ids = ids
        self.path_length = np.zeros(n)
        self.min_clearance = np.full(n, np.inf)
        self.min_agent_clearance = np.full(n, np.inf)
        self.min_terrain_clearance = np.full(n, np.inf)
        self.arrival_time = np.full(n, np.nan)
        self.collisions = np.zeros(n, dtype=int)
        self.collided_with: list[list[str]] = [[] for _ in range(n)]
        self.escapes = np.zeros(n, dtype=int)
        self.escape_ms: list[list[float]] = [[] for _ in range(n)]
        self.optimizer_runs = np.zeros(n, dtype=int)
        self.stuck_events = np.zeros(n, dtype=int)
        self.near_misses = np.zeros(n, dtype=int)
        self.emergency_stops = np.zeros(n, dtype=int)
        self.guard_steps = np.zeros(n, dtype=int)  # fixed-wing steps flown by the turn-ahead guard
        self.positions: list[np.ndarray] = []  # per step (N, 3), for curvature

    def add_step(
        self,
        pos0: np.ndarray,
        pos1: np.ndarray,
        active: np.ndarray,
        obstacle_clearance: np.ndarray,
        agent_clearance: np.ndarray,
        terrain_clearance: np.ndarray,
    ) -> None:
        self.path_length += np.where(active, np.linalg.norm(pos1 - pos0, axis=1), 0.0)
        self.min_clearance = np.where(
            active, np.minimum(self.min_clearance, obstacle_clearance), self.min_clearance
        )
        self.min_agent_clearance = np.where(
            active, np.minimum(self.min_agent_clearance, agent_clearance), self.min_agent_clearance
        )
        self.min_terrain_clearance = np.where(
            active, np.minimum(self.min_terrain_clearance, terrain_clearance), self.min_terrain_clearance
        )
        self.positions.append(pos1.copy())

    def curvature(self, i: int, until: int | None = None) -> np.ndarray:
        pts = np.array([p[i] for p in self.positions[:until]])
        return path_curvature(pts)
