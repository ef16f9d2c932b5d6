"""Artificial potential field for all agents at once: forces in, commanded velocities out.

Terms (all per agent, summed in one compiled pass, :mod:`swarmplan.flight._apf_kernel`):
- attraction to the goal, quadratic within ``quadratic_radius`` and conic beyond;
- repulsion from obstacle *surfaces* (true signed distances and their gradients),
  ``k_rep (1/rho - 1/rho0)`` inside the influence distance ``rho0``, scaled by the
  goal-distance factor ``min(1, d_goal/rho0)^n`` plus its companion term (of the static
  bodies) pulling along the agent's way, towards its point of attraction (Ge & Cui's
  modified APF) so a goal beside an obstacle stays reachable; a guided agent's static
  repulsion is scaled by ``Flyers.static_scale``;
- the same from the terrain/ground (vertical clearance) and the faces of ``bounds``, scaled
  as the static bodies;
- moving obstacles: repulsion at the predicted closest approach within ``horizon`` seconds,
  the agent flying on at its speed towards its point of attraction (relative-velocity term,
  with the goal factor), with a right-hand bias that breaks head-on symmetry (head-on: to the
  left where a static body or a face of the flight volume hems the right side in within the
  mover's radius and the agent's, over both where both sides are; the same on a collision
  course where less room than the miss still needed lies on the agent's side of the mover's
  path);
- other agents: an ellipsoidal ``separation`` metric, current and predicted, whose range
  comes from the two agents' own motion, not from ``influence``: beyond the distance both
  need to brake from the speeds they fly at (plus a step of reaction each,
  :func:`reach_at_speed`; at most from cruise speed, :func:`stopping_reach`) a neighbour is
  no threat, and a longer range only pushes a dense swarm apart and holds agents off goals
  that sit close together. A range sized for cruise held agents slowed by a crowd off each
  other as if they still flew at cruise: the antipodal sphere's centre (64 agents) jammed,
  paths 1.29x the straight line, the last arrival 18 s where ORCA-3D's is 12 s (13 s with
  the current speeds). Fixed wings keep the range from cruise (they cannot slow down to
  stop). Head-on and many-way encounters are broken by a right-hand component about the
  relative velocity. The predicted term weighs a closest approach ``tau`` s ahead by
  ``field_law.urgency``, ``(1 - tau / horizon)^2``: flat where a conflict enters the horizon,
  so a crowd converging on one point does not brake as one in the step its conflicts come
  into view. Its gain left out scales with the pull at cruise (``k_agent = 0.5 k_att
  influence``, ``world.schema.default_field_scale``). On beliefs (``Swarm.view``), each pair's
  ellipsoid widens by how far the other may be from where it is believed (``Swarm.doubt``);
- parked agents: at rest they need no room to brake, so their repulsion reaches only the
  flyer's own braking distance at its current speed (:func:`reach_at_speed`) beyond the
  separation ellipsoid: a slow agent closing in on its goal beside a parked neighbour is
  not held off by a range sized for two agents at cruise;
- priority near goals: arrived (parked) agents, and agents farther from their goals than the
  agent itself, repel as static bodies do, with its goal factor, for agents that can stop
  (multirotors): near its goal an agent goes on through the crowd and the others give way
  (without it, neighbours hovering by their own goals hold each other off for good). Fixed
  wings keep the full repulsion of flying agents (they cannot stop, so the standstill the
  factor resolves does not arise), but fixed wings loitering about their goals
  (``Swarm.yields``) give way to every flyer: their repulsion takes its goal factor (pushed off
  its final approach by a neighbour circling its own goal a turn radius away, an aircraft
  missed its goal by a little and flew its whole approach circle again); the loiterer still
  feels the arriving agent in full and makes room.
Each multirotor flies the field at its own scale (``kinematics.field_scales``): the influence,
the quadratic radius and ``k_agent`` times its room over the largest agent's (four braking
distances from cruise speed each), ``k_rep`` times its square, so a drone that brakes in
centimetres is pushed by the bodies within its own reach, not by every body within the metres
the fastest agent of its world needs (the field's shape is the same at every scale).
The point of attraction (``Flyers.target``) is the goal, or a segment's or route's waypoint, or
for an agent whose straight line is blocked by a static obstacle the point ahead on its way
round it (:mod:`swarmplan.flight.guide`, which also scales that agent's static repulsion).
The force's direction becomes the commanded velocity; its speed is the cruise speed, cut
so a multirotor can still brake before the goal, and so the agent can before any obstacle
surface ahead (a fixed wing does not brake for its goal, :func:`speed_floor`).

The field has two implementations with the same bits: the compiled kernel, and numpy
(:mod:`swarmplan.flight._apf_numpy`, no numba to load) for the first calls of a world below
swarm size (``swarmplan.runtime.compiled.field_numpy_calls``) while numba is not in the
process (once something else has loaded it, e.g. the guide's kernels, the kernel costs no more
to load than its own cached code). The bits are the same, so this is a speed choice only.
The numpy reference the tests compare both with, sums in another order, lives in
tests/apf_reference.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from swarmplan.flight import _apf_numpy
from swarmplan.flight.kinematics import AgentParams, safety_margin
from swarmplan.geometry.vec3 import dot3, norm3
from swarmplan.runtime.compiled import field_numpy_calls, kernel_module, read_only, use_numpy_twin

if TYPE_CHECKING:
    from swarmplan.world.model import World
    from swarmplan.world.planner_config import ApfConfig

_EPS = 1e-9
_NO_ROWS = np.zeros(0, dtype=np.int64)
_NO_DOUBT = np.zeros(0)

WINDOW_FROM = 128
"""Swarm size from which the field's agent term tests only the agents within a window along x
of each flyer (``_apf_kernel.apf_forces``: the same forces, fewer pair tests)."""


@dataclass(frozen=True)
class FieldInputs:
    """Geometry seen by the active agents this step (computed by the simulation); a moving
    obstacle at distance inf is one that agent does not see (beyond its sensing range)."""

    obstacle_distance: np.ndarray  # (N, M) signed distance from agent centre to obstacle surface
    obstacle_gradient: np.ndarray  # (N, M, 3)
    obstacle_velocity: np.ndarray  # (M, 3), zero for static obstacles
    obstacle_moving: np.ndarray  # (M,) bool
    obstacle_radius: np.ndarray  # (M,) bounding radius (prediction of moving bodies)
    obstacle_center: np.ndarray  # (M, 3)


@dataclass(frozen=True)
class Flyers:
    """The agents the field is computed for: rows of the swarm ``idx`` at ``pos``/``vel`` heading
    for ``goal``. ``target`` (default ``goal``) is the point of attraction, e.g. the next waypoint
    of a route or segment (the goal-distance factor always uses the real goal); ``static_scale``
    (n,) scales the repulsion of static obstacles per agent (default 1)."""

    idx: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    goal: np.ndarray
    target: np.ndarray | None = None
    static_scale: np.ndarray | None = None


@dataclass(frozen=True)
class Swarm:
    """Every agent of the world (``pos``/``vel`` (N, 3)); ``parked`` (N,) marks those that no
    longer fly (arrived, stopped), which repel as static bodies (with the goal factor);
    ``goal_distance`` (N,) each one's distance to its goal (default: none nearer than any
    flyer to its own, i.e. no priority between flying agents).

    With ``view`` (flyers, N), the swarm as each flyer believes it (``swarmplan.sim.network``):
    ``pos``, ``vel``, ``parked`` and ``goal_distance`` are a table of believed states, one row
    each, ``row_agent`` (rows,) whose state each row is, and ``view[k, b]`` the row flyer k holds
    of agent b (-1: it knows nothing of b); ``doubt`` (rows,) how far, m, each row's agent may
    be from where it is believed (default 0), by which the pair's separation ellipsoid widens
    on every axis; ``yields`` (rows,) marks those that give way to every flyer (fixed wings
    loitering about their goals): their repulsion takes the flyer's goal factor, as a parked
    agent's does for a multirotor."""

    pos: np.ndarray
    vel: np.ndarray
    parked: np.ndarray | None = None
    goal_distance: np.ndarray | None = None
    view: np.ndarray | None = None
    row_agent: np.ndarray | None = None
    doubt: np.ndarray | None = None
    yields: np.ndarray | None = None


def reach_at_speed(params: AgentParams, idx: np.ndarray, vel: np.ndarray, dt: float) -> np.ndarray:
    """Per agent ``idx[i]`` flying at ``vel[i]``: the distance it needs to be out of a parked
    agent's way from its *current* speed ``v``, one step of reaction and then braking to a
    stop (``v dt + v^2 / (2 a)``) for a multirotor; a fixed wing (which cannot stop, and
    keeps the full range of parked agents) its :func:`stopping_reach` from cruise speed.
    A parked agent needs no room of its own (it is at rest), so the pair's repulsion reaches
    this far beyond the separation ellipsoid and no farther: an agent closing in slowly on
    its goal beside a parked neighbour is not held off by a range sized for two agents at
    cruise speed. Two multirotors flying need the sum of their two values (at most the sum
    of their :func:`stopping_reach`): slowed by a crowd, they need less room than at cruise."""
    v = norm3(vel)
    stop = v * dt + v * v / (2.0 * np.maximum(params.max_accel[idx], _EPS))
    return np.where(params.fixed_wing[idx], stopping_reach(params, dt)[idx], stop)


def stopping_reach(params: AgentParams, dt: float) -> np.ndarray:
    """Per agent: the distance it covers from cruise speed until it is out of another's way,
    one step of reaction and then, for a multirotor, braking to a stop at ``max_accel``
    (``v dt + v^2 / (2 a)``), for a fixed wing (which cannot stop) a turn at its minimum
    radius (``v dt + min_turn_radius``). Two agents' repulsion reaches at most the sum of
    their two values beyond their separation ellipsoid (two multirotors: less while slower,
    :func:`reach_at_speed`), and at most the field's ``influence``."""
    v = params.speed_cruise
    stop = v * v / (2.0 * np.maximum(params.max_accel, _EPS))
    return v * dt + np.where(params.fixed_wing, params.min_turn_radius, stop)


class ApfField:
    """The potential field of one world: its gains (``planner.apf``), agents and terrain.

    ``forces(flyers, field, swarm)`` is the total force on every flyer, shape (n, 3).
    """

    def __init__(self, world: World, params: AgentParams, gains: ApfConfig | None = None):
        self.world = world
        self.params = params
        self.gains = world.planner_config.apf if gains is None else gains
        self.reach_per_agent = np.ascontiguousarray(stopping_reach(params, world.dt))
        self.can_stop = np.ascontiguousarray(~params.fixed_wing)
        # Each agent's own field, the world's scaled (kinematics.field_scales; 1 without).
        scales = params.field_scale
        self.field_scale = np.ones(len(params.radius)) if scales is None else np.asarray(scales, dtype=float)
        g = self.gains
        gains_ = (
            g.k_att,
            g.k_rep,
            g.influence,
            g.k_agent,
            g.quadratic_radius,
            g.goal_power,
            g.k_moving,
            g.horizon,
        )
        self._gains = tuple(float(v) for v in gains_)
        self._floor = float(world.terrain_clearance) if world.peaks else 0.0
        self._reach = current_reach(params, self.reach_per_agent, self.gains.influence)
        # reach_at_speed's constant parts, computed once: the same floats in the same order.
        self._brake_denominator = 2.0 * np.maximum(params.max_accel, _EPS)
        # One denominator for every agent: the reaches of rows at the same velocities are the same.
        den = self._brake_denominator
        self._one_denominator = bool(len(den) and (den == den[0]).all())
        self._any_fixed_wing = bool(params.fixed_wing.any())
        self._numpy_calls = field_numpy_calls(len(world.agents), self._any_fixed_wing)  # then compiled

    @property
    def agent_reach(self) -> float:
        """Distance between centres beyond which another agent's current repulsion is zero
        (:func:`current_reach`)."""
        return self._reach

    def _reach_at_speed(self, idx: np.ndarray | None, vel: np.ndarray) -> np.ndarray:
        """:func:`reach_at_speed` of agents ``idx`` (None: the first ``len(vel)``, in order)."""
        if self._any_fixed_wing:
            idx = np.arange(len(vel)) if idx is None else idx
            return np.ascontiguousarray(reach_at_speed(self.params, idx, vel, self.world.dt))
        if use_numpy_twin():  # the kernel's formula in numpy (the same bits): numba stays unloaded
            v = norm3(vel)
            denominator = self._brake_denominator[: len(vel)] if idx is None else self._brake_denominator[idx]
            return np.ascontiguousarray(v * self.world.dt + v * v / denominator)
        rows = _NO_ROWS if idx is None else np.asarray(idx, dtype=np.int64)
        vel = np.ascontiguousarray(vel, dtype=float)
        out = np.empty(len(vel))
        return kernel_module("swarmplan.flight._apf_kernel").reach_at_speed(
            vel, rows, self._brake_denominator, self.world.dt, out
        )

    def forces(self, flyers: Flyers, field: FieldInputs, swarm: Swarm) -> np.ndarray:
        n = len(flyers.idx)
        out = np.empty((n, 3))
        if n == 0:
            return out
        w, p = self.world, self.params
        pos, goal = flyers.pos, flyers.goal
        h = w.terrain_height(pos[:, :2])
        gh = w.terrain_gradient(pos[:, :2])
        h_goal = w.terrain_height(goal[:, :2])
        # A target equal to the goal is the same field as no target (the quadratic well included).
        tgt = goal if flyers.target is None else flyers.target
        scale = np.ones(n) if flyers.static_scale is None else np.asarray(flyers.static_scale, dtype=float)
        all_pos, all_vel, shape = swarm.pos, swarm.vel, swarm.pos.shape[:-1]
        parked = np.zeros(shape, dtype=bool) if swarm.parked is None else swarm.parked
        goal_dist = swarm.goal_distance
        goal_dist = np.full(shape, -np.inf) if goal_dist is None else np.asarray(goal_dist, dtype=float)
        yields = np.zeros(shape, dtype=bool) if swarm.yields is None else swarm.yields
        yields = np.asarray(yields, dtype=np.bool_)
        idx = np.asarray(flyers.idx, dtype=np.int64)
        reach_now = self._reach_at_speed(flyers.idx, flyers.vel)
        reach = self._reach * (1.0 + 1e-9) + 1e-9
        if swarm.view is None:  # one swarm for every flyer
            view = np.zeros((0, 0), dtype=np.int64)
            if flyers.vel is all_vel and self._one_denominator and not self._any_fixed_wing:
                reach_all = reach_now  # (every agent flies: the same rows, the same values)
            else:
                reach_all = self._reach_at_speed(None, all_vel)
            doubt = _NO_DOUBT
        else:  # each flyer's own beliefs: its rows of the table
            view = np.ascontiguousarray(swarm.view, dtype=np.int64)
            reach_all = self._reach_at_speed(np.asarray(swarm.row_agent, dtype=np.int64), all_vel)
            doubt = np.zeros(len(all_pos)) if swarm.doubt is None else np.asarray(swarm.doubt, dtype=float)
        if self._numpy_calls > 0 and use_numpy_twin():
            self._numpy_calls -= 1
            apf_forces = _apf_numpy.apf_forces  # the same bits, without numba to load
        else:
            apf_forces = kernel_module("swarmplan.flight._apf_kernel").apf_forces
        apf_forces(
            (pos, flyers.vel, goal, tgt, scale, idx, reach_now, self.field_scale[idx]),
            (p.radius, p.separation, p.min_altitude, self.reach_per_agent, self.can_stop),
            (field.obstacle_distance, field.obstacle_gradient, field.obstacle_moving,
             read_only(field.obstacle_center), field.obstacle_velocity, field.obstacle_radius),
            (h, gh, h_goal, self._floor, w.bounds_min, w.bounds_max),
            (all_pos, all_vel, np.asarray(parked, dtype=np.bool_), goal_dist, reach_all, view, doubt, yields),
            reach,
            self._gains,
            out,
            (view.shape[1] if swarm.view is not None else len(all_pos)) >= WINDOW_FROM,
        )  # fmt: skip
        return out


def current_reach(params: AgentParams, reach_per_agent: np.ndarray, influence: float) -> float:
    """Distance between centres beyond which another agent's *current* repulsion is zero:
    the largest semi-axis of the pair's separation ellipsoid plus both stopping reaches (at
    most ``influence``), maximised over the pairs of agent kinds (the predicted term adds the
    relative motion)."""
    rows = np.column_stack([params.separation, params.radius, reach_per_agent])
    # Usually every agent is of one kind; np.unique over rows costs more than the rest.
    kinds = rows[:1] if (rows == rows[0]).all() else np.unique(rows, axis=0)
    sep = np.maximum(kinds[:, None, :3], kinds[None, :, :3])
    scale = sep + (kinds[:, None, 3] + kinds[None, :, 3])[..., None]
    return float((scale.max(axis=-1) + np.minimum(kinds[:, None, 4] + kinds[None, :, 4], influence)).max())


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(norm3(v, keepdims=True), _EPS)


def speed_floor(params: AgentParams, idx: np.ndarray) -> np.ndarray:
    """The slowest command of agents ``idx`` before the surface brake: a fixed wing's cruise
    speed, 0 for a multirotor (it stops). A fixed wing does not stop at its goal: it flies
    through its tolerance and loiters on, so braking towards it buys nothing and would fly
    its capture turns at its minimum speed, the edge of its envelope, with no speed left
    below to take up a lead on its path (an autopilot following that path could not fall
    back onto it); and a command below its minimum speed would leave the surface brake
    weighing a speed it never flies."""
    return np.where(params.fixed_wing[idx], params.speed_cruise[idx], 0.0)


def commanded_velocity(
    params: AgentParams,
    idx: np.ndarray,
    force: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    clearance: np.ndarray,
    clearance_dir: np.ndarray,
    dt: float,
) -> np.ndarray:
    """:func:`commanded_velocity_numpy` in one compiled pass over the rows (the same bits,
    tests/test_apf_compiled.py); numpy itself until numba is in the process (a small world's
    steps never load numba for it)."""
    if use_numpy_twin():
        return commanded_velocity_numpy(params, idx, force, pos, goal, clearance, clearance_dir, dt)
    f = np.ascontiguousarray
    return kernel_module("swarmplan.flight._apf_kernel").commanded_velocity(
        params.max_accel[idx], params.speed_cruise[idx], speed_floor(params, idx),
        safety_margin(params.radius[idx]),
        f(force, dtype=float), f(pos, dtype=float), f(goal, dtype=float), f(clearance, dtype=float),
        f(clearance_dir, dtype=float), float(dt), np.empty((len(idx), 3)),
    )  # fmt: skip


def commanded_velocity_numpy(
    params: AgentParams,
    idx: np.ndarray,
    force: np.ndarray,
    pos: np.ndarray,
    goal: np.ndarray,
    clearance: np.ndarray,
    clearance_dir: np.ndarray,
    dt: float,
) -> np.ndarray:
    """Velocity command from the force: cruise speed along it, slowed to brake before the goal
    (never below the agent's :func:`speed_floor`: a fixed wing flies on at its cruise speed,
    slowed only by the surface brake and its model's minimum speed) and before the nearest surface ahead
    (``clearance`` (n,), outward normal ``clearance_dir``).
    Towards a surface the speed is what still brakes at the agent's safety margin from it
    (``kinematics.safety_margin``: a fifth of its radius, at most 0.25 m, the room the safety
    filter keeps from every surface; a stand-off in metres held lab drones a body length and
    more short of goals beside a wall), unless the goal is nearer than the surface: the goal's
    cap (a stop within 0.8 of the goal's distance) then keeps the agent off the surface. Within
    a step of that margin (a gap ``g`` under ``|v| dt``), a multirotor's speed towards it is also
    no more than lets a stop along the whole command ``v`` (one step at ``v``, then braking at
    ``max_accel``: the safety filter's braking margin, ``sim.safety``) fit in the gap: with ``t``
    the speed along the surface and ``w`` the speed towards it, ``w (t + w) / (2 a) + w dt <= g``
    (``|v| <= t + w``), or the first cap times ``g / (|v| dt)`` when that is more (the two meet
    without a jump at a step's distance). A command that slides along a surface at its margin
    keeps its speed along it; with the first cap alone, a small component towards the surface
    left the braking margin to cut the whole speed, each step more as the gap closed, until the
    agent stood beside the surface for good. Farther out the braking margin slows a command
    that closes in along its whole length, which keeps its direction (a path flown along a
    planned arc keeps the arc's curvature)."""
    amax = params.max_accel[idx]
    speed = params.speed_cruise[idx].copy()
    dg = norm3(goal - pos)
    speed = np.maximum(np.minimum(speed, np.sqrt(2.0 * 0.8 * amax * dg)), speed_floor(params, idx))
    v = _unit(force) * speed[:, None]
    # Component towards the nearest surface may not exceed what can still be braked.
    toward = -dot3(v, clearance_dir)
    gap = np.maximum(clearance - safety_margin(params.radius[idx]), 0.0)
    allowed = np.sqrt(2.0 * 0.8 * amax * gap)
    along = v + toward[:, None] * clearance_dir
    c = norm3(along) / (2.0 * amax) + dt
    stops = (speed_floor(params, idx) == 0.0) & (gap < speed * dt)  # within a step of the margin
    with np.errstate(invalid="ignore", divide="ignore"):  # (the other rows' values are not taken)
        stop = 2.0 * gap / (np.sqrt(c * c + 2.0 * gap / amax) + c)  # w of w (t + w) / (2 a) + w dt = g
        stop = np.maximum(stop, allowed * (gap / (speed * dt)))  # meets the first cap at a step
    allowed = np.where(stops, np.minimum(allowed, stop), allowed)
    allowed = np.where(dg < clearance, np.maximum(allowed, speed), allowed)
    excess = np.maximum(toward - allowed, 0.0)
    return v + excess[:, None] * clearance_dir
