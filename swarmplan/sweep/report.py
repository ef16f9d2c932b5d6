"""Tables in the papers' style, Wilcoxon rank-sum verdicts and box plots from a sweep's rows.

Each group of rows (one world and one combination of override values) gives one table: a line
per optimizer with mean ± std over its seeds, and a verdict against the first optimizer:
``+`` significantly lower (better) than it, ``-`` significantly higher, ``=`` no significant
difference (scipy ``ranksums``, p >= alpha). Error rows count as runs but give no metrics.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

#: (column, header, number format) of the tables.
STATS = [
    ("path_length_mean", "length m", "{:.1f}"),
    ("path_ratio_mean", "length ratio", "{:.3f}"),
    ("curvature_mean", "curvature 1/m", "{:.4f}"),
    ("arrival_time_mean", "arrival s", "{:.1f}"),
    ("planning_ms", "planning ms", "{:.0f}"),
    ("plan_cost", "plan cost", "{:.4g}"),
]
#: Columns that get a verdict against the first optimizer (lower is better for all of them).
VERDICTS = [("path_length_mean", "length"), ("arrival_time_mean", "arrival"), ("planning_ms", "planning")]
BOXES = [("path_length_mean", "path length (m)"), ("arrival_time_mean", "arrival time (s)"),
         ("planning_ms", "planning time (ms)")]  # fmt: skip


def _vals(rows: list[dict[str, Any]], col: str) -> list[float]:
    out = []
    for r in rows:
        if r.get("status") != "ok":
            continue
        try:
            v = float(r[col])
        except (TypeError, ValueError, KeyError):
            continue
        if math.isfinite(v):
            out.append(v)
    return out


#: What an empty cell reads (explained under the table by :func:`table_notes`).
NO_VALUE = "n/a"


def mean_std(xs: list[float], fmt: str = "{:.1f}") -> str:
    if not xs:
        return NO_VALUE
    return f"{fmt.format(np.mean(xs))} ± {fmt.format(np.std(xs))}"


def verdict(base: list[float], other: list[float], alpha: float) -> str:
    """'+' (other significantly lower = better), '-' (higher), '=' by the Wilcoxon rank-sum test."""
    from scipy.stats import ranksums

    a = [x for x in base if math.isfinite(x)]
    b = [x for x in other if math.isfinite(x)]
    if len(a) < 2 or len(b) < 2:
        return "n/a"
    p = float(ranksums(b, a).pvalue)
    if p >= alpha or np.median(a) == np.median(b):
        return f"= (p={p_text(p, alpha)})"
    return f"{'+' if np.median(b) < np.median(a) else '-'} (p={p_text(p, alpha)})"


def p_text(p: float, alpha: float) -> str:
    """``p`` with the digits it takes to read on the same side of ``alpha`` as it is
    (0.0495 is not printed as 0.05 beside alpha = 0.05)."""
    for digits in range(2, 17):
        text = f"{p:.{digits}g}"
        shown = float(text)
        if (shown < alpha) == (p < alpha) and (shown != alpha or p == alpha):
            return text
    return repr(p)


def smallest_p(n_a: int, n_b: int) -> float:
    """The smallest p the rank-sum test can give with ``n_a`` and ``n_b`` runs (every run of one
    side below every run of the other)."""
    from scipy.stats import ranksums

    if n_a < 1 or n_b < 1:
        return 1.0
    return float(ranksums(np.arange(n_a), np.arange(n_a, n_a + n_b)).pvalue)


def seeds_needed(alpha: float, most: int = 100) -> int:
    """The fewest runs per side with which the rank-sum test can reach p < ``alpha``."""
    return next((n for n in range(2, most + 1) if smallest_p(n, n) < alpha), most)


def _success(rows: list[dict[str, Any]]) -> str:
    ok = sum(str(r.get("success")) == "True" for r in rows)
    errors = sum(r.get("status") != "ok" for r in rows)
    pct = 100.0 * ok / len(rows) if rows else 0.0
    return f"{ok}/{len(rows)} ({pct:.0f}%)" + (f", {errors} error(s)" if errors else "")


def _home(rows: list[dict[str, Any]]) -> str:
    """Agents that arrived over all agents of the finished runs ('4/6'): a run that failed may
    still have brought most of its agents home."""
    counts = [(_int(r.get("arrived")), _int(r.get("agents"))) for r in rows if r.get("status") == "ok"]
    counts = [(a, n) for a, n in counts if a is not None and n is not None]
    if not counts:
        return NO_VALUE
    return f"{sum(a for a, _ in counts)}/{sum(n for _, n in counts)}"


def _int(value: Any) -> int | None:
    try:
        return int(value)
    except (TypeError, ValueError):
        return None


def _no_optimizer_ran(rows: list[dict[str, Any]]) -> bool:
    """Every finished run (at least one) says it made no optimizer call (pure APF throughout)."""
    runs = [_int(r.get("optimizer_runs")) for r in rows if r.get("status") == "ok"]
    return bool(runs) and all(n == 0 for n in runs)


def _alike(rows: list[dict[str, Any]]) -> bool:
    """The finished runs (two or more) flew alike: the same figures but for the timing ones."""
    keys = ("arrived", "collisions", "sim_time", "path_length_mean", "arrival_time_mean", "curvature_mean")
    seen = {tuple(str(r.get(k)) for k in keys) for r in rows if r.get("status") == "ok"}
    return len([r for r in rows if r.get("status") == "ok"]) > 1 and len(seen) == 1


def table(rows: list[dict[str, Any]], optimizers: list[str], alpha: float = 0.05) -> str:
    """A markdown table: one line per optimizer (in the given order; the first is the reference)."""
    by = {n: [r for r in rows if r["optimizer"] == n] for n in optimizers}
    ref = optimizers[0]
    stats = [s for s in STATS if s[0] != "plan_cost" or _vals(rows, "plan_cost")]
    head = ["optimizer", "success", "agents home", *(h for _, h, _ in stats)]
    head += [f"{h} vs {ref}" for _, h in VERDICTS]
    if any(s[0] == "plan_cost" for s in stats):
        head.append(f"cost vs {ref}")
    out_rows = []
    for n in optimizers:
        rs = by[n]
        cells = [n, _success(rs), _home(rs), *(mean_std(_vals(rs, c), f) for c, _, f in stats)]
        cols = [c for c, _ in VERDICTS] + (
            ["plan_cost"] if len(head) > 3 + len(stats) + len(VERDICTS) else []
        )
        for c in cols:
            cells.append("(reference)" if n == ref else verdict(_vals(by[ref], c), _vals(rs, c), alpha))
        out_rows.append(cells)
    widths = [max(len(h), *(len(r[k]) for r in out_rows)) for k, h in enumerate(head)]

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.ljust(w) for c, w in zip(cells, widths, strict=True)) + " |"

    return "\n".join([line(head), line(["-" * w for w in widths])] + [line(r) for r in out_rows])


def table_notes(rows: list[dict[str, Any]], optimizers: list[str], alpha: float = 0.05) -> list[str]:
    """One sentence per kind of ``n/a`` (or missing column) in :func:`table`, saying why."""
    notes = []
    if not _vals(rows, "plan_cost"):
        notes.append(
            "no plan cost column: no run made a global plan (the world plans reactively, "
            "`planner.mode: reactive`; the cost is that of `mode: global`'s plans)"
        )
    by = {n: [r for r in rows if r["optimizer"] == n] for n in optimizers}
    idle = [n for n, rs in by.items() if n != "none" and _no_optimizer_ran(rs)]
    if idle:
        same = "none" in by and _no_optimizer_ran(by["none"])
        alike = all(_alike(by[n]) for n in idle)
        notes.append(
            f"no optimizer ran in any run of {', '.join(idle)}: no agent got stuck, needed smoothing or "
            "a global plan, so these rows are pure APF's"
            + (" (the same as `none`'s)" if same else "")
            + (", every seed's the same" if alike else "")
            + "; the optimizers are compared only where they run (a harder world, or more agents)"
        )
    empty = [n for n, rs in by.items() if rs and not _vals(rs, "path_length_mean")]
    if empty:
        notes.append(
            f"n/a in length, curvature and arrival for {', '.join(empty)}: no agent of any of its runs "
            "arrived (these metrics average the agents that arrived)"
        )
    cols = [c for c, _ in VERDICTS] + (["plan_cost"] if _vals(rows, "plan_cost") else [])
    sizes = [len(rs) for rs in by.values() if rs]
    if len(optimizers) > 1 and sizes and smallest_p(min(sizes), min(sizes)) >= alpha:
        notes.append(
            f"no verdict can be significant: with {min(sizes)} run(s) per optimizer the rank-sum test's "
            f"smallest possible p is {p_text(smallest_p(min(sizes), min(sizes)), alpha)} (>= alpha = "
            f"{alpha:g}); it takes at least {seeds_needed(alpha)} seeds"
        )
    few = [n for n, rs in by.items() if any(len(_vals(rs, c)) < 2 for c in cols)]
    if len(optimizers) > 1 and few:
        notes.append(
            f"n/a in a verdict column: fewer than 2 values on a side ({', '.join(few)}); the rank-sum "
            "test needs at least 2 runs per optimizer (more seeds)"
        )
    return notes


def groups(rows: list[dict[str, Any]], override_keys: list[str]) -> list[tuple[str, tuple, list[dict]]]:
    """(world, override values, rows) in order of first appearance."""
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        key = (r["world"], tuple(json.dumps(r.get(k), default=str) for k in override_keys))
        out.setdefault(key, []).append(r)
    return [(w, vals, rs) for (w, vals), rs in out.items()]


def box_plot(path: Path, title: str, rows: list[dict[str, Any]], labels: list[tuple[str, Any]]) -> Path:
    """One PNG: a panel per metric of :data:`BOXES`, a box per (label, selector) over its runs."""
    box_figure(title, rows, labels).savefig(path)
    return path


def box_figure(title: str, rows: list[dict[str, Any]], labels: list[tuple[str, Any]]):  # noqa: ANN201
    """The matplotlib Figure of :func:`box_plot`."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    # wide enough for its labels: a box per label, the optimizer and its settings on two lines
    width = max(4.0, 0.9 * len(labels))
    fig = Figure(figsize=(width * len(BOXES), 4.8), dpi=100, layout="constrained")
    axes = fig.subplots(1, len(BOXES))
    for ax, (col, name) in zip(np.atleast_1d(axes), BOXES, strict=True):
        data = [_vals([r for r in rows if sel(r)], col) for _, sel in labels]
        names = [lab.replace(" ", "\n", 1) for lab, _ in labels]
        keep = [i for i, d in enumerate(data) if d]
        if keep:
            ax.boxplot(
                [data[i] for i in keep],
                showmeans=True,
                medianprops={"color": "tab:orange"},
                meanprops={"marker": "^", "markerfacecolor": "tab:green", "markeredgecolor": "tab:green"},
            )
            rotate = 45 if max(len(n) for n in names) * len(keep) > 60 else 0
            ax.set_xticks(range(1, len(keep) + 1), [names[i] for i in keep], rotation=rotate,
                          ha="right" if rotate else "center", fontsize=8)  # fmt: skip
        else:
            ax.text(0.5, 0.5, "no finished run", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(name)
        ax.grid(True, axis="y", alpha=0.3)
    legend = [
        Line2D([], [], color="tab:orange", label="median"),
        Line2D([], [], color="tab:green", marker="^", ls="", label="mean"),
        Line2D([], [], color="k", marker="o", mfc="none", ls="", label="outlier (beyond 1.5 IQR)"),
    ]
    fig.legend(handles=legend, loc="outside lower center", ncol=3, fontsize=8)
    fig.suptitle(f"{title}: boxes over the seeds (box: quartiles, whiskers: 1.5 IQR)")
    return fig


def plot_name(world: str, worlds: list[str]) -> str:
    """A file-name-safe name for a world's plots: its file name, or its label when another world
    of the study has the same file name."""
    stem = Path(world).stem
    if sum(Path(w).stem == stem for w in worlds) > 1:
        stem = Path(world).with_suffix("").as_posix()
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("_")


def _fmt_combo(override_keys: list[str], vals: tuple) -> str:
    return ", ".join(f"`{k}` = {v}" for k, v in zip(override_keys, vals, strict=True))


def write_report(
    out_dir: Path,
    name: str,
    rows: list[dict[str, Any]],
    optimizers: list[str],
    override_keys: list[str],
    alpha: float,
    notes: list[str],
) -> Path:
    """report.md (and one box-plot PNG per world) in ``out_dir``."""
    lines = [f"# Sweep `{name}`", ""]
    lines += notes
    lines += [
        "",
        f"Mean ± std over the seeds. Verdicts: Wilcoxon rank-sum test against `{optimizers[0]}` at "
        f"alpha = {alpha:g}: `+` significantly lower (better), `-` significantly higher, `=` no "
        "significant difference. Length, ratio, curvature and arrival time average the agents that "
        "arrived; planning time is the wall time of all optimizer calls in a run.",
    ]
    worlds: list[str] = []
    for w, vals, rs in groups(rows, override_keys):
        if w not in worlds:
            worlds.append(w)
            lines += ["", f"## {w}"]
        if override_keys:
            lines += ["", f"### {_fmt_combo(override_keys, tuple(json.loads(v) for v in vals))}"]
        lines += ["", table(rs, optimizers, alpha)]
        lines += [f"\n{n}" for n in table_notes(rs, optimizers, alpha)]
        errors = [r for r in rs if r.get("status") != "ok"]
        for r in errors:
            lines.append(f"\nerror: {r['optimizer']} seed {r['seed']}: {r.get('error', '')}")
    lines += ["", "## Box plots"]
    for w in worlds:
        wrows = [r for r in rows if r["world"] == w]
        labels: list[tuple[str, Any]] = []
        for _, vals, _rs in groups(wrows, override_keys):
            for o in optimizers:
                tag = " ".join(
                    f"{k.rsplit('.', 1)[-1]}={json.loads(v)}"
                    for k, v in zip(override_keys, vals, strict=True)
                )

                def sel(r: dict, o: str = o, vals: tuple = vals) -> bool:
                    return (
                        r["optimizer"] == o
                        and tuple(json.dumps(r.get(k), default=str) for k in override_keys) == vals
                    )

                labels.append((f"{o} {tag}".strip(), sel))
        png = out_dir / f"box-{plot_name(w, worlds)}.png"
        box_plot(png, w, wrows, labels)
        lines += ["", f"![{w}]({png.name})"]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
