"""What an export reads from a run log: each agent's flown path on the log's timing, its limits
(from the log's ``/world``), and the log's own soundness (agents, a complete file)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmplan.replay import Recording

# Agents still: a speed below this (m/s) at the end of the log is a hover at the last point.
STILL_SPEED = 1e-6


class ExportError(Exception):
    """The log or the request cannot be exported: one line for the user (exit 2)."""


class LimitError(Exception):
    """A trajectory cannot be exported within the agent's limits at the asked accuracy (exit 2):
    the message says what would fit."""


@dataclass(frozen=True)
class AgentLimits:
    """One agent's parameters from the log's ``/world`` (agent keys over ``agent_defaults``)."""

    id: str
    model: str  # multirotor, fixed_wing
    radius: float
    speed_min: float
    speed_max: float
    speed_cruise: float
    max_accel: float
    min_turn_radius: float
    max_climb_angle_deg: float
    separation: tuple[float, float, float]


@dataclass(frozen=True)
class FlownPath:
    """One agent's flown path: ``times`` (K,) from the log's t = 0, ``positions`` (K, 3), from its
    first recorded step to the last step it moved (it hovers there after)."""

    limits: AgentLimits
    times: np.ndarray
    positions: np.ndarray
    arrived: bool

    @property
    def start_time(self) -> float:
        return float(self.times[0])

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])


def agent_limits(world: dict[str, Any], agent_id: str) -> AgentLimits:
    """The resolved parameters of ``agent_id`` in a ``/world`` message."""
    defaults = world.get("agent_defaults") or {}
    entry = next((a for a in world.get("agents") or [] if str(a.get("id")) == agent_id), {})
    merged = {**defaults, **entry}
    speed = {**(defaults.get("speed") or {}), **(entry.get("speed") or {})}
    sep = merged.get("separation") or [0.0, 0.0, 0.0]
    return AgentLimits(
        id=agent_id,
        model=str(merged.get("model", "multirotor")),
        radius=float(merged.get("radius", 0.0)),
        speed_min=float(speed.get("min", 0.0)),
        speed_max=float(speed.get("max", 0.0)),
        speed_cruise=float(speed.get("cruise", 0.0)),
        max_accel=float(merged.get("max_accel", 0.0)),
        min_turn_radius=float(merged.get("min_turn_radius", 0.0)),
        max_climb_angle_deg=float(merged.get("max_climb_angle", 0.0)),
        separation=tuple(float(s) for s in sep[:3]),  # type: ignore[arg-type]
    )


def check_log(rec: Recording) -> None:
    """Refuse a log an export cannot stand on: cut short, without agents or without two steps."""
    if rec.truncated or rec.summary is None:
        raise ExportError(
            f"{rec.file}: the log was cut short (no /summary; e.g. the run was killed):"
            " its flight is not complete, nothing exported"
        )
    if not rec.agent_ids:
        raise ExportError(f"{rec.file}: the log has no agents")
    if rec.n_steps < 2:
        raise ExportError(f"{rec.file}: the log has {rec.n_steps} step(s); an export needs at least two")


def select_agents(rec: Recording, wanted: list[str] | None) -> list[str]:
    """The agents to export, in the log's order (``wanted`` checked against the log)."""
    if not wanted:
        return list(rec.agent_ids)
    for aid in wanted:
        if aid not in rec.agent_ids:
            raise ExportError(f"--agent {aid}: no such agent in the log (agents: {', '.join(rec.agent_ids)})")
    return [aid for aid in rec.agent_ids if aid in wanted]


def flown_path(rec: Recording, agent_id: str) -> FlownPath:
    """The agent's flown path: its recorded steps up to the last one it moved (a hover at the end
    is the trajectory's end, held by the vehicle)."""
    i = rec.agent_index(agent_id)
    ok = np.flatnonzero(np.isfinite(rec.positions[i]).all(axis=1))
    if len(ok) < 2:
        raise ExportError(f"agent {agent_id}: fewer than two recorded positions")
    first, last = int(ok[0]), int(ok[-1])
    pos = rec.positions[i, first : last + 1]
    times = np.asarray(rec.times, float)[first : last + 1]
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1) / np.diff(times)
    moving = np.flatnonzero(step > STILL_SPEED)
    end = int(moving[-1]) + 2 if len(moving) else 2
    arrived = bool(np.isin(rec.modes[i].astype(str), ("arrived",)).any())
    return FlownPath(agent_limits(rec.world, agent_id), times[:end], pos[:end], arrived)


def tolerance_of(world: dict[str, Any]) -> float:
    """The world's goal tolerance (m)."""
    return float((world.get("sim") or {}).get("goal_tolerance", 0.0) or 0.0)
