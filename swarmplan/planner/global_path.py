"""Global-path mode: plan each agent's whole path before flight with a paper's cost model.

``planner: {mode: global, global: {...}}`` in the world file selects it; the keys of
``planner.global`` (all optional) are::

    cost: mcfo | iba | iafsa    # paper 004 (length/height/smoothness), 000 (threats), 002 (energy)
    encoding: planes | spline   # default: planes, spline for iafsa (paper 002)
    waypoints: 8                # planes (waypoints) or spline control points across start→goal
    lateral: 0                  # m, ± range of the lateral offsets (0 = |start→goal| / 2)
    vertical: 0                 # m, ± range of the vertical offsets (0 = height of the bounds)
    margin: 0                   # m of clearance beyond the agent radius (0 = half apf.influence)
    samples: 40                 # spline samples (the route's vertices)
    population: 0               # 0 = planner.optimizer.population
    iterations: 0               # 0 = planner.optimizer.iterations
    retries: 2                  # new runs with budget x 1.5 each when the best path is invalid
    shortcut: true              # prune the valid plan: drop vertices a straight leg can skip (FCL)
    warm_start: true            # seed the population with the straight line and smooth detours
    weights: {}                 # the cost model's weights (see cost_models.py)

:func:`plan_global_routes` optimizes every agent's path with the named optimizer (budget
``population × iterations`` evaluations, vectorized over the population), logs each run
on ``/optimizer`` with purpose ``global``, checks the best path with FCL against the static
obstacles, the terrain and the bounds, and returns the valid ones as routes: corners turned
into paper 004's arcs (§6, :func:`fillet_route`; a corner whose arc does not fit or touches
something stays a "broken point") and legs split so the APF pursuit follows the planned
polyline closely. An invalid best path is planned
again (``retries`` times, the budget × 1.5 each time); if none is valid the agent has no
route (it flies reactively: APF with escapes), said in a ``global_plan_invalid`` event;
valid ones get a ``global_plan`` event with their length, cost, attempts and ``fillet``
(radius, arcs, broken points).

``warm_start`` (default on) hands every optimizer the same few structured paths as ``x0``
(:meth:`PlaneEncoding.warm_start`: the straight line, half-sine detours to both sides and
over the top); the rest of the population is random as in the papers. Without it the
comparison mostly measures an algorithm's initial bias: WOA's and RSCDWOA's pull towards the
origin of the box is a pull towards the straight line in this encoding, so they found
feasible fixed-wing paths in paper 001's world while BA, IBA-ABC, CFO and MCFO never did.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmplan import optimizers
from swarmplan.core import PlanningContext
from swarmplan.geometry.polyline import Fillet, densify, fillet_path
from swarmplan.planner.cores import static_leg_hit
from swarmplan.planner.cost_models import PathContext, make_cost
from swarmplan.planner.encodings import PlaneEncoding, SplineEncoding
from swarmplan.planner.escape import model_turn_radius, static_clearance
from swarmplan.world.model import AgentSpec, World
from swarmplan.world.planner_config import GlobalConfig

RETRY_GROWTH = 1.5


def global_config(world: World) -> GlobalConfig:
    """``planner.global`` of ``world`` (validated by the world parser)."""
    return world.planner_config.global_


@dataclass
class AgentProblem:
    """The encoding and cost model of one agent's global path."""

    encoding: PlaneEncoding
    model: Any
    margin: float

    def cost(self, X: np.ndarray) -> np.ndarray:
        nodes = self.encoding.decode(X)
        return self.model(nodes, self.encoding.dense(X, nodes))


def agent_problem(world: World, agent: AgentSpec, cfg: GlobalConfig) -> AgentProblem:
    span = float(np.linalg.norm(agent.goal - agent.start))
    # Default clearance: half the APF influence distance, so the route stays where the static
    # repulsion is weak and the pursuit of the route's points is not pushed off them.
    margin = cfg.margin or max(agent.radius, 0.5 * world.planner_config.apf.influence)
    lateral = cfg.lateral or span / 2
    vertical = cfg.vertical or float(world.bounds_max[2] - world.bounds_min[2])
    lo = world.bounds_min + agent.radius + margin
    hi = world.bounds_max - agent.radius - margin
    lo[2] = world.bounds_min[2] + max(agent.min_altitude, agent.radius + margin)
    hi = np.maximum(hi, lo)
    step = max(2.0 * (agent.radius + margin), span / 200)
    cls = SplineEncoding if cfg.encoding == "spline" else PlaneEncoding
    kw = {"samples": cfg.samples} if cls is SplineEncoding else {}
    alt = max(agent.min_altitude, world.terrain_clearance, agent.radius + margin)
    floor = (lambda xy: world.terrain_height(xy) + alt) if world.peaks else None
    enc = cls(agent.start, agent.goal, cfg.waypoints, lateral, vertical, lo, hi, step=step, floor=floor, **kw)
    # The altitude floor rises from the start's/goal's own height over two plane spacings, so
    # a path through waypoints at the floor is valid however low the user put its ends.
    ctx = PathContext(world, agent, margin=margin, ramp=2.0 * span / (cfg.waypoints + 1))
    return AgentProblem(enc, make_cost(cfg.cost, ctx, cfg.weights), margin)


def validate_path(sim: PlanningContext, i: int, path: np.ndarray, inflate: float) -> str | None:
    """What the agent's sphere (radius + ``inflate``) touches along ``path`` (FCL, static world), or None.

    The start and the goal may lie closer to the ground or an obstacle than the inflated radius
    (a take-off from the ground): the legs leaving the start and reaching the goal are swept
    with the margin those points have (never less than the bare radius).
    """
    radius = float(sim.params.radius[i])
    ends = static_clearance(sim, path[[0, -1]], radius)
    n = len(path) - 1
    for k, (p0, p1) in enumerate(zip(path[:-1], path[1:], strict=True)):
        margin = inflate
        if k == 0:
            margin = min(margin, max(0.0, 0.5 * float(ends[0])))
        if k == n - 1:
            margin = min(margin, max(0.0, 0.5 * float(ends[1])))
        r = radius + margin
        if sim.collision.sweep_bounds(p1):
            return "bounds"
        hit = sim.collision.sweep_terrain(p0, p1, r) or sim.collision.sweep_static(p0, p1, r)
        if hit is not None:
            return hit
    return None


def shortcut_path(sim: PlanningContext, i: int, path: np.ndarray, inflate: float) -> np.ndarray:
    """Greedy pruning of a valid path: from each kept vertex, jump to the farthest later one whose
    straight leg FCL finds clear (radius + ``inflate``), that enters no avoided threat core
    (:mod:`swarmplan.planner.cores`) and whose climb angle the agent can fly.

    The metaheuristics' best paths at a planning budget often keep detours the cost barely
    penalizes (a zig-zag across free space); pruning them is the usual post-processing of
    sampled and evolved paths. Fixed wings are left as planned: removing vertices can sharpen
    the remaining turns below the minimum turn radius that the cost model enforced.
    """
    if sim.params.fixed_wing[i]:
        return path
    r = float(sim.params.radius[i]) + inflate
    max_climb = float(sim.params.max_climb[i])
    kept, j = [0], 0
    while j < len(path) - 1:
        nxt = j + 1
        for k in range(len(path) - 1, j + 1, -1):
            leg = path[k] - path[j]
            climb = math.atan2(abs(leg[2]), float(np.hypot(leg[0], leg[1])))
            if climb > max_climb:
                continue
            a, b = path[j], path[k]
            if not static_leg_hit(sim, a, b, r):
                nxt = k
                break
        kept.append(nxt)
        j = nxt
    return path[kept]


def fillet_route(sim: PlanningContext, i: int, path: np.ndarray, inflate: float) -> Fillet:
    """``path`` with its corners turned into arcs of the agent's turn radius (paper 004 §6:
    ρ = v²/a at cruise for a multirotor, eq 34; the minimum turn radius for a fixed wing).
    An arc that FCL finds touching something (the same sweep as :func:`validate_path`) or that
    enters an avoided threat core keeps its corner, as does one that does not fit between the
    neighbouring corners."""
    r = float(sim.params.radius[i]) + inflate

    def hits(arc: np.ndarray) -> bool:
        for a, b in zip(arc[:-1], arc[1:], strict=True):
            if sim.collision.sweep_bounds(b):
                return True
            if static_leg_hit(sim, a, b, r):
                return True
        return False

    return fillet_path(path, model_turn_radius(sim, i), collision_check=hits)


def route_spacing(world: World, agent: AgentSpec) -> float:
    """Spacing of the route's points: the APF's quadratic radius (so the next point is far enough for
    the full, conic attraction) but at least the sim's waypoint reach (3 steps at cruise speed)."""
    return max(
        world.goal_tolerance, 3.0 * agent.speed_cruise * world.dt, world.planner_config.apf.quadratic_radius
    )


def plan_global_routes(sim: PlanningContext, optimizer_name: str) -> dict[int, np.ndarray]:
    """Plan every agent's whole path with ``optimizer_name``; {agent index: route (K, 3)} for valid plans."""
    world: World = sim.world
    cfg = global_config(world)
    opt_cfg = world.planner_config.optimizer
    population = cfg.population or opt_cfg.population
    iterations = cfg.iterations or opt_cfg.iterations
    params = dict(opt_cfg.params) if opt_cfg.name == optimizer_name else {}
    opt = optimizers.make(optimizer_name, population=population, **params)
    opt.warm_up()  # compiled code loads here, not inside planning_ms
    routes: dict[int, np.ndarray] = {}
    for i, agent in enumerate(world.agents):
        rng = sim.rng_for("global", i)
        prob = agent_problem(world, agent, cfg)
        enc = prob.encoding
        t0 = time.perf_counter()
        for attempt in range(cfg.retries + 1):
            budget = int(population * iterations * RETRY_GROWTH**attempt)
            x0 = enc.warm_start() if cfg.warm_start else None
            res = opt.minimize(prob.cost, enc.lower, enc.upper, max_evals=budget, seed=rng, x0=x0)
            sim.record_optimizer(i, "global", optimizer_name, res, t=0.0)
            nodes = enc.decode(res.x[None])
            dense = enc.dense(res.x[None], nodes)
            violation = float(prob.model.violation(nodes, dense)[0])
            # FCL on the planned polyline itself (its vertices are on the route).
            hit = validate_path(sim, i, nodes[0], 0.5 * prob.margin) if violation == 0 else None
            if violation == 0 and hit is None:
                break
        path = nodes[0]
        valid = violation == 0 and hit is None
        if valid and cfg.shortcut:
            path = shortcut_path(sim, i, path, 0.5 * prob.margin)
        fillet = fillet_route(sim, i, path, 0.5 * prob.margin) if valid else None
        if fillet is not None:
            path = fillet.points
        route = densify(path, route_spacing(world, agent))
        detail = {
            "algorithm": optimizer_name,
            "cost_model": cfg.cost,
            "encoding": cfg.encoding,
            "best_cost": round(float(res.f), 6),
            "length": round(float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum()), 6),
            "planning_ms": round((time.perf_counter() - t0) * 1000.0, 3),
            "attempts": attempt + 1,
            "planned_length": round(float(np.linalg.norm(np.diff(nodes[0], axis=0), axis=1).sum()), 6),
        }
        if violation > 0 or hit is not None:
            detail["reason"] = (
                f"best path violates constraints (violation {violation:.3g})"
                if violation > 0
                else f"best path touches '{hit}' (FCL)"
            )
            detail["fallback"] = "no route: reactive flight (APF with escapes) to the goal"
            sim.note_event(i, "global_plan_invalid", detail)
            continue
        detail["waypoints"] = np.round(path, 3).tolist()
        detail["fillet"] = {
            "radius": round(model_turn_radius(sim, i), 6),
            "arcs": fillet.arcs,
            "broken_points": fillet.broken,
        }
        detail["planned_waypoints"] = np.round(nodes[0], 3).tolist()
        sim.note_event(i, "global_plan", detail)
        routes[i] = route[1:]
    return routes
