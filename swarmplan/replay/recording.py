"""Load a swarmplan run log (MCAP) into numpy arrays.

Only the JSON analysis channels of the log contract (shared/spec/log-format.md) are
decoded: ``/world``, ``/agents/state``, ``/obstacles/state``, ``/events``,
``/optimizer`` and ``/summary``. Foxglove channels are skipped. A file cut short by a
hard kill (no summary section, no footer) is read by streaming up to its last complete
chunk and flagged ``truncated``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

TOPICS = ("/world", "/agents/state", "/obstacles/state", "/events", "/optimizer", "/summary", "/comms")
MODES = ("apf", "escape", "smoothing", "arrived", "collided", "failed")


class RecordingError(Exception):
    """The file cannot be read as a swarmplan run log."""


# Simulation times are multiples of dt computed in floating point (40.800000000000004); they
# are rounded to this many decimals on reading, far below any dt, so they print and compare
# as the step grid they are.
TIME_DECIMALS = 9


@dataclass(frozen=True)
class Event:
    """One ``/events`` message: at time ``t`` (s, on the step grid), ``agent`` (None for the
    whole run) had an event of ``kind`` with ``detail`` (the contract's event fields)."""

    t: float
    agent: str | None
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_json(cls, msg: dict[str, Any], dt: float | None = None) -> Event:
        t = float(msg.get("t", math.nan))
        agent = msg.get("agent")
        detail = msg.get("detail")
        return cls(
            snap_time(t, dt),
            None if agent is None else str(agent),
            str(msg.get("kind")),
            dict(detail) if isinstance(detail, dict) else {},
        )

    def to_json(self) -> dict[str, Any]:
        return {"t": self.t, "agent": self.agent, "kind": self.kind, "detail": dict(self.detail)}


def snap_time(t: float, dt: float | None) -> float:
    """``t`` on the step grid (the nearest multiple of ``dt`` when within 1e-6 s of one), rounded."""
    if dt and math.isfinite(t):
        k = round(t / dt)
        if abs(t - k * dt) < 1e-6:
            t = k * dt
    return round(t, TIME_DECIMALS) if math.isfinite(t) else t


def _world_dt(world: dict[str, Any]) -> float | None:
    try:
        dt = float((world.get("sim") or {}).get("dt"))
    except (TypeError, ValueError):
        return None
    return dt if dt > 0 and math.isfinite(dt) else None


@dataclass
class ObstacleTrack:
    """Pose of one moving obstacle over time (its own sample times)."""

    id: str
    times: np.ndarray  # (K,)
    positions: np.ndarray  # (K, 3)
    orientations: np.ndarray  # (K, 4) quaternions [qx, qy, qz, qw]

    def at(self, times: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Positions (linear interpolation) and orientations (nearest sample) at ``times``.

        A scalar time gives shapes (3,) and (4,); an array of K times (K, 3) and (K, 4).
        """
        if len(self.times) == 0:
            raise ValueError(f"obstacle {self.id}: empty track")
        scalar = np.ndim(times) == 0
        t = np.atleast_1d(np.asarray(times, float))
        pos = np.stack([np.interp(t, self.times, self.positions[:, i]) for i in range(3)], axis=1)
        idx = np.clip(np.searchsorted(self.times, t), 0, len(self.times) - 1)
        prev = np.clip(idx - 1, 0, len(self.times) - 1)
        use_prev = np.abs(self.times[prev] - t) < np.abs(self.times[idx] - t)
        idx = np.where(use_prev, prev, idx)
        quat = self.orientations[idx]
        return (pos[0], quat[0]) if scalar else (pos, quat)


@dataclass
class Recording:
    """Everything a run log holds, as arrays. Agent axis first: ``positions[a, k]``."""

    file: str  # the log's path
    world: dict[str, Any]
    times: np.ndarray  # (T,) simulation time of each /agents/state step, s
    agent_ids: list[str]
    positions: np.ndarray  # (A, T, 3), NaN where an agent is absent from a step
    velocities: np.ndarray  # (A, T, 3)
    modes: np.ndarray  # (A, T) str ('' where absent)
    goals: np.ndarray  # (A, 3)
    radii: np.ndarray  # (A,)
    obstacle_tracks: dict[str, ObstacleTrack] = field(default_factory=dict)
    events: list[Event] = field(default_factory=list)
    optimizer_runs: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] | None = None
    truncated: bool = False
    topic_counts: dict[str, int] = field(default_factory=dict)
    comms: list[dict[str, Any]] = field(default_factory=list)  # the /comms messages (worlds with comms)

    # ------------------------------------------------------------------ helpers
    @property
    def n_agents(self) -> int:
        return len(self.agent_ids)

    @property
    def n_steps(self) -> int:
        return len(self.times)

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0]) if len(self.times) else 0.0

    @property
    def world_dt(self) -> float | None:
        """``sim.dt`` of the recorded world, when it has one."""
        return _world_dt(self.world)

    @property
    def dt(self) -> float:
        """Step of the recording: the world's ``sim.dt`` when the recorded steps follow it, else
        the median recorded step (rounded like the times)."""
        wdt = self.world_dt
        if len(self.times) < 2:
            return wdt or 0.0
        step = float(np.median(np.diff(self.times)))
        if wdt is not None and abs(step - wdt) <= 1e-6 * max(1.0, wdt):
            return wdt
        return round(step, TIME_DECIMALS)

    @property
    def goal_tolerance(self) -> float:
        return float((self.world.get("sim") or {}).get("goal_tolerance", 0.0) or 0.0)

    @property
    def interrupted(self) -> bool:
        return bool(self.summary and self.summary.get("interrupted"))

    def agent_index(self, agent_id: str) -> int:
        try:
            return self.agent_ids.index(str(agent_id))
        except ValueError:
            raise KeyError(f"no agent {agent_id!r} (agents: {', '.join(self.agent_ids)})") from None

    def step_at(self, t: float) -> int:
        """Index of the recorded step nearest to time ``t``."""
        if not len(self.times):
            raise ValueError("recording has no steps")
        return int(np.argmin(np.abs(self.times - float(t))))

    @property
    def obstacles(self) -> list[dict[str, Any]]:
        """Every obstacle of the recorded world (resolved dicts, as in ``/world``)."""
        return list(self.world.get("obstacles") or [])

    @property
    def static_obstacles(self) -> list[dict[str, Any]]:
        return [o for o in self.obstacles if not o.get("motion")]

    @property
    def moving_obstacles(self) -> list[dict[str, Any]]:
        return [o for o in self.obstacles if o.get("motion")]

    def obstacle_poses(self, oid: str, times: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (K,3) and quaternions (K,4) of obstacle ``oid`` at ``times`` (default: steps).

        Static obstacles (or moving ones without a recorded track) give their world pose.
        """
        t = self.times if times is None else np.atleast_1d(np.asarray(times, float))
        track = self.obstacle_tracks.get(oid)
        if track is not None and len(track.times):
            return track.at(t)
        obst = next((o for o in self.obstacles if o.get("id") == oid), None)
        if obst is None:
            raise KeyError(f"no obstacle {oid!r}")
        from .geometry import euler_deg_to_quat

        pos = np.tile(np.asarray(obst.get("position", [0, 0, 0]), float), (len(t), 1))
        quat = np.tile(euler_deg_to_quat(obst.get("rotation") or [0, 0, 0]), (len(t), 1))
        return pos, quat


# ---------------------------------------------------------------------- reading


def _read_indexed(path: str) -> dict[str, list[tuple[int, bytes]]]:
    from mcap.reader import make_reader

    out: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages(topics=list(TOPICS), log_time_order=False):
            out.setdefault(channel.topic, []).append((message.log_time, message.data))
    return out


def _read_streaming(path: str) -> dict[str, list[tuple[int, bytes]]]:
    """Read every complete record; stop silently at the first incomplete one."""
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    out: dict[str, list[tuple[int, bytes]]] = {}
    topics: dict[int, str] = {}
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f, skip_magic=False).records:
                if isinstance(rec, Channel):
                    topics[rec.id] = rec.topic
                elif isinstance(rec, Message):
                    topic = topics.get(rec.channel_id)
                    if topic in TOPICS:
                        out.setdefault(topic, []).append((rec.log_time, rec.data))
        except Exception:  # noqa: BLE001 - a cut file ends with a partial record
            pass
    return out


def _decode(items: list[tuple[int, bytes]]) -> list[dict[str, Any]]:
    res = []
    for _log_time, data in items:
        try:
            msg = json.loads(data)
        except ValueError:
            continue
        if isinstance(msg, dict):
            res.append(msg)
    return res


def load(path: str | Path) -> Recording:
    """Read a run log. Raises :class:`RecordingError` when it is not a readable swarmplan log."""
    path = str(path)
    if not Path(path).is_file():
        raise RecordingError(f"{path}: no such file")
    truncated = False
    try:
        raw = _read_indexed(path)
    except Exception:  # noqa: BLE001 - missing footer/summary: try streaming
        truncated = True
        try:
            raw = _read_streaming(path)
        except Exception as exc:  # noqa: BLE001
            raise RecordingError(f"{path}: not an MCAP file ({exc})") from None
    if not raw:
        with open(path, "rb") as f:
            head = f.read(8)
        if not head.startswith(b"\x89MCAP"):
            raise RecordingError(f"{path}: not an MCAP file")
        if truncated:
            raise RecordingError(
                f"{path}: cut short before its first complete chunk (e.g. the run was hard-killed"
                " at its start): no swarmplan message to read"
            )
        raise RecordingError(f"{path}: no swarmplan channels ({', '.join(TOPICS)}) found")
    if "/world" not in raw:
        raise RecordingError(f"{path}: no /world message (not a swarmplan run log?)")
    worlds = _decode(raw["/world"])
    if not worlds:
        raise RecordingError(f"{path}: /world message is not a JSON object")
    world = worlds[0]

    states = _decode(raw.get("/agents/state", []))
    states.sort(key=lambda m: float(m.get("t", 0.0)))
    agent_ids = [str(a["id"]) for a in world.get("agents") or [] if "id" in a]
    for msg in states:
        for a in msg.get("agents", []):
            if str(a.get("id")) not in agent_ids:
                agent_ids.append(str(a.get("id")))
    index = {aid: i for i, aid in enumerate(agent_ids)}
    n_a, n_t = len(agent_ids), len(states)
    world_dt = _world_dt(world)
    times = np.round(np.array([float(m.get("t", math.nan)) for m in states], float), TIME_DECIMALS)
    positions = np.full((n_a, n_t, 3), np.nan)
    velocities = np.full((n_a, n_t, 3), np.nan)
    modes = np.full((n_a, n_t), "", dtype=object)
    goals = np.full((n_a, 3), np.nan)
    radii = np.zeros(n_a)
    defaults = world.get("agent_defaults") or {}
    for a in world.get("agents") or []:
        i = index.get(str(a.get("id")))
        if i is None:
            continue
        if a.get("goal") is not None:
            goals[i] = np.asarray(a["goal"], float)[:3]
        radii[i] = float(a.get("radius", defaults.get("radius", 0.0)) or 0.0)
    full_order = list(agent_ids)
    nan3 = [math.nan] * 3
    for k, msg in enumerate(states):
        agents = msg.get("agents", [])
        ids_k = [str(a.get("id")) for a in agents]
        if ids_k == full_order and agents:  # fast path: every agent, in world order
            positions[:, k] = [(a.get("position") or nan3)[:3] for a in agents]
            velocities[:, k] = [(a.get("velocity") or nan3)[:3] for a in agents]
            modes[:, k] = [str(a.get("mode", "")) for a in agents]
        else:
            for aid, a in zip(ids_k, agents, strict=True):
                i = index[aid]
                positions[i, k] = (a.get("position") or nan3)[:3]
                velocities[i, k] = (a.get("velocity") or nan3)[:3]
                modes[i, k] = str(a.get("mode", ""))
    for i in np.flatnonzero(np.isnan(goals).any(axis=1)):  # goals missing from /world
        for msg in states:
            a = next((a for a in msg.get("agents", []) if str(a.get("id")) == agent_ids[i]), None)
            if a is not None and a.get("goal") is not None:
                goals[i] = np.asarray(a["goal"], float)[:3]
                break
    modes = modes.astype(str)

    tracks: dict[str, dict[str, list]] = {}
    for msg in _decode(raw.get("/obstacles/state", [])):
        t = round(float(msg.get("t", math.nan)), TIME_DECIMALS)
        for o in msg.get("obstacles", []):
            tr = tracks.setdefault(str(o.get("id")), {"t": [], "p": [], "q": []})
            tr["t"].append(t)
            tr["p"].append(o.get("position", [math.nan] * 3)[:3])
            tr["q"].append((o.get("orientation") or [0.0, 0.0, 0.0, 1.0])[:4])
    obstacle_tracks = {}
    for oid, tr in tracks.items():
        order = np.argsort(np.asarray(tr["t"], float), kind="stable")
        obstacle_tracks[oid] = ObstacleTrack(
            oid,
            np.asarray(tr["t"], float)[order],
            np.asarray(tr["p"], float).reshape(-1, 3)[order],
            np.asarray(tr["q"], float).reshape(-1, 4)[order],
        )

    events = [Event.from_json(e, world_dt) for e in _decode(raw.get("/events", []))]
    events.sort(key=lambda e: e.t)
    optimizer_runs = _decode(raw.get("/optimizer", []))
    optimizer_runs.sort(key=lambda e: float(e.get("t", 0.0)))
    summaries = _decode(raw.get("/summary", []))
    return Recording(
        file=path,
        world=world,
        times=times,
        agent_ids=agent_ids,
        positions=positions,
        velocities=velocities,
        modes=modes,
        goals=goals,
        radii=radii,
        obstacle_tracks=obstacle_tracks,
        events=events,
        optimizer_runs=optimizer_runs,
        summary=summaries[-1] if summaries else None,
        truncated=truncated,
        topic_counts={k: len(v) for k, v in raw.items()},
        comms=_decode(raw.get("/comms", [])),
    )
