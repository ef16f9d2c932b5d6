"""Outputs of a tracking run: an MCAP log of the tracked flight, and a plot.

The log follows the run-log contract (shared/spec/log-format.md) with the *tracked* states
on ``/agents/state`` (so ``python -m swarmplan.replay`` and Foxglove show the quadrotor's
flight), plus:

- ``/tracking`` (JSON, every recorded step): per tracked agent the reference and tracked
  position, the error, tilt, thrust and whether the reference is flyable at that instant;
- ``/tracking/scene`` (``foxglove.SceneUpdate``, once at t = 0): the reference path of each
  tracked agent as a dashed-looking thin line, so Foxglove's 3D panel shows it next to the
  flown path (``/scene/paths``).

States are written at the recorded step times only (obstacle poses are not known beyond
them), so the settle hover after the log's end is in the metrics and the plot, not in the file.
Fixed-wing agents are written with their tracked states while in flight (the recorded ones
before and after); agents without a vehicle model (skipped) keep their recorded states.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan.io.recording import McapRecorder
from swarmplan.replay import Recording

from .tracking import TrackResult

TRACKING_TOPIC = "/tracking"
TRACKING_SCENE_TOPIC = "/tracking/scene"
TRACKING_SCHEMA: dict[str, Any] = {
    "title": "swarmplan.Tracking",
    "type": "object",
    "required": ["t", "agents"],
    "properties": {
        "t": {"type": "number"},
        "agents": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["id", "reference", "tracked", "error_m"],
                "properties": {
                    "id": {"type": "string"},
                    "reference": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                    "tracked": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                    "error_m": {"type": "number"},
                    "tilt_deg": {"type": "number"},
                    "thrust_n": {"type": "number"},
                    "reference_feasible": {"type": "boolean"},
                },
            },
        },
    },
}

PLOT_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg")


class _TrackingRecorder(McapRecorder):
    """The run recorder plus the tracking channels."""

    def __init__(self, path: str | Path) -> None:
        super().__init__(path, foxglove=True)
        self.add_json_channel(TRACKING_TOPIC, TRACKING_SCHEMA)

    def write_tracking(self, t: float, agents: list[dict[str, Any]]) -> None:
        self.write_json(TRACKING_TOPIC, t, {"t": round(t, 9), "agents": agents})

    def write_reference_scene(self, paths: dict[str, np.ndarray]) -> None:
        from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

        from swarmplan.io.foxglove_scene import FRAME, file_descriptor_set

        self.add_protobuf_channel(
            TRACKING_SCENE_TOPIC, "foxglove.SceneUpdate", file_descriptor_set(SceneUpdate).SerializeToString()
        )
        msg = SceneUpdate()
        for aid, pts in paths.items():
            ent = msg.entities.add()
            ent.frame_id = FRAME
            ent.id = f"reference/{aid}"
            ent.frame_locked = False
            line = ent.lines.add()
            line.type = 0  # LINE_STRIP
            line.thickness = 0.15
            line.scale_invariant = False
            line.color.r, line.color.g, line.color.b, line.color.a = 0.85, 0.1, 0.1, 0.9
            line.pose.orientation.w = 1.0
            for p in pts:
                q = line.points.add()
                q.x, q.y, q.z = (float(c) for c in p)
        self.write_bytes(TRACKING_SCENE_TOPIC, 0.0, msg.SerializeToString())


def _interp(grid: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """values (A, K, d) on ``grid`` -> (A, len(t), d) at ``t``."""
    out = np.empty((values.shape[0], len(t), values.shape[2]))
    for a in range(values.shape[0]):
        for d in range(values.shape[2]):
            out[a, :, d] = np.interp(t, grid, values[a, :, d])
    return out


def write_mcap(result: TrackResult, rec: Recording, path: str | Path, source: str) -> None:
    """The tracked flight as a run log (see the module docstring)."""
    start = time.perf_counter()
    times = np.asarray(rec.times, float)
    grid = result.ref.times
    idx = {aid: a for a, aid in enumerate(result.ids)}
    tp = _interp(grid, result.flight.pos, times)
    tv = _interp(grid, result.flight.vel, times)
    rp = _interp(grid, result.ref.pos, times)
    err = np.linalg.norm(tp - rp, axis=2)
    tilt = _interp(grid, result.flight.tilt_deg[..., None], times)[..., 0]
    thrust = _interp(grid, result.flight.thrust[..., None], times)[..., 0]
    k_grid = np.clip(np.searchsorted(grid, times), 0, len(grid) - 1)
    feasible = ~result.infeasible[:, k_grid]
    world = dict(rec.world)
    world["tracker"] = result.cfg.to_dict()
    world["tracked_from"] = source
    moving = list(rec.moving_obstacles)
    with _TrackingRecorder(path) as out:
        out.write_world(world)
        out.write_reference_scene(
            {aid: result.ref.pos[a, :: max(1, len(grid) // 2000)] for aid, a in idx.items()}
        )
        for k, t in enumerate(times):
            agents = []
            for i, aid in enumerate(rec.agent_ids):
                a = idx.get(aid)
                f = result.fixed_wing.get(aid)
                if a is None and f is not None and f.times[0] <= t <= f.times[-1]:
                    position = [float(np.interp(t, f.times, f.pos[:, j])) for j in range(3)]
                    velocity = [float(np.interp(t, f.times, f.vel[:, j])) for j in range(3)]
                elif a is None:  # skipped: the recorded state as it was
                    p = rec.positions[i, k]
                    if not np.isfinite(p).all():
                        continue
                    position, velocity = p.tolist(), np.nan_to_num(rec.velocities[i, k]).tolist()
                else:
                    position, velocity = tp[a, k].tolist(), tv[a, k].tolist()
                agents.append(
                    {
                        "id": aid,
                        "position": position,
                        "velocity": velocity,
                        "mode": str(rec.modes[i, k]) or "apf",
                        "goal": rec.goals[i].tolist(),
                    }
                )
            obstacles = None
            if moving:
                obstacles = []
                for o in moving:
                    op, oq = rec.obstacle_poses(str(o["id"]), np.array([t]))
                    obstacles.append(
                        {"id": str(o["id"]), "position": op[0].tolist(), "orientation": oq[0].tolist()}
                    )
            out.write_state(float(t), agents, obstacles)
            out.write_tracking(
                float(t),
                [
                    {
                        "id": aid,
                        "reference": rp[a, k].tolist(),
                        "tracked": tp[a, k].tolist(),
                        "error_m": float(err[a, k]),
                        "tilt_deg": float(tilt[a, k]),
                        "thrust_n": float(thrust[a, k]),
                        "reference_feasible": bool(feasible[a, k]),
                    }
                    for aid, a in idx.items()
                ],
            )
        for aid in idx:
            for t0 in result.agents[aid].infeasible_at:
                out.write_event(
                    {
                        "t": min(t0, float(times[-1])),
                        "agent": aid,
                        "kind": "tracking_infeasible_reference",
                        "detail": {"needs_more_than": "thrust-to-weight or tilt limit"},
                    }
                )
        summary_agents = []
        for i, aid in enumerate(rec.agent_ids):
            final = str(rec.modes[i, -1])
            entry: dict[str, Any] = {"id": aid, "arrived": final == "arrived"}
            if aid in result.fixed_wing:
                entry.update(result.fixed_wing[aid].to_json())
            elif aid in idx:
                entry.update(result.agents[aid].to_json())
                p = tp[idx[aid]]
                entry["path_length"] = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
                entry["final_distance_to_goal"] = float(np.linalg.norm(p[-1] - rec.goals[i]))
            else:
                entry["skipped"] = result.skipped.get(aid, "not selected")
            summary_agents.append(entry)
        out.write_summary(
            {
                "interrupted": False,
                "success": all(e["arrived"] for e in summary_agents),
                "wall_time": time.perf_counter() - start,
                "sim_time": float(times[-1]),
                "agents": summary_agents,
                "source": source,
                "kind": "tracking",
            }
        )


def plot(result: TrackResult, path: str | Path, title: str = "", rec: Recording | None = None) -> None:
    """Reference vs tracked paths in 3D, and the error over time, one colour per agent; with the
    log's ``rec``, among the world's obstacles and terrain, within its bounds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 5.5))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    cmap = plt.get_cmap("tab10")
    t = result.ref.times
    step = max(1, len(t) // 3000)
    for a, aid in enumerate(result.ids):
        c = cmap(a % 10)
        r, f = result.ref.pos[a, ::step], result.flight.pos[a, ::step]
        ax3.plot(r[:, 0], r[:, 1], r[:, 2], "--", color=c, lw=1.0, alpha=0.8)
        ax3.plot(f[:, 0], f[:, 1], f[:, 2], "-", color=c, lw=1.6, alpha=0.9, label=aid)
        bad = np.flatnonzero(result.infeasible[a])
        if len(bad):
            p = result.ref.pos[a, bad]
            ax3.scatter(p[:, 0], p[:, 1], p[:, 2], color=c, marker="x", s=25)
        m = result.agents[aid]
        ax2.plot(
            t[::step], result.error[a, ::step], color=c, lw=1.2, label=f"{aid} (max {m.max_error_m:.2f} m)"
        )
        if len(bad):
            ax2.scatter(t[bad], result.error[a, bad], color=c, marker="x", s=12)
    for b, (aid, f) in enumerate(result.fixed_wing.items()):
        c = cmap((len(result.ids) + b) % 10)
        step_f = max(1, len(f.times) // 3000)
        r, p = f.ref_pos[::step_f], f.pos[::step_f]
        ax3.plot(r[:, 0], r[:, 1], r[:, 2], "--", color=c, lw=1.0, alpha=0.8)
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], "-", color=c, lw=1.6, alpha=0.9, label=f"{aid} (fixed wing)")
        j = f.to_json()
        ax2.plot(
            f.times[::step_f],
            f.error[::step_f],
            color=c,
            lw=1.2,
            label=f"{aid} (max {j['max_error_m']:.2f} m, bank {j['max_bank_deg']:.0f} deg)",
        )
    if result.ids:
        ax2.axhline(1.2, color="k", ls=":", lw=1, label="1.2 m (paper 004)")
    for lim in sorted({round(f.error_limit_m, 3) for f in result.fixed_wing.values()}):
        ax2.axhline(lim, color="0.4", ls="-.", lw=1, label=f"{lim:g} m (fixed-wing limit)")
    if result.record_end < t[-1]:
        ax2.axvspan(result.record_end, t[-1], color="0.9", label="settle hover")
    if rec is not None:
        from swarmplan.replay.plots import world_in_3d

        world_in_3d(ax3, rec)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title("reference (dashed) vs tracked (solid); x = infeasible reference")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("tracking error [m]")
    ax2.set_title("error over time")
    ax2.grid(alpha=0.3)
    if result.ids or result.fixed_wing:
        ax3.legend(loc="upper left", fontsize=8)
        ax2.legend(loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
