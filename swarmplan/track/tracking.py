"""Fly the agents of a recorded run with a vehicle model and measure the tracking error: multirotors
with the quadrotor model (``quadrotor.py``), fixed wings with the coordinated-turn aircraft
(``fixed_wing.py``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarmplan.replay import Recording
from swarmplan.world.tracker_config import G, TrackerConfig

from .fixed_wing import FixedWingConfig, FixedWingFlight, aircraft_of, fly
from .quadrotor import Flight, simulate
from .reference import Reference, build_reference, feasibility, fill_gaps

# Samples closer than this to an infeasible instant are excluded from the diagnostic
# ``max_error_away_from_infeasible_m`` (never from ``max_error_m``): about the time the
# position loop needs to recover (4 / (damping * natural frequency) of the default loop).
RECOVERY_S = 2.0


@dataclass(frozen=True)
class AgentTrack:
    """Tracking result of one multirotor agent."""

    id: str
    max_error_m: float
    rms_error_m: float
    time_of_max_error_s: float
    max_tilt_deg: float
    max_thrust_n: float
    max_thrust_to_weight: float
    saturated_s: float  # time with the thrust or tilt limit active
    reference_feasible: bool
    infeasible_s: float  # time the reference asks for more than the vehicle has
    infeasible_at: tuple[float, ...]  # start time of each infeasible stretch
    max_reference_accel: float  # m/s^2
    max_error_away_from_infeasible_m: float | None  # max error > RECOVERY_S from any infeasible instant
    max_error_vs_recorded_m: float  # max distance to the recorded positions, at the recorded times

    def to_json(self) -> dict[str, Any]:
        return {
            "max_error_m": round(self.max_error_m, 4),
            "rms_error_m": round(self.rms_error_m, 4),
            "max_tilt_deg": round(self.max_tilt_deg, 2),
            "max_thrust_n": round(self.max_thrust_n, 3),
            "max_thrust_to_weight": round(self.max_thrust_to_weight, 3),
            "time_of_max_error_s": round(self.time_of_max_error_s, 3),
            "saturated_s": round(self.saturated_s, 3),
            "reference_feasible": self.reference_feasible,
            "infeasible_s": round(self.infeasible_s, 3),
            "infeasible_at": [round(t, 3) for t in self.infeasible_at],
            "max_reference_accel": round(self.max_reference_accel, 2),
            "max_error_away_from_infeasible_m": None
            if self.max_error_away_from_infeasible_m is None
            else round(self.max_error_away_from_infeasible_m, 4),
            "max_error_vs_recorded_m": round(self.max_error_vs_recorded_m, 4),
            "skipped": None,
        }


@dataclass(frozen=True)
class TrackResult:
    """Everything one tracking run produced; agent axis of the arrays follows ``ids``."""

    cfg: TrackerConfig
    ids: tuple[str, ...]  # tracked (multirotor) agents
    skipped: dict[str, str]  # agent id -> reason
    ref: Reference
    flight: Flight
    infeasible: np.ndarray  # (A, K) bool
    error: np.ndarray  # (A, K) m
    agents: dict[str, AgentTrack]
    record_end: float  # last recorded time (the settle hold follows it)
    fixed_wing: dict[str, FixedWingFlight] = field(default_factory=dict)  # agent id -> tracked flight

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {aid: {"model": "multirotor", **self.agents[aid].to_json()} for aid in self.ids}
        for aid, f in self.fixed_wing.items():
            out[aid] = f.to_json()
        for aid, reason in self.skipped.items():
            out[aid] = {"max_error_m": None, "rms_error_m": None, "max_tilt_deg": None, "skipped": reason}
        return {"agents": out}


FLYING_MODES = ("apf", "escape", "smoothing")
"""Modes in which a log can end with the agent still on its way (timeout, interruption)."""


def agent_max_accel(world: dict[str, Any], agent_id: str) -> float:
    """The agent's ``max_accel`` in the log's /world (5 m/s^2, the world format's default, if absent)."""
    defaults = world.get("agent_defaults") or {}
    for a in world.get("agents") or []:
        if str(a.get("id")) == agent_id and a.get("max_accel"):
            return float(a["max_accel"])
    return float(defaults.get("max_accel") or 5.0)


def agent_model(world: dict[str, Any], agent_id: str) -> str:
    defaults = world.get("agent_defaults") or {}
    for a in world.get("agents") or []:
        if str(a.get("id")) == agent_id:
            return str(a.get("model") or defaults.get("model") or "multirotor")
    return str(defaults.get("model") or "multirotor")


def _stretch_starts(mask: np.ndarray, times: np.ndarray, gap: float = 0.5) -> tuple[float, ...]:
    """Start time of each infeasible stretch; stretches less than ``gap`` s apart count as one
    (a spline rings over a few samples around one bad recorded step)."""
    bad = np.flatnonzero(mask)
    if not len(bad):
        return ()
    t = times[bad]
    keep = np.concatenate([[True], np.diff(t) > gap])
    return tuple(float(x) for x in t[keep])


def _fixed_wing_window(rec: Recording, i: int) -> tuple[int, int]:
    """First and last recorded step of fixed wing ``i`` in flight: up to the step before its
    arrival or its end (an arrived or collided agent's last step has zero velocity)."""
    ok = np.flatnonzero(np.isfinite(rec.positions[i]).all(axis=1))
    first, last = int(ok[0]), int(ok[-1])
    modes = rec.modes[i]
    done = np.flatnonzero(np.isin(modes.astype(str), ("arrived", "collided", "failed")))
    if len(done):
        last = min(last, int(done[0]) - 1)
    return first, last


def track(
    rec: Recording, cfg: TrackerConfig, agent: str | None = None, fixed_cfg: FixedWingConfig | None = None
) -> TrackResult:
    """Fly every agent of ``rec`` (or only ``agent``) along its recorded trajectory: multirotors
    with the quadrotor, fixed wings with the coordinated-turn aircraft (``fixed_cfg``).

    Raises ``KeyError`` for an unknown ``agent`` and ``ValueError`` when the log has fewer
    than two steps.
    """
    ids = list(rec.agent_ids) if agent is None else [rec.agent_ids[rec.agent_index(agent)]]
    skipped: dict[str, str] = {}
    chosen: list[int] = []
    fixed: list[int] = []
    for aid in ids:
        model = agent_model(rec.world, aid)
        i = rec.agent_index(aid)
        if not np.isfinite(rec.positions[i]).all(axis=1).any():
            skipped[aid] = "no recorded position"
        elif model == "fixed_wing":
            fixed.append(i)
        elif model != "multirotor":
            skipped[aid] = f"{model} agent: no vehicle model for it"
        else:
            chosen.append(i)
    if rec.n_steps < 2:
        raise ValueError(f"{rec.file}: the log has {rec.n_steps} step(s); tracking needs at least two")
    fixed_cfg = FixedWingConfig() if fixed_cfg is None else fixed_cfg
    flights: dict[str, FixedWingFlight] = {}
    for i in fixed:
        aid = rec.agent_ids[i]
        a, b = _fixed_wing_window(rec, i)
        if b - a < 2:
            skipped[aid] = "fewer than three recorded steps in flight"
            continue
        t_rec = np.asarray(rec.times, float)[a : b + 1]
        flights[aid] = fly(t_rec, rec.positions[i, a : b + 1], aircraft_of(rec.world, aid), fixed_cfg, rec.dt)
    times = np.asarray(rec.times, float)
    pos = fill_gaps(times, rec.positions[chosen])
    vel = np.nan_to_num(rec.velocities[chosen][:, [0, -1]])
    # Settle hold: a vehicle still moving when the log ends has to stop somewhere. An agent the
    # log ends as arrived (or collided, failed) stops at its last recorded position, so hovering
    # there shows that stop (and its overshoot) instead of cutting it off. An agent still flying
    # (the run timed out or was interrupted) was not asked to stop there: its reference goes on
    # at its last velocity and brakes at its own max_accel, then hovers.
    if cfg.settle_time > 0 and chosen:
        h = rec.dt
        v_end = (pos[:, -1] - pos[:, -2]) / max(float(times[-1] - times[-2]), 1e-9)
        flying = np.array([str(rec.modes[i][-1]) in FLYING_MODES for i in chosen])
        v_end[~flying] = 0.0
        a_brake = np.array([agent_max_accel(rec.world, rec.agent_ids[i]) for i in chosen])
        speed = np.linalg.norm(v_end, axis=1)
        t_stop = speed / a_brake
        n_hold = int(np.ceil((cfg.settle_time + t_stop.max()) / max(h, 1e-9)))
        tau = np.minimum(h * np.arange(1, n_hold + 1)[None, :], t_stop[:, None])  # (A, n)
        u = v_end / np.maximum(speed, 1e-12)[:, None]
        along = speed[:, None] * tau - 0.5 * a_brake[:, None] * tau**2
        times = np.concatenate([times, times[-1] + h * np.arange(1, n_hold + 1)])
        pos = np.concatenate([pos, pos[:, -1:] + along[..., None] * u[:, None, :]], axis=1)
        vel[:, -1] = 0.0
    if chosen:
        ref = build_reference(times, pos, vel, cfg.dt, cfg.reference)
    else:  # nothing to fly (only fixed wings): empty arrays keep one result shape
        empty = np.zeros((0, 1, 3))
        ref = Reference(times[:1], empty, empty, empty)
    infeasible = feasibility(ref, cfg)
    flight = simulate(ref, cfg)
    error = np.linalg.norm(flight.pos - ref.pos, axis=2)
    dt = cfg.dt
    agents: dict[str, AgentTrack] = {}
    recovery = int(round(RECOVERY_S / dt))
    rec_t = np.asarray(rec.times, float)
    rec_pos = fill_gaps(rec_t, rec.positions[chosen]) if chosen else np.zeros((0, len(rec_t), 3))
    for a, i in enumerate(chosen):
        aid = rec.agent_ids[i]
        near = np.zeros(len(ref.times), bool)
        bad = np.flatnonzero(infeasible[a])
        if len(bad):
            # every sample within RECOVERY_S of an infeasible one: dilate by a running window
            hit = np.zeros(len(ref.times) + 1, int)
            np.add.at(hit, np.clip(bad - recovery, 0, None), 1)
            np.add.at(hit, np.clip(bad + recovery + 1, None, len(ref.times)), -1)
            near = np.cumsum(hit)[:-1] > 0
        away = error[a][~near]
        k = int(np.argmax(error[a]))
        flown = np.column_stack([np.interp(rec_t, ref.times, flight.pos[a, :, j]) for j in range(3)])
        vs_recorded = float(np.linalg.norm(flown - rec_pos[a], axis=1).max())
        agents[aid] = AgentTrack(
            id=aid,
            max_error_m=float(error[a].max()),
            rms_error_m=float(np.sqrt(np.mean(error[a] ** 2))),
            time_of_max_error_s=float(ref.times[k]),
            max_tilt_deg=float(flight.tilt_deg[a].max()),
            max_thrust_n=float(flight.thrust[a].max()),
            max_thrust_to_weight=float(flight.thrust[a].max() / (cfg.mass * G)),
            saturated_s=float(flight.saturated[a].sum() * dt),
            reference_feasible=not bool(len(bad)),
            infeasible_s=float(len(bad) * dt),
            infeasible_at=_stretch_starts(infeasible[a], ref.times),
            max_reference_accel=float(np.linalg.norm(ref.acc[a], axis=1).max()),
            max_error_away_from_infeasible_m=float(away.max()) if len(away) else None,
            max_error_vs_recorded_m=vs_recorded,
        )
    return TrackResult(
        cfg=cfg,
        ids=tuple(rec.agent_ids[i] for i in chosen),
        skipped=skipped,
        ref=ref,
        flight=flight,
        infeasible=infeasible,
        error=error,
        agents=agents,
        record_end=float(rec.times[-1]),
        fixed_wing=flights,
    )
