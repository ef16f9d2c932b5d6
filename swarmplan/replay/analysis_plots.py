"""Analysis plots of a recorded run: curvature along each path, optimizer convergence."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .metrics import active_mask, curvature_over, curvature_series, fixed_wing_turn_limit
from .plots import _mode_runs, _select, _title, agent_colors, new_figure
from .recording import Recording

CURVATURE_WINDOW = 1.0
"""Seconds of flight the plotted curvature line is taken over (see ``curvature_over``)."""


def plot_curvature(rec: Recording, agents: list[str] | None = None, fig: Figure | None = None):
    """Curvature of each flown path vs time: a line over :data:`CURVATURE_WINDOW` seconds of
    flight (the turn over the distance), the discrete per-step values (same definition as the
    metrics) as faint dots; a dashed line at each fixed wing's limit (1 / min_turn_radius).

    A step-by-step path may alternate turns at its limit with straight steps, which per step
    reads as noise between 0 and the limit; the line shows the turn it flies. A cusp (a
    turn-back, curvature orders of magnitude above the rest) would flatten every other curve
    on a linear axis, so the axis is clipped at 1.5 times the 98th percentile of all values and
    every value above it is marked by a triangle at the top edge (its value in the legend).
    """
    fig = fig or new_figure(figsize=(10, 5))
    ax = fig.add_subplot()
    colors = agent_colors(rec.n_agents)
    active = active_mask(rec)
    idx = _select(rec, agents)
    series, lines = [], []
    for i in idx:
        pts = np.where(active[i][:, None], rec.positions[i], np.nan)
        series.append(curvature_series(pts, rec.times))
        lines.append(curvature_over(pts, rec.times, CURVATURE_WINDOW))
    limits = sorted({v for i in idx if (v := fixed_wing_turn_limit(rec, i)) is not None})
    values = np.concatenate([k[np.isfinite(k)] for _t, k in series] or [np.zeros(0)])
    top = None
    if len(values):
        cap = 1.5 * float(np.percentile(values, 98))
        if cap > 0 and values.max() > cap:
            top = max(cap, 1.1 * max(limits, default=0.0))
    n_cusps, worst = 0, 0.0
    for i, (t, k), (tw, kw) in zip(idx, series, lines, strict=True):
        aid = rec.agent_ids[i]
        ax.plot(
            t, k if top is None else np.minimum(k, top), color=colors[i], marker=".", ms=2, ls="none",
            alpha=0.35, gid=f"step:{aid}"
        )  # fmt: skip
        ax.plot(
            tw, kw if top is None else np.minimum(kw, top), color=colors[i], lw=1.4, label=aid,
            gid=f"path:{aid}"
        )  # fmt: skip
        if top is not None:
            over = np.isfinite(k) & (k > top)
            if over.any():
                edge = np.full(over.sum(), top)
                ax.plot(t[over], edge, marker="^", ms=8, color=colors[i], mec="k", ls="none",
                        clip_on=False, zorder=5, gid=f"cusp:{aid}")  # fmt: skip
                n_cusps += int(over.sum())
                worst = max(worst, float(k[over].max()))
        for a, b, mode in _mode_runs(rec.modes[i], np.ones(rec.n_steps, bool)):
            if mode == "escape":
                ax.axvspan(rec.times[a], rec.times[b], color=colors[i], alpha=0.08, lw=0)
    for v in limits:
        ax.axhline(v, color="0.3", ls="--", lw=1.0, gid=f"limit:{v:g}", label=f"fixed-wing limit {v:.3g} 1/m")
    handles, _labels = ax.get_legend_handles_labels()
    if top is not None:
        ax.set_ylim(0, top * 1.02)
        handles.append(
            Line2D([], [], marker="^", color="0.5", mec="k", ms=8, ls="none",
                   label=f"cusp: {n_cusps} value(s) above {top:.3g} 1/m (max {worst:.3g})")
        )  # fmt: skip
    ax.set_xlabel("time [s]")
    ax.set_ylabel("curvature [1/m]" + ("  (clipped)" if top is not None else ""))
    ax.grid(alpha=0.3)
    if len(idx) <= 20:
        ax.legend(
            handles=handles[:21], fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0
        )
    ax.set_title(
        f"{_title(rec)} - path curvature (line: over {CURVATURE_WINDOW:g} s; dots: per step; shaded: escape)",
        fontsize=10,
    )
    return fig


def plot_convergence(rec: Recording, agents: list[str] | None = None, fig: Figure | None = None):
    """Best cost per iteration of every optimizer run recorded on /optimizer."""
    fig = fig or new_figure(figsize=(10, 5))
    ax = fig.add_subplot()
    runs = rec.optimizer_runs
    if agents is not None:
        runs = [r for r in runs if str(r.get("agent")) in set(agents)]
    colors = agent_colors(rec.n_agents)
    styles = {"escape": "-", "smoothing": "--", "global": ":"}
    labels = {"escape": "escape", "smoothing": "smoothing", "global": "global plan"}
    used: list[str] = []
    positive = True
    drawn = 0
    for r in runs:
        conv = np.asarray(r.get("convergence") or [], float)
        if not len(conv):
            continue
        aid = str(r.get("agent"))
        col = colors[rec.agent_ids.index(aid)] if aid in rec.agent_ids else "0.4"
        purpose = str(r.get("purpose"))
        if purpose not in used:
            used.append(purpose)
        ax.plot(
            np.arange(1, len(conv) + 1),
            conv,
            color=col,
            ls=styles.get(purpose, "-."),
            lw=1.0,
            alpha=0.8,
            gid=f"run:{aid}:{r.get('purpose')}:{r.get('t')}",
        )
        positive &= bool(np.all(conv[np.isfinite(conv)] > 0))
        drawn += 1
    finite = [np.asarray(r.get("convergence") or [], float) for r in runs]
    finite = np.concatenate([c[np.isfinite(c)] for c in finite] or [np.zeros(0)])
    # Log scale only where it helps: costs spanning more than a decade.
    if drawn and positive and len(finite) and finite.max() > 10 * finite.min():
        ax.set_yscale("log")
    handles = [
        Line2D([], [], color="0.3", ls=styles.get(p, "-."), label=labels.get(p, p))
        for p in sorted(used, key=lambda p: (p not in styles, list(styles).index(p) if p in styles else 0, p))
    ]
    shown_agents = sorted({str(r.get("agent")) for r in runs}, key=lambda a: (a not in rec.agent_ids, a))
    for aid in shown_agents[:12]:
        if aid in rec.agent_ids:
            handles.append(Line2D([], [], color=colors[rec.agent_ids.index(aid)], label=aid))
    if handles:
        ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    algos = sorted({str(r.get("algorithm")) for r in runs}) or ["-"]
    ax.set_xlabel("iteration")
    ax.set_ylabel("best cost")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(
        f"optimizer convergence: {drawn} run{'' if drawn == 1 else 's'} ({', '.join(algos)})", fontsize=10
    )
    if not drawn:
        ax.text(0.5, 0.5, "no optimizer runs recorded", transform=ax.transAxes, ha="center", va="center")
    return fig
