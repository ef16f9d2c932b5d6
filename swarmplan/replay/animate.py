"""Animated playback of a recorded run: GIF (Pillow) or MP4 (when ffmpeg is installed).

Frames are subsampled from the recorded steps (``fps``, ``max_frames``, ``speed``) so a
long run still renders in seconds; a progress bar (tqdm) is shown on stderr while rendering
(the command line shows it only when stderr is a terminal).
"""

from __future__ import annotations

import math
import shutil
import sys
from collections.abc import Callable

import numpy as np
from matplotlib.collections import PatchCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon

from . import plots
from .metrics import active_mask
from .recording import Recording

# Agent marker edge (colour, width) by mode: the face keeps the agent's colour, so the edge
# must not look like another agent (no tab10 colours).
MODE_EDGE = {
    "apf": ("black", 1.0),
    "escape": ("black", 3.0),
    "smoothing": ("#ffd700", 3.0),
    "arrived": ("white", 1.5),
    "collided": ("#ff00ff", 3.0),
    "failed": ("0.6", 3.0),
}
MODE_EDGE_LABEL = {
    "apf": "flying (APF)",
    "escape": "escaping",
    "smoothing": "smoothing",
    "arrived": "arrived",
    "collided": "collided",
    "failed": "failed",
}


def frame_steps(
    rec: Recording, fps: float = 10.0, max_frames: int = 150, speed: float | None = None
) -> np.ndarray:
    """Indices of the recorded steps to draw, evenly spaced in time."""
    if rec.n_steps == 0:
        return np.zeros(0, int)
    n = rec.n_steps
    if speed is not None and speed > 0 and rec.duration > 0:
        n = int(math.ceil(rec.duration / speed * fps)) + 1
    n = max(1, min(n, int(max_frames), rec.n_steps))
    targets = np.linspace(rec.times[0], rec.times[-1], n)
    steps = np.searchsorted(rec.times, targets).clip(0, rec.n_steps - 1)
    return np.unique(steps)


def animation_figure(
    rec: Recording, agents: list[str] | None = None, dpi: int = 80, trail: float = 10.0
) -> tuple[Figure, Callable[[int], None]]:
    """The animation's figure and ``draw(k)``, which puts it at recorded step ``k``."""
    idx = plots._select(rec, agents)  # noqa: SLF001
    colors = plots.agent_colors(rec.n_agents)
    active = active_mask(rec)
    fig = plots.new_figure(figsize=(9.5, 7), dpi=dpi)
    # static background (bounds, terrain, static obstacles, faint full paths)
    stub = Recording(**{**rec.__dict__, "world": {**rec.world, "obstacles": rec.static_obstacles}})
    plots.plot_top(stub, agents=[rec.agent_ids[i] for i in idx], fig=fig)
    ax = fig.axes[0]
    for line in list(ax.lines):
        gid = line.get_gid() or ""
        if gid.startswith(("path:", "mode:")):
            line.set_alpha(0.15)
            line.set_path_effects([])
    title = ax.set_title("")
    # the legend of the stub lacks what only moves: moving obstacles and the agents' modes
    used_modes = {m for m in ("escape", "smoothing", "collided", "failed") if (rec.modes == m).any()}
    handles = plots.legend_handles(rec, idx, colors, used_modes, bool(rec.moving_obstacles), tracks=False)
    for mode, label in MODE_EDGE_LABEL.items():
        if mode == "apf" or (rec.modes[idx] == mode).any():
            col, width = MODE_EDGE[mode]
            handles.append(
                Line2D(
                    [],
                    [],
                    marker="o",
                    ls="none",
                    color="0.8",
                    mec=col,
                    mew=width,
                    ms=8,
                    label=f"agent {label}",
                )
            )
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=7)
    fig.subplots_adjust(left=0.08, right=0.7, bottom=0.08, top=0.93)  # frames are not "tight": room for it
    # moving obstacles: one patch collection, redrawn each frame
    moving = rec.moving_obstacles
    mov_coll = PatchCollection(
        [], facecolor=plots.MOVING_COLOR, edgecolor="0.2", alpha=0.75, zorder=5, hatch=plots.MOVING_HATCH
    )
    ax.add_collection(mov_coll)
    trails = {i: ax.plot([], [], color=colors[i], lw=2.0, zorder=6)[0] for i in idx}
    # agents as fixed-size markers (real radii are invisible at world scale); edge = mode
    pts = ax.scatter(
        np.zeros(len(idx)),
        np.zeros(len(idx)),
        s=np.full(len(idx), 40.0),
        c=[colors[i] for i in idx],
        edgecolors="k",
        linewidths=1.5,
        zorder=7,
    )
    n_trail = max(1, int(round(trail / max(rec.dt, 1e-9))))

    def draw(k: int):
        t = rec.times[k]
        patches, faces = [], []
        for m, o in enumerate(moving):
            oid = o.get("id")
            if oid in rec.obstacle_tracks:
                p, q = rec.obstacle_poses(oid, np.array([t]))
                polys = plots._footprint(o, p[0], q[0])  # noqa: SLF001
            else:
                polys = plots._footprint(o)  # noqa: SLF001
            patches += [Polygon(poly, closed=True) for poly in polys]
            faces += [plots.mover_color(m)] * len(polys)
        mov_coll.set_paths(patches)
        mov_coll.set_facecolors(faces)
        xy, edge = [], []
        for i in idx:
            P = rec.positions[i, : k + 1]
            lo = max(0, k + 1 - n_trail)
            tr = P[lo:][active[i, lo : k + 1]]
            trails[i].set_data(tr[:, 0], tr[:, 1])
            xy.append(P[-1, :2] if np.isfinite(P[-1, 0]) else [np.nan, np.nan])
            edge.append(MODE_EDGE.get(rec.modes[i, k], ("black", 1.0)))
        pts.set_offsets(np.asarray(xy))
        pts.set_edgecolors([e[0] for e in edge])
        pts.set_linewidths([e[1] for e in edge])
        counts = {}
        for i in idx:
            counts[rec.modes[i, k]] = counts.get(rec.modes[i, k], 0) + 1
        modes = ", ".join(f"{m} {c}" for m, c in sorted(counts.items()))
        title.set_text(f"{rec.world.get('name', '?')}  t = {t:6.2f} s   {modes}")
        title.set_fontsize(9)

    return fig, draw


def animate(
    rec: Recording,
    out: str,
    fps: float = 10.0,
    max_frames: int = 150,
    speed: float | None = None,
    agents: list[str] | None = None,
    dpi: int = 80,
    trail: float = 10.0,
    progress: bool = True,
) -> str:
    """Render a top-view playback to ``out`` (.gif, or .mp4 when ffmpeg exists). Returns the path
    actually written (a .mp4 request without ffmpeg falls back to .gif, with a notice)."""
    out = str(out)
    if not out.lower().endswith((".gif", ".mp4")):
        raise ValueError(f"{out}: unsupported animation type; use .gif or .mp4")
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps:g}")
    if int(max_frames) < 1:
        raise ValueError(f"max_frames must be >= 1, got {max_frames}")
    want_mp4 = out.lower().endswith(".mp4")
    if want_mp4 and shutil.which("ffmpeg") is None:
        out = out[:-4] + ".gif"
        print(f"notice: ffmpeg not found, writing {out} instead", file=sys.stderr)
        want_mp4 = False
    steps = frame_steps(rec, fps, max_frames, speed)
    if not len(steps):
        raise ValueError("nothing to animate: no recorded steps")

    fig, draw = animation_figure(rec, agents, dpi, trail)
    from tqdm import tqdm

    bar = tqdm(total=len(steps), desc="rendering", unit="frame", file=sys.stderr, disable=not progress)
    if want_mp4:
        from matplotlib.animation import FFMpegWriter

        writer = FFMpegWriter(fps=fps)
        with writer.saving(fig, out, dpi):
            for k in steps:
                draw(int(k))
                writer.grab_frame()
                bar.update()
    else:
        from PIL import Image

        frames = []
        for k in steps:
            draw(int(k))
            fig.canvas.draw()
            img = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[:, :, :3])
            frames.append(img.quantize(colors=128, method=Image.Quantize.MEDIANCUT))
            bar.update()
        frames[0].save(out, save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    bar.close()
    return out
