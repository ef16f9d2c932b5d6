"""The papers' path cost models, vectorized: ``model(nodes, dense) -> (n,)`` for n candidate paths.

``nodes`` (n, K, 3) are the path's vertices (start, waypoints, goal: what the agent flies
as its route); ``dense`` (n, P, 3) is the same path resampled finely for clearance checks.

- :class:`McfoCost` — paper 004 (Chen et al., MCFO) eqs 1-6:
  ``J = w1·J_path + w2·J_height + w3·J_smooth`` with ``J_path`` the polyline length (eq 3),
  ``J_height`` the standard deviation of the node heights (eqs 4-5, population std over
  the n nodes, S and T included) and ``J_smooth = (x_n - x_1)·Σ arccos(φ_{k+1}·φ_k / |φ_{k+1}||φ_k|)``
  (eq 6); ``x_n - x_1`` is the extent along the planes' normal, i.e. |S→T| in our rotated
  frame. Infeasible paths (eqs 8-12) cost ``c_j·J`` (eq 11) — *plus* ``c_j·|S→T|·V`` where V
  grades how infeasible the path is (see :meth:`PathContext.violation`); 004's bare ``c_j·J``
  gives every infeasible path the same shape of landscape as the feasible ones, so a
  population that starts infeasible has nothing pulling it out.
- :class:`ThreatCost` — paper 000 (Zhou et al., IBA) eqs 2-7 with Table 1 weights:
  ``W = δ_O·L + Σ_segments l_ij · (1/5)Σ_k w_k`` (the integral of eq 6 with the segment
  average of eq 7), where ``w_k = Σ_threats δ·P(d) + P_T + P_B + P_H`` at the 5 points
  ``k/5`` (k = 1..5) of the segment. ``P_R(d) = 1/d^4`` for radar and ``1/d`` for missile,
  artillery and weather inside ``[r_min, r_max]``, 1 below ``r_min`` and 0 beyond ``r_max``
  (eqs 2-3), with ``d`` in ``threat_unit`` metres (the paper uses km: ``threat_unit: 1000``
  reproduces its numbers; a world scaled 1:s uses ``1000/s``) and lengths in the same
  unit. ``δ`` is each threat's ``weight`` from the world file. ``P_T = 1`` below the
  terrain, ``P_B = 1`` over the maximum climb angle, ``P_H = 1`` above the maximum height.
- :class:`EnergyCost` — paper 002 (IAFSA) eqs 2-12: ``C = α1·L + α2·E``,
  ``E = ℘_E (E1 + E2)``, ``℘_E = (℘_E(n) - 1)/γ_k · γ + 1`` (eq 5), ``E1 = Σ ξ1(|Δx| + |Δy|)``
  and ``E2 = Σ ξ2 |Δz|`` (eqs 7-8; the PDF text lost the bars — the paper says ascent and
  descent cost the same, so they are absolute values), turning angle ``γ_i <= γ_max``
  (eq 10) and climb angle ``ϑ_i <= ϑ_max`` (eq 11) as constraints.

Every model adds the same hard constraints, never part of a paper's objective and zero on
a valid path: clearance from static obstacles (ObstacleField signed distances on the
dense path) and terrain, the agent's climb angle, and for fixed wings the minimum turn
radius (a corner of angle θ between segments of length ≥ l needs ``R·tan(θ/2) <= l/2``
for a circular fillet of radius R). A path violating any of them gets
``penalty·(1 + V)`` added (``c_j`` multiplies instead for 004, as above).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from swarmplan.geometry.polyline import climb_angles, horizontal_turn_angles, polyline_length, turn_angles
from swarmplan.geometry.shapes import ObstacleField, distance_and_gradient
from swarmplan.world.planner_config import COST_WEIGHTS

if TYPE_CHECKING:
    from swarmplan.world.model import AgentSpec, World

# ----------------------------------------------------------------------------- geometry helpers


def height_std(P: np.ndarray) -> np.ndarray:
    """Population standard deviation of the node heights (004 eqs 4-5)."""
    return P[..., 2].std(axis=1)


def fillet_violation(P: np.ndarray, r_min: float) -> np.ndarray:
    """(n,) Σ over corners of max(0, R·tan(θ/2) - l/2): how far corners are from admitting radius R."""
    if P.shape[1] < 3 or r_min <= 0:
        return np.zeros(len(P))
    seg = np.linalg.norm(np.diff(P, axis=1), axis=-1)
    lmin = np.minimum(seg[:, :-1], seg[:, 1:])
    th = np.minimum(turn_angles(P), np.pi * 0.999)
    return np.maximum(0.0, r_min * np.tan(th / 2) - lmin / 2).sum(axis=1)


# ----------------------------------------------------------------------------- shared context


@dataclass
class PathContext:
    """What every cost model needs about the world and the agent that will fly the path."""

    world: World
    agent: AgentSpec
    margin: float = 0.0  # extra clearance beyond the agent's radius (m)
    ramp: float = 0.0  # m from the start/goal over which the altitude floor rises (0: half climb slope)
    distances: ObstacleField = field(init=False)

    def __post_init__(self) -> None:
        self.distances = ObstacleField(self.world.static_obstacles)
        self.radius = float(self.agent.radius)
        self.need = self.radius + float(self.margin)
        self.fixed_wing = self.agent.model == "fixed_wing"
        self.span = float(np.linalg.norm(self.agent.goal - self.agent.start))
        ends = np.stack([self.agent.start, self.agent.goal])
        self.end_altitude = (ends[:, 2] - self.world.terrain_height(ends[:, :2])).tolist()

    def obstacle_clearance(self, dense: np.ndarray) -> np.ndarray:
        """(n, P) clearance of every dense point from the static obstacles' surfaces, minus the radius."""
        n, p, _ = dense.shape
        pts = dense.reshape(-1, 3)
        clear = np.full(len(pts), np.inf)
        # Only points within reach of an obstacle's bounding sphere need its exact distance: the
        # rest are farther than the margin anyway (their clearance is then under-reported as
        # the bounding-sphere gap, which is still beyond the margin).
        reach = self.need + 1.0
        for j, o in enumerate(self.distances.obstacles):
            gap = np.linalg.norm(pts - o.position, axis=1) - o.bounding_radius
            near = gap < reach
            d = gap
            if near.any():
                d = gap.copy()
                d[near] = distance_and_gradient(o, pts[near], None, self.distances.mesh_grids.get(j))[0]
            clear = np.minimum(clear, d)
        return (clear - self.radius).reshape(n, p)

    def altitude_shortfall(self, dense: np.ndarray) -> np.ndarray:
        """(n, P) ≥ 0: how far each dense point is below the required height above the terrain.

        The requirement is ``max(min_altitude, terrain.clearance, radius + margin)``, ramped up
        linearly from the start's and goal's own height (which the user places, possibly lower)
        over ``ramp`` metres (default: at half the maximum climb slope), never below the radius.
        """
        alt = dense[..., 2] - self.world.terrain_height(dense[..., :2])
        need = max(self.agent.min_altitude, self.world.terrain_clearance, self.need)
        ends = np.minimum(
            np.linalg.norm(dense - self.agent.start, axis=-1),
            np.linalg.norm(dense - self.agent.goal, axis=-1),
        )
        low = max(self.radius, min(self.end_altitude))
        if self.ramp > 0:
            ramp = low + (need - low) * ends / self.ramp
        else:
            ramp = low + ends * 0.5 * np.tan(self.agent.max_climb_angle)
        req = np.minimum(need, ramp)
        return np.maximum(0.0, req - alt)

    def violation(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        """(n,) ≥ 0, zero iff the path is valid: penetration (m) into the clearance margin of the
        obstacles and the altitude floor along the dense path, climb angle excess (rad, times |S→G|)
        and fillet excess (m) for fixed wings."""
        pen = np.maximum(0.0, self.margin - self.obstacle_clearance(dense))
        pen = np.maximum(pen, self.altitude_shortfall(dense))
        v = pen.max(axis=1) + pen.mean(axis=1)
        climb = np.maximum(0.0, np.abs(climb_angles(nodes)) - self.agent.max_climb_angle)
        v = v + climb.sum(axis=1) * max(self.span, 1.0)
        if self.fixed_wing:
            v = v + fillet_violation(nodes, self.agent.min_turn_radius)
        return v


# ----------------------------------------------------------------------------- models


class CostModel:
    """Base: ``__call__(nodes, dense)`` returns (n,) costs; ``objective`` is the paper's term alone."""

    name = ""
    defaults: dict[str, float] = {}

    def __init__(self, ctx: PathContext, **weights: float):
        unknown = sorted(set(weights) - set(self.defaults))
        if unknown:
            raise ValueError(f"unknown weight(s) {', '.join(unknown)}; known: {', '.join(self.defaults)}")
        self.ctx = ctx
        self.w = {**self.defaults, **{k: float(v) for k, v in weights.items()}}

    def objective(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def extra_violation(self, nodes: np.ndarray) -> np.ndarray:
        return np.zeros(len(nodes))

    def violation(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        return self.ctx.violation(nodes, dense) + self.extra_violation(nodes)

    def __call__(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        j = self.objective(nodes, dense)
        v = self.violation(nodes, dense)
        return np.where(v > 0, j + self.w["penalty"] * (1.0 + v), j)


class McfoCost(CostModel):
    """Paper 004: J = w1·length + w2·height std + w3·smoothness; infeasible → c_j·(J + |S→T|·V)."""

    name = "mcfo"
    defaults = COST_WEIGHTS["mcfo"]

    def terms(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(J_path, J_height, J_smooth) of eqs 3, 4 and 6."""
        return polyline_length(nodes), height_std(nodes), self.ctx.span * turn_angles(nodes).sum(axis=1)

    def objective(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        jp, jh, js = self.terms(nodes)
        return self.w["w1"] * jp + self.w["w2"] * jh + self.w["w3"] * js

    def __call__(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        j = self.objective(nodes, dense)
        v = self.violation(nodes, dense)
        return np.where(v > 0, self.w["penalty"] * (j + max(self.ctx.span, 1.0) * v), j)


_RADAR_POWER = 4.0  # A of 000 eq 2 (the world format: radar is 1/d^4 inside its band)


def threat_probability(kind: str, d: np.ndarray, r_min: float, r_max: float) -> np.ndarray:
    """000 eqs 2-3 with ``d``, ``r_min``, ``r_max`` in the paper's unit: 1 inside r_min, 1/d^A or 1/d
    in the band, 0 beyond r_max (capped at 1: a probability, when r_min < 1 unit)."""
    power = _RADAR_POWER if kind == "radar" else 1.0
    band = np.minimum(1.0, 1.0 / np.maximum(d, 1e-12) ** power)
    return np.where(d < r_min, 1.0, np.where(d <= r_max, band, 0.0))


class ThreatCost(CostModel):
    """Paper 000: W = δ_O·L + Σ_seg l·mean_k(Σ δ P_threat + P_T + P_B + P_H) (eqs 2-7, Table 1)."""

    name = "iba"
    # Weight names and meanings: swarmplan.world.planner_config.COST_WEIGHTS.
    defaults = COST_WEIGHTS["iba"]

    def __init__(self, ctx: PathContext, **weights: float):
        super().__init__(ctx, **weights)
        w = ctx.world
        self.z_max = self.w["max_altitude"] or float(w.bounds_max[2])
        self.climb_max = (
            np.radians(self.w["max_climb_angle"]) if self.w["max_climb_angle"] else ctx.agent.max_climb_angle
        )

    def point_cost(self, pts: np.ndarray) -> np.ndarray:
        """Σ_threats δ·P(d) + P_T + P_H at points (..., 3) (P_B is per segment)."""
        u = self.w["threat_unit"]
        c = np.zeros(pts.shape[:-1])
        for th in self.ctx.world.threats:
            d = np.linalg.norm(pts - th.position, axis=-1) / u
            c = c + th.weight * threat_probability(th.kind, d, th.r_min / u, th.r_max / u)
        ground = self.ctx.world.terrain_height(pts[..., :2])
        c = c + (pts[..., 2] < ground).astype(float)  # P_T
        c = c + (pts[..., 2] > self.z_max).astype(float)  # P_H
        return c

    def extra_violation(self, nodes: np.ndarray) -> np.ndarray:
        """Eq 5, ``sum l_i <= l_max``: the excess length in metres (0 when ``max_length`` is 0)."""
        if self.w["max_length"] <= 0:
            return np.zeros(len(nodes))
        return np.maximum(0.0, polyline_length(nodes) - self.w["max_length"])

    def segment_costs(self, nodes: np.ndarray) -> np.ndarray:
        """(n, K-1) mean of w_k over the 5 points k/5, k = 1..5 of each segment (eq 7)."""
        k = np.arange(1, 6) / 5.0
        a, b = nodes[:, :-1, None, :], nodes[:, 1:, None, :]
        pts = a + k[None, None, :, None] * (b - a)  # (n, K-1, 5, 3)
        w = self.point_cost(pts).mean(axis=-1)
        p_b = (np.abs(climb_angles(nodes)) > self.climb_max + 1e-12).astype(float)
        return w + p_b

    def objective(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        u = self.w["threat_unit"]
        seg = np.linalg.norm(np.diff(nodes, axis=1), axis=-1) / u
        return self.w["path"] * seg.sum(axis=1) + (seg * self.segment_costs(nodes)).sum(axis=1)


class EnergyCost(CostModel):
    """Paper 002: C = α1·L + α2·℘_E·(E1 + E2) with turning/climb limits (eqs 2-12)."""

    name = "iafsa"
    # Weight names and meanings: swarmplan.world.planner_config.COST_WEIGHTS.
    defaults = COST_WEIGHTS["iafsa"]

    @property
    def payload_factor(self) -> float:
        """℘_E of eq 5."""
        w = self.w
        return (w["payload_penalty_max"] - 1.0) / w["payload_max"] * w["payload"] + 1.0

    def energy(self, nodes: np.ndarray) -> np.ndarray:
        d = np.abs(np.diff(nodes, axis=1))
        e1 = self.w["xi1"] * (d[..., 0] + d[..., 1]).sum(axis=1)
        e2 = self.w["xi2"] * d[..., 2].sum(axis=1)
        return self.payload_factor * (e1 + e2)

    def objective(self, nodes: np.ndarray, dense: np.ndarray) -> np.ndarray:
        return self.w["alpha1"] * polyline_length(nodes) + self.w["alpha2"] * self.energy(nodes)

    def extra_violation(self, nodes: np.ndarray) -> np.ndarray:
        v = np.zeros(len(nodes))
        span = max(self.ctx.span, 1.0)
        if self.w["max_turn_angle"] > 0:
            ex = horizontal_turn_angles(nodes) - np.radians(self.w["max_turn_angle"])
            v = v + np.maximum(0.0, ex).sum(axis=1) * span
        if self.w["max_climb_angle"] > 0:
            ex = np.abs(climb_angles(nodes)) - np.radians(self.w["max_climb_angle"])
            v = v + np.maximum(0.0, ex).sum(axis=1) * span
        return v


MODELS: dict[str, type[CostModel]] = {m.name: m for m in (McfoCost, ThreatCost, EnergyCost)}


def make_cost(name: str, ctx: PathContext, weights: dict[str, Any] | None = None) -> CostModel:
    """The cost model ``name`` (mcfo | iba | iafsa) with ``weights`` over its defaults."""
    if name not in MODELS:
        raise ValueError(f"unknown cost model {name!r}; known: {', '.join(MODELS)}")
    return MODELS[name](ctx, **(weights or {}))
