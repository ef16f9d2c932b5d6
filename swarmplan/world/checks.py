"""Cross-field checks of a parsed world: agents' starts and goals against the bounds, the
obstacles (exact signed distances) and the terrain."""

from __future__ import annotations

import numpy as np

from swarmplan.geometry.shapes import signed_distance
from swarmplan.world import terrain
from swarmplan.world.checker import Checker
from swarmplan.world.model import AgentSpec, Obstacle, Peak


def check_placements(
    c: Checker,
    agents: list[AgentSpec],
    raw_agents: list,
    obstacles: list[Obstacle],
    bmin: np.ndarray | None,
    bmax: np.ndarray | None,
    peaks: list[Peak],
) -> None:
    index = {a.get("id"): i for i, a in enumerate(raw_agents) if isinstance(a, dict)}
    static = [o for o in obstacles if not o.moving]
    # Every start against every obstacle and every goal against the static ones, one call per
    # obstacle (one per agent and obstacle took ~2 s for 512 agents among 88 obstacles).
    clear = {
        "start": _distances(obstacles, [a.start for a in agents]),
        "goal": _distances(static, [a.goal for a in agents]),
    }
    for k, a in enumerate(agents):
        p = f"agents[{index.get(a.id, '?')}]"
        for key, point, against in (("start", a.start, obstacles), ("goal", a.goal, static)):
            if bmin is not None and bmax is not None and (np.any(point < bmin) or np.any(point > bmax)):
                c.add(f"{p}.{key}", f"{point.tolist()} is outside bounds {bmin.tolist()}..{bmax.tolist()}")
                continue
            for o, d in zip(against, clear[key][k].tolist(), strict=True):
                if d < a.radius:
                    what = "inside" if d < 0 else "touching"
                    c.add(f"{p}.{key}", f"{what} obstacle '{o.id}' (clearance {d - a.radius:.2f} m)")
            if peaks:
                ground = float(terrain.height(peaks, point[:2]))
                if point[2] - ground < a.radius:
                    c.add(f"{p}.{key}", f"below the terrain (terrain height {ground:.2f} m at this point)")
            elif point[2] < a.radius:
                c.add(f"{p}.{key}", f"touching the ground (z = {point[2]:g} m, radius {a.radius:g} m)")
    for key in ("start", "goal"):
        for k, j, gap, need in _overlaps(agents, key):
            p = f"agents[{index.get(agents[k].id, '?')}]"
            c.add(
                f"{p}.{key}",
                f"overlaps agent '{agents[j].id}' ({key}s {gap:.3g} m apart; their bodies need {need:.3g} m)",
            )


def _overlaps(agents: list[AgentSpec], key: str) -> list[tuple[int, int, float, float]]:
    """Pairs ``(k, j, distance, r_k + r_j)``, ``k < j``, of agents whose ``key`` points (start or
    goal) are closer than their two radii: their bodies would overlap there."""
    if len(agents) < 2:
        return []
    pts = np.array([getattr(a, key) for a in agents], dtype=float)
    radii = np.array([a.radius for a in agents], dtype=float)
    if len(agents) <= 64:  # every pair (a small world starts without scipy.spatial)
        k, j = np.triu_indices(len(agents), 1)
        pairs = np.column_stack([k, j])
    else:
        from scipy.spatial import cKDTree

        pairs = cKDTree(pts).query_pairs(2.0 * float(radii.max()), output_type="ndarray")
    out = []
    for k, j in sorted(map(tuple, pairs.tolist())):
        gap, need = float(np.linalg.norm(pts[k] - pts[j])), float(radii[k] + radii[j])
        if gap < need:
            out.append((k, j, gap, need))
    return out


def _distances(obstacles: list[Obstacle], points: list[np.ndarray]) -> np.ndarray:
    """Signed distances (points, obstacles) of each point to each obstacle at its t = 0 place."""
    if not points or not obstacles:
        return np.zeros((len(points), len(obstacles)))
    xyz = np.array(points, dtype=float).reshape(len(points), 3)
    return np.stack([signed_distance(o, xyz) for o in obstacles], axis=1)
