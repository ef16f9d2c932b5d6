"""Threat zones in flight: exposure per agent for ``/summary``, and the cores local flight avoids.

A threat is a ball about its ``position`` (3D distance, so a threat on the ground covers a
dome): the planners' soft cost acts inside ``r_max``; ``r_min`` is its core. Exposure counts
an agent's flying steps whose end lies inside a zone (``threat_time``, seconds inside some
``r_max``; ``threat_core_time``, inside some ``r_min``) and its closest approach to a threat's
centre. A world asks local flight to keep out of a core with ``threats[i].avoid: true``: the
core then repels the agents like a static sphere of radius ``r_min`` in the potential field
(never a wall for the collision checks: a threat stays soft).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from swarmplan.flight.apf import FieldInputs
from swarmplan.planner.cores import avoided_cores

if TYPE_CHECKING:
    from swarmplan.world.model import World


def threat_cores(world: World) -> tuple[np.ndarray, np.ndarray] | None:
    """(centres (K, 3), radii (K,)) of the cores local flight keeps out of, or None (the
    planners' pruning keeps out of the same ones: :func:`swarmplan.planner.cores.avoided_cores`)."""
    cores = avoided_cores(world)
    return None if cores is None else (cores[0], cores[1])


def with_cores(inputs: FieldInputs, pos: np.ndarray, cores: tuple[np.ndarray, np.ndarray]) -> FieldInputs:
    """``inputs`` with the threat cores appended as static spheres (distance, outward normal)."""
    centers, radii = cores
    rel = pos[:, None, :] - centers[None, :, :]  # (n, K, 3)
    dist = np.sqrt((rel * rel).sum(-1))
    grad = rel / np.maximum(dist, 1e-9)[..., None]
    k = len(radii)
    return replace(
        inputs,
        obstacle_distance=np.concatenate([inputs.obstacle_distance, dist - radii[None, :]], axis=1),
        obstacle_gradient=np.concatenate([inputs.obstacle_gradient, grad], axis=1),
        obstacle_velocity=np.concatenate([inputs.obstacle_velocity, np.zeros((k, 3))]),
        obstacle_moving=np.concatenate([inputs.obstacle_moving, np.zeros(k, bool)]),
        obstacle_radius=np.concatenate([inputs.obstacle_radius, radii]),
        obstacle_center=np.concatenate([inputs.obstacle_center, centers]),
    )


def exposure(world: World, positions: np.ndarray, flying: np.ndarray) -> list[dict[str, Any]] | None:
    """Per agent ``threat_time``, ``threat_core_time`` (s), ``threat_closest`` (m to a centre) and
    ``threat_closest_to`` (``threats[i]``), or None for a world without threats.

    ``positions`` (K, N, 3) are the agents' positions at the end of each step, ``flying``
    (K, N) whether the agent flew that step; ``world.dt`` is the step.
    """
    if not world.threats:
        return None
    n = positions.shape[1]
    in_range = np.zeros(positions.shape[:2], bool)
    in_core = np.zeros(positions.shape[:2], bool)
    closest = np.full(n, np.inf)
    closest_to = np.full(n, -1)
    for j, th in enumerate(world.threats):
        d = np.linalg.norm(positions - th.position, axis=-1)
        in_range |= flying & (d < th.r_max)
        in_core |= flying & (d < th.r_min)
        dmin = np.where(flying, d, np.inf).min(axis=0) if len(d) else np.full(n, np.inf)
        closer = dmin < closest
        closest = np.where(closer, dmin, closest)
        closest_to = np.where(closer, j, closest_to)
    out = []
    for i in range(n):
        finite = bool(np.isfinite(closest[i]))
        out.append(
            {
                "threat_time": round(float(in_range[:, i].sum()) * world.dt, 6),
                "threat_core_time": round(float(in_core[:, i].sum()) * world.dt, 6),
                "threat_closest": round(float(closest[i]), 6) if finite else None,
                "threat_closest_to": f"threats[{int(closest_to[i])}]" if finite else None,
            }
        )
    return out


def exposure_warnings(summary: dict[str, Any]) -> list[str]:
    """One line per agent that flew inside a threat's core (for the end-of-run table)."""
    return [
        f"WARNING {a['id']}: {a['threat_core_time']:.1f} s inside the core (r_min) of "
        f"{a['threat_closest_to']}, {a['threat_closest']:.1f} m from its centre at the closest"
        for a in summary.get("agents", [])
        if a.get("threat_core_time")
    ]


def nearest_with_cores(
    clearance: np.ndarray,
    normal: np.ndarray,
    pos: np.ndarray,
    radius: np.ndarray,
    cores: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """The nearest surface per agent counting the avoided cores: the commanded speed towards it
    is capped like towards an obstacle, so an agent brakes at a core instead of sliding in."""
    centers, radii = cores
    rel = pos[:, None, :] - centers[None, :, :]
    dist = np.sqrt((rel * rel).sum(-1))
    gap = dist - radii[None, :] - radius[:, None]  # (n, K)
    j = np.argmin(gap, axis=1)
    rows = np.arange(len(pos))
    g = gap[rows, j]
    closer = g < clearance
    n = rel[rows, j] / np.maximum(dist[rows, j], 1e-9)[:, None]
    return np.where(closer, g, clearance), np.where(closer[:, None], n, normal)
