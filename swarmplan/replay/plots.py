"""Static plots of a recorded run (matplotlib, Agg canvas, no pyplot global state).

Every ``plot_*`` function returns a :class:`matplotlib.figure.Figure`; :func:`save`
writes it. Each agent's path artists carry ``gid = "path:<agent id>"`` so callers (and
tests) can find them: :func:`agent_paths_in` lists the agents drawn in a figure.

Colours: each agent has its own colour everywhere, also along its escape (a thick line
outlined in black) and smoothing segments (a translucent halo); obstacles are grey,
moving ones hatched in dark colours no agent gets (one per mover, its track dashed in the same
colour, drawn at one pose that the legend states: the last recorded one unless a step is
asked for); threats are red markers with a filled core (``r_min``) and a dotted outer ring
(``r_max``), and path points inside a core are red crosses. Starts are squares (the
animation's agents are circles), goals stars. Terrain contours carry their heights.
Legends sit outside the axes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib import patheffects
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Polygon

from swarmplan.geometry import bodies

from .geometry import euler_deg_to_matrix, quat_to_matrix, terrain_height
from .metrics import active_mask
from .recording import Recording

# Mode segments are drawn over the agent's path in the agent's own colour ("color": None) or
# in a fixed colour; the style alone tells the mode.
MODE_STYLE = {
    "escape": {"color": None, "lw": 3.5, "outline": True, "label": "escape (optimizer)"},
    "smoothing": {"color": None, "lw": 8.0, "alpha": 0.3, "zorder": 2, "label": "smoothing (halo)"},
    "collided": {"color": "black", "lw": 3.0, "label": "collided"},
    "failed": {"color": "#7f7f7f", "lw": 2.0, "ls": ":", "label": "failed"},
}
OBSTACLE_COLOR = np.array([0.55, 0.58, 0.65])
MOVING_COLOR = np.array([0.10, 0.30, 0.30])  # dark teal: not in the tab10/tab20 agent palettes
# one per mover (then repeated): dark, unlike the agents' tab10/tab20 colours
MOVING_COLORS = ("#1a4d4d", "#5c3a1e", "#3d1f5c", "#4d4d00", "#0d2b52", "#5c1f3d")
START_MARKER = "s"
MOVING_HATCH = "////"
THREAT_COLOR = "#b00020"
THREAT_MARKERS = {"radar": "^", "missile": "X", "artillery": "s", "weather": "o"}
MAX_MESH_FACES = 4000
# A mode segment shorter than this fraction of the scene's size is also marked by a dot, so a
# one-step segment stays visible.
SHORT_SEGMENT = 0.02


def new_figure(figsize=(9, 7), dpi=100) -> Figure:
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def save(fig: Figure, path: str) -> str:
    # "tight" keeps the legends placed outside the axes inside the image.
    fig.savefig(path, bbox_inches="tight")
    return str(path)


def agent_colors(n: int) -> list:
    from matplotlib import colormaps

    cmap = colormaps["tab10" if n <= 10 else "tab20" if n <= 20 else "turbo"]
    if n <= 20:
        return [cmap(i % cmap.N) for i in range(n)]
    return [cmap(x) for x in np.linspace(0.05, 0.95, n)]


def agent_paths_in(fig: Figure) -> list[str]:
    """Agent ids whose path is drawn in ``fig`` (each once, in drawing order)."""
    seen: list[str] = []
    for ax in fig.axes:
        for art in list(ax.lines) + list(ax.collections):
            gid = art.get_gid() or ""
            if gid.startswith("path:") and gid[5:] not in seen:
                seen.append(gid[5:])
    return seen


def _select(rec: Recording, agents: list[str] | None) -> list[int]:
    if agents is None:
        return list(range(rec.n_agents))
    return [rec.agent_index(a) for a in agents]


def _mode_runs(modes: np.ndarray, valid: np.ndarray):
    """(start, stop_inclusive, mode) runs of equal mode over valid steps."""
    runs = []
    k, n = 0, len(modes)
    while k < n:
        if not valid[k]:
            k += 1
            continue
        j = k
        while j + 1 < n and valid[j + 1] and modes[j + 1] == modes[k]:
            j += 1
        runs.append((k, j, modes[k]))
        k = j + 1
    return runs


# ---------------------------------------------------------------------- shapes


def obstacle_mesh(obst: dict[str, Any], position=None, quat=None):
    """(vertices (N,3) world, faces (M,3)) of an obstacle at a pose (default: its world pose)."""
    shape = obst.get("shape")
    if shape == "mesh":
        if "vertices" not in obst:
            return None
        v = np.asarray(obst["vertices"], float)
        f = np.asarray(obst["faces"], int)
        if position is not None:  # moving mesh: vertices are the pose at t = 0
            c0 = np.asarray(obst.get("position", [0, 0, 0]), float)
            r0 = euler_deg_to_matrix(obst.get("rotation") or [0, 0, 0])
            r = quat_to_matrix(quat) if quat is not None else r0
            v = (v - c0) @ r0 @ r.T + np.asarray(position, float)
        return v, f
    s = bodies.BY_NAME.get(str(shape))
    if s is None or s.code < 0:
        return None
    values = dict(obst)
    if "height" not in values and "length" in values:  # older logs name a capsule's height so
        values["height"] = values["length"]
    m = s.surface(values)
    c = np.asarray(obst.get("position", [0, 0, 0]) if position is None else position, float)
    r = quat_to_matrix(quat) if quat is not None else euler_deg_to_matrix(obst.get("rotation") or [0, 0, 0])
    return np.asarray(m.vertices) @ r.T + c, np.asarray(m.faces)


def _shaded(v, f, base, alpha):
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-12
    light = np.array([0.4, 0.3, 0.85])
    light /= np.linalg.norm(light)
    k = 0.45 + 0.55 * np.abs(n @ light)
    cols = np.clip(base[None, :] * k[:, None], 0, 1)
    return np.concatenate([cols, np.full((len(cols), 1), alpha)], axis=1)


def _draw_obstacle_3d(ax, obst, position=None, quat=None, color=OBSTACLE_COLOR, alpha=0.55, label=None):
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    mesh = obstacle_mesh(obst, position, quat)
    if mesh is None:
        return None
    v, f = mesh
    if len(f) > MAX_MESH_FACES:
        f = f[np.linspace(0, len(f) - 1, MAX_MESH_FACES).astype(int)]
    coll = Poly3DCollection(v[f], facecolors=_shaded(v, f, np.asarray(color), alpha), edgecolors="none")
    coll.set_gid(f"obstacle:{obst.get('id')}")
    if label:
        coll.set_label(label)
    ax.add_collection3d(coll)
    return coll


def _bounds(rec: Recording):
    b = rec.world.get("bounds") or {}
    lo = np.asarray(b.get("min", np.nanmin(rec.positions, axis=(0, 1))), float)
    hi = np.asarray(b.get("max", np.nanmax(rec.positions, axis=(0, 1))), float)
    return lo, hi


def _bounds_edges(lo, hi):
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    edges = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.count_nonzero(corners[i] != corners[j]) == 1:
                edges.append((corners[i], corners[j]))
    return edges


# ---------------------------------------------------------------------- 3D


def plot_3d(
    rec: Recording, agents: list[str] | None = None, step: int | None = None, fig: Figure | None = None
):
    """3D view: bounds, terrain, obstacles, moving-obstacle tracks, paths by mode, starts, goals."""
    import mpl_toolkits.mplot3d  # noqa: F401 - registers the 3d projection

    fig = fig or new_figure()
    ax = fig.add_subplot(projection="3d")
    lo, hi = _bounds(rec)
    for a, b in _bounds_edges(lo, hi):
        ax.plot(*np.stack([a, b]).T, color="0.6", lw=0.6, ls=":")
    _terrain_3d(ax, rec, lo, hi)
    for obst in rec.static_obstacles:
        _draw_obstacle_3d(ax, obst)
    for m, obst in enumerate(rec.moving_obstacles):
        oid = obst.get("id")
        col = mover_color(m)
        if oid in rec.obstacle_tracks:
            tr = rec.obstacle_tracks[oid]
            ax.plot(*tr.positions.T, color=col, ls="--", lw=1.2, gid=f"track:{oid}")
            k = -1 if step is None else int(np.argmin(np.abs(tr.times - rec.times[step])))
            _draw_obstacle_3d(ax, obst, tr.positions[k], tr.orientations[k], col, 0.6)
        else:
            _draw_obstacle_3d(ax, obst, color=col)
    _threats_3d(ax, rec)
    idx = _select(rec, agents)
    colors = agent_colors(rec.n_agents)
    active = active_mask(rec)
    used_modes = set()
    for i in idx:
        _draw_path(ax, rec, i, colors[i], active[i], used_modes, three_d=True)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ext = np.maximum(hi - lo, 1e-9)
    ax.set_box_aspect((ext[0], ext[1], max(ext[2], 0.25 * max(ext[0], ext[1]))))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    _legend(ax, rec, idx, colors, used_modes, bool(rec.moving_obstacles), mover_time(rec, step))
    ax.set_title(_title(rec))
    return fig


def world_in_3d(ax, rec: Recording) -> None:
    """The world's bounds (as the axes' limits, true aspect), terrain and static obstacles on a 3D
    axes, for plots of other tools (``python -m swarmplan.track``)."""
    lo, hi = _bounds(rec)
    _terrain_3d(ax, rec, lo, hi)
    for obst in rec.static_obstacles:
        _draw_obstacle_3d(ax, obst)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ext = np.maximum(hi - lo, 1e-9)
    ax.set_box_aspect((ext[0], ext[1], max(ext[2], 0.25 * max(ext[0], ext[1]))))


def mover_color(m: int) -> np.ndarray:
    """The colour (RGB) of the ``m``-th moving obstacle (its body and its track)."""
    from matplotlib.colors import to_rgb

    return np.array(to_rgb(MOVING_COLORS[m % len(MOVING_COLORS)]))


def mover_time(rec: Recording, step: int | None) -> float:
    """The time at which the moving obstacles are drawn: the step's, or the last recorded."""
    if step is not None and rec.n_steps:
        return float(rec.times[step])
    ends = [float(tr.times[-1]) for tr in rec.obstacle_tracks.values() if len(tr.times)]
    return max(ends) if ends else (float(rec.times[-1]) if rec.n_steps else 0.0)


def inside_cores(rec: Recording, i: int, valid: np.ndarray) -> np.ndarray:
    """Agent ``i``'s recorded positions (K, 3) inside some threat's core (r_min)."""
    P = rec.positions[i][valid]
    inside = np.zeros(len(P), bool)
    for th in _threats(rec):
        r = float(th.get("r_min") or 0.0)
        inside |= np.linalg.norm(P - np.asarray(th["position"], float), axis=1) < r
    return P[inside]


def _threats(rec: Recording) -> list[dict[str, Any]]:
    return [t for t in rec.world.get("threats") or [] if t.get("position") is not None]


def _threats_3d(ax, rec: Recording) -> None:
    """Threat centres as markers, and their r_min ring in the horizontal plane of the centre."""
    ang = np.linspace(0, 2 * np.pi, 48)
    for k, th in enumerate(_threats(rec)):
        c = np.asarray(th["position"], float)
        ax.plot(
            [c[0]],
            [c[1]],
            [c[2]],
            marker=THREAT_MARKERS.get(th.get("kind"), "P"),
            color=THREAT_COLOR,
            mec="k",
            ms=8,
            ls="none",
            gid=f"threat:{k}",
        )
        r = float(th.get("r_min") or 0.0)
        if r > 0:
            ax.plot(c[0] + r * np.cos(ang), c[1] + r * np.sin(ang), np.full_like(ang, c[2]),
                    color=THREAT_COLOR, lw=1.0, alpha=0.8)  # fmt: skip
        r = float(th.get("r_max") or 0.0)
        if r > 0:
            ax.plot(c[0] + r * np.cos(ang), c[1] + r * np.sin(ang), np.full_like(ang, c[2]),
                    color=THREAT_COLOR, lw=0.8, ls=":", alpha=0.6)  # fmt: skip


def _threats_top(ax, rec: Recording) -> None:
    """Threat centres as markers, a translucent core out to r_min and a dotted ring at r_max."""
    for k, th in enumerate(_threats(rec)):
        c = np.asarray(th["position"], float)[:2]
        r_min, r_max = float(th.get("r_min") or 0.0), float(th.get("r_max") or 0.0)
        if r_min > 0:
            ax.add_patch(Circle(c, r_min, fc=THREAT_COLOR, ec=THREAT_COLOR, alpha=0.18, lw=1.0, zorder=1.5))
        if r_max > r_min:
            ax.add_patch(Circle(c, r_max, fill=False, ec=THREAT_COLOR, ls=":", lw=0.8, alpha=0.6, zorder=1.5))
        ax.plot(
            *c,
            marker=THREAT_MARKERS.get(th.get("kind"), "P"),
            color=THREAT_COLOR,
            mec="k",
            ms=8,
            ls="none",
            zorder=6,
            gid=f"threat:{k}",
        )


def _terrain_3d(ax, rec, lo, hi, n=40):
    if not (rec.world.get("terrain") or {}).get("peaks"):
        return
    xs, ys = np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)
    X, Y = np.meshgrid(xs, ys)
    Z = terrain_height(rec.world, np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(X.shape)
    top = max(float(Z.max()), 1e-9)
    ax.plot_surface(
        X,
        Y,
        Z,
        cmap="terrain",
        vmin=-0.3 * top,
        vmax=top,
        alpha=0.35,
        linewidth=0,
        antialiased=False,
        gid="terrain",
    )


def _draw_path(ax, rec, i, color, active, used_modes, three_d):
    aid = rec.agent_ids[i]
    P = rec.positions[i]
    valid = np.isfinite(P[:, 0]) & active
    last = np.flatnonzero(valid)
    if not len(last):
        return
    coords = (lambda Q: Q.T) if three_d else (lambda Q: Q[:, :2].T)
    lo, hi = _bounds(rec)
    short = SHORT_SEGMENT * float(np.linalg.norm(hi - lo))
    # nominal path in the agent's colour, then mode segments on top
    ax.plot(*coords(P[valid]), color=color, lw=1.4, gid=f"path:{aid}", zorder=3)
    for a, b, mode in _mode_runs(rec.modes[i], valid):
        style = MODE_STYLE.get(mode)
        if style is None:
            continue
        seg = P[max(a - 1, 0) : b + 2][valid[max(a - 1, 0) : b + 2]]
        if len(seg) < 2:
            seg = P[a : b + 1]
        col = color if style["color"] is None else style["color"]
        effects = [patheffects.withStroke(linewidth=style["lw"] + 1.6, foreground="k")]
        ax.plot(
            *coords(seg),
            color=col,
            lw=style["lw"],
            ls=style.get("ls", "-"),
            alpha=style.get("alpha", 0.95),
            gid=f"mode:{mode}:{aid}",
            zorder=style.get("zorder", 4),
            solid_capstyle="round",
            path_effects=effects if style.get("outline") else None,
        )
        if path_length_of(seg) < short:  # too short to see at this scale: mark it
            ax.plot(
                *coords(seg[len(seg) // 2][None]),
                marker="o",
                ms=style["lw"] + 3,
                color=col,
                alpha=max(style.get("alpha", 0.95), 0.6),
                mec="k" if style.get("outline") else "none",
                ls="none",
                zorder=style.get("zorder", 4),
                gid=f"mode-dot:{mode}:{aid}",
            )
        used_modes.add(mode)
    core = inside_cores(rec, i, valid)
    if len(core):
        ax.plot(*coords(core), marker="x", color=THREAT_COLOR, ms=5, ls="none", gid=f"core:{aid}", zorder=5)
        used_modes.add("core")
    s, g = P[last[0]], rec.goals[i]
    ax.plot(*coords(s[None]), marker=START_MARKER, color=color, ms=6, mec="k", ls="none", gid=f"start:{aid}",
            zorder=6)  # fmt: skip
    ax.plot(*coords(g[None]), marker="*", color=color, ms=12, mec="k", ls="none", gid=f"goal:{aid}", zorder=6)


def path_length_of(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()) if len(points) > 1 else 0.0


def legend_handles(
    rec, idx, colors, used_modes, moving: bool, tracks: bool = True, at: float | None = None
) -> list[Line2D]:
    """Legend entries: agents, the modes drawn, start/goal, obstacles, moving obstacles, threats."""
    from matplotlib.patches import Patch

    handles = []
    max_agents = 12
    for i in idx[:max_agents]:
        handles.append(Line2D([], [], color=colors[i], lw=2, label=rec.agent_ids[i]))
    if len(idx) > max_agents:
        handles.append(Line2D([], [], color="none", label=f"... {len(idx) - max_agents} more agents"))
    for mode in ("escape", "smoothing", "collided", "failed"):
        if mode in used_modes:
            st = MODE_STYLE[mode]
            effects = [patheffects.withStroke(linewidth=st["lw"] + 1.6, foreground="k")]
            handles.append(
                Line2D(
                    [],
                    [],
                    color=st["color"] or "0.45",
                    lw=st["lw"],
                    ls=st.get("ls", "-"),
                    alpha=st.get("alpha", 0.95),
                    path_effects=effects if st.get("outline") else None,
                    label=st["label"] + (" (agent colour)" if st["color"] is None else ""),
                )
            )
    if "core" in used_modes:
        handles.append(
            Line2D([], [], marker="x", color=THREAT_COLOR, ls="none", label="inside a threat core")
        )
    handles.append(Line2D([], [], marker=START_MARKER, color="0.5", mec="k", ls="none", label="start"))
    handles.append(Line2D([], [], marker="*", color="0.5", mec="k", ms=12, ls="none", label="goal"))
    if rec.static_obstacles:
        handles.append(Patch(fc=OBSTACLE_COLOR, ec="0.3", label="obstacle"))
    if moving:
        where = "" if at is None else f" at t = {at:.1f} s" + (" (last pose)" if at >= rec.duration else "")
        for m, obst in enumerate(rec.moving_obstacles[:6]):
            handles.append(
                Patch(fc=mover_color(m), ec="0.3", hatch=MOVING_HATCH, alpha=0.75,
                      label=f"moving obstacle {obst.get('id')}{where}")
            )  # fmt: skip
        if tracks:
            handles.append(Line2D([], [], color="0.3", ls="--", label="moving obstacle track (its colour)"))
    kinds = []
    for th in _threats(rec):
        if th.get("kind") not in kinds:
            kinds.append(th.get("kind"))
    for kind in kinds:
        handles.append(
            Line2D([], [], marker=THREAT_MARKERS.get(kind, "P"), color=THREAT_COLOR, mec="k", ms=8, ls="none",
                   label=f"threat: {kind} (core r_min)")
        )  # fmt: skip
    if kinds:
        handles.append(Line2D([], [], color=THREAT_COLOR, ls=":", lw=0.8, label="threat outer ring (r_max)"))
    return handles


def _legend(ax, rec, idx, colors, used_modes, moving, at=None):
    # Outside the axes, so it never hides a start, a goal or a path.
    ax.legend(
        handles=legend_handles(rec, idx, colors, used_modes, moving, at=at),
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize=7,
        framealpha=0.9,
    )


def _title(rec: Recording) -> str:
    w = rec.world
    opt = (rec.summary or {}).get("optimizer") or ((w.get("planner") or {}).get("optimizer") or {}).get(
        "name", "?"
    )
    extra = " [TRUNCATED LOG]" if rec.truncated else (" [interrupted]" if rec.interrupted else "")
    return f"{w.get('name', '?')} (seed {w.get('seed', '?')}, {opt}), t = 0..{rec.duration:.1f} s{extra}"


# ---------------------------------------------------------------------- 2D top view


def _footprint(obst, position=None, quat=None):
    """Polygons (list of (K,2) arrays) of the obstacle seen from above."""
    mesh = obstacle_mesh(obst, position, quat)
    if mesh is None:
        return []
    v, f = mesh
    if obst.get("shape") == "mesh":
        if len(f) > MAX_MESH_FACES:
            f = f[np.linspace(0, len(f) - 1, MAX_MESH_FACES).astype(int)]
        return [v[t][:, :2] for t in f]
    from scipy.spatial import ConvexHull

    pts = v[:, :2]
    try:
        hull = ConvexHull(pts)
    except Exception:  # noqa: BLE001 - degenerate (flat) footprint
        return [pts]
    return [pts[hull.vertices]]


def plot_top(
    rec: Recording, agents: list[str] | None = None, step: int | None = None, fig: Figure | None = None
):
    """Top view (x-y): bounds, terrain contours, obstacle footprints, tracks, paths by mode."""
    fig = fig or new_figure(figsize=(10, 8))
    ax = fig.add_subplot()
    lo, hi = _bounds(rec)
    ax.add_patch(
        Polygon([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]], fill=False, ls=":")
    )
    if (rec.world.get("terrain") or {}).get("peaks"):
        xs, ys = np.linspace(lo[0], hi[0], 80), np.linspace(lo[1], hi[1], 80)
        X, Y = np.meshgrid(xs, ys)
        Z = terrain_height(rec.world, np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(X.shape)
        top = max(float(Z.max()), 1e-9)
        levels = np.linspace(0.05 * top, top, 10)
        ax.contourf(
            X, Y, Z, levels=levels, cmap="terrain", vmin=-0.3 * top, vmax=top, alpha=0.35, extend="neither"
        )
        lines = ax.contour(X, Y, Z, levels=levels, colors="0.5", linewidths=0.4)
        ax.clabel(lines, lines.levels[::2], fmt="%.0f m", fontsize=6, inline=True)
    for obst in rec.static_obstacles:
        for poly in _footprint(obst):
            ax.add_patch(Polygon(poly, closed=True, fc=OBSTACLE_COLOR, ec="0.3", alpha=0.7, lw=0.5))
    for m, obst in enumerate(rec.moving_obstacles):
        oid = obst.get("id")
        tr = rec.obstacle_tracks.get(oid)
        if tr is not None and len(tr.times):
            ax.plot(
                tr.positions[:, 0],
                tr.positions[:, 1],
                color=mover_color(m),
                ls="--",
                lw=1.2,
                gid=f"track:{oid}",
            )
            k = -1 if step is None else int(np.argmin(np.abs(tr.times - rec.times[step])))
            polys = _footprint(obst, tr.positions[k], tr.orientations[k])
        else:
            polys = _footprint(obst)
        for poly in polys:
            ax.add_patch(
                Polygon(poly, closed=True, fc=mover_color(m), ec="0.2", alpha=0.6, lw=0.5, hatch=MOVING_HATCH)
            )
    _threats_top(ax, rec)
    idx = _select(rec, agents)
    colors = agent_colors(rec.n_agents)
    active = active_mask(rec)
    used_modes = set()
    for i in idx:
        _draw_path(ax, rec, i, colors[i], active[i], used_modes, three_d=False)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    _legend(ax, rec, idx, colors, used_modes, bool(rec.moving_obstacles), mover_time(rec, step))
    ax.set_title(_title(rec) + " - top view", fontsize=10)
    return fig


# The analysis plots (curvature, convergence) are in analysis_plots.py.
