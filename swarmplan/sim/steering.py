"""The potential field's commands for the flying agents of one step.

The field (threat cores repel like static spheres), the points of attraction (segments and
routes from :mod:`~swarmplan.sim.navigation`, the guide's ways round static obstacles, whose
guide is built anew when a mover comes to rest for good, the points straight ahead of the fixed
wings that cannot turn onto their goals yet, :mod:`~swarmplan.flight.capture`, the points ahead
on their circles of the fixed wings that loiter about their goals, :mod:`~swarmplan.sim.loiter`),
the clearance to the nearest static surface and the commanded velocity within each agent's
kinematic limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarmplan.core import SwarmState
from swarmplan.flight.apf import ApfField, FieldInputs, Flyers, Swarm, commanded_velocity, stopping_reach
from swarmplan.flight.capture import GoalCapture, height_first
from swarmplan.flight.guide import StaticGuide, make_guide
from swarmplan.flight.kinematics import AgentParams
from swarmplan.flight.sight import Sight
from swarmplan.geometry.vec3 import norm3
from swarmplan.sim.deconflict import BrakingLook, braking_room, oldest_age
from swarmplan.sim.loiter import Loiter
from swarmplan.sim.metrics import Tally
from swarmplan.sim.navigation import Navigator
from swarmplan.sim.network import Beliefs, Network
from swarmplan.sim.network_passes import belief_doubt
from swarmplan.sim.obstacles import Obstacles
from swarmplan.sim.threats import nearest_with_cores, threat_cores, with_cores
from swarmplan.world.model import World
from swarmplan.world.motion import next_rest


@dataclass
class Commands:
    """The field's commands for the flying agents ``idx`` (rows in that order)."""

    velocity: np.ndarray  # (n, 3) commanded velocities
    position: np.ndarray  # (n, 3) the agents' positions
    goal: np.ndarray  # (n, 3) their goals
    obstacle_distance: np.ndarray  # (n, obstacles) surface distances at the step's start
    clearance: np.ndarray  # (n,) to the nearest static surface (threat cores included)
    ended: Tally  # segments and routes that ended on the way
    beliefs: Beliefs | None = None  # with comms: what they believe of the others
    oldest: np.ndarray | None = None  # with comms: per row the oldest state acted on (s; nan: none)


class Steering:
    """The field, the guide, the navigator and the loiter circles of one run (reset with :meth:`reset`)."""

    def __init__(self, world: World, params: AgentParams, obstacles: Obstacles):
        self.world, self.params, self.obstacles = world, params, obstacles
        self.apf = ApfField(world, params)
        # The way round static obstacles for agents whose straight line is blocked (None without any).
        self.guide: StaticGuide | None = make_guide(world, params)
        self._guide_at = 0.0  # the time the guide's bodies are at rest for good from
        self._rest_at = next_rest(world, 0.0)  # when the next mover comes to rest for good
        self._threat_cores = threat_cores(world)
        self.navigator = Navigator(world, params, self.guide)
        self.loiter = Loiter(params)  # arrived fixed wings circle their goals
        self.sight = Sight(len(world.agents))  # fixed wings' clear lines (swarmplan.flight.sight)
        self.capture = GoalCapture(params)  # fixed wings' final approach (swarmplan.flight.capture)
        # With comms: what each agent has heard of the others.
        self.network = None
        if world.comms is not None:
            reach = stopping_reach(params, world.dt)
            self.network = Network(world.comms, world.sensing, params.max_accel, reach, world.dt)
        self.sensing_range = math.inf if world.sensing is None else world.sensing.range
        self._look = BrakingLook(params, world.dt)  # how far the braking room looks
        self._oldest = 0.0  # the age of the oldest state any flyer acted on in the last step

    def reset(self, start: np.ndarray, goal: np.ndarray) -> None:
        """Back to the bodies at rest at t = 0 (a mover parked in the last run), the guide's ways
        from ``start`` to ``goal``, no loiter circles."""
        self._oldest = 0.0
        self.loiter.reset()
        self.sight.reset()
        self.capture.reset()
        if self._guide_at > 0.0:
            self._new_guide(0.0)
        if self.guide is not None:
            self.guide.reset(start, goal)

    def _new_guide(self, t: float) -> None:
        """The guide round the bodies at rest for good at ``t``."""
        self._guide_at, self._rest_at = t, next_rest(self.world, t)
        self.sight.reset()
        self.guide = self.navigator.guide = make_guide(self.world, self.params, t)

    def commands(
        self,
        s: SwarmState,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        distances: tuple[np.ndarray, np.ndarray],
        q0: np.ndarray,
        qv0: np.ndarray,
        parked: np.ndarray,
    ) -> Commands:
        """The commands of flying agents ``idx`` of state ``s`` at the step's start (every agent
        at ``pos0`` moving at ``vel0``): ``distances`` the distances and gradients of every agent to
        the obstacles at poses ``q0`` moving at ``qv0``; ``parked`` the agents that no longer fly."""
        mv = self.obstacles.moving_mask
        if len(idx) == len(pos0):  # every agent flies: the rows are the cache's (read only)
            d, g = distances
            p_idx, v_idx, goal_idx = pos0, vel0, s.goal.copy()
        else:
            # (take: the rows [idx] gives, without its general indexing's cost)
            d, g = distances[0].take(idx, axis=0), distances[1].take(idx, axis=0)
            p_idx, v_idx, goal_idx = pos0.take(idx, axis=0), vel0.take(idx, axis=0), s.goal.take(idx, axis=0)
        if self.sensing_range < math.inf and mv.any():  # movers beyond sensing range are not seen
            d = np.where(mv[None, :] & (d > self.sensing_range), np.inf, d)
        inputs = FieldInputs(d, g, qv0 * mv[:, None], mv, self.obstacles.bounding_radius, q0)
        if self._threat_cores is not None:  # threats[i].avoid: cores repel like static spheres
            inputs = with_cores(inputs, p_idx, self._threat_cores)
        target, rep_scale, ended = self.navigator.attraction_targets(s, idx)
        if self._rest_at <= s.t:  # a mover parked for good: go round it too
            self._new_guide(s.t)
        if self.guide is not None:
            at, goals = pos0[idx], s.goal[idx]
            target, rep_scale = self.guide.targets(s.step, idx, at, goals, target, rep_scale)
            target, rep_scale = self.sight.targets(self.guide, s.step, idx, at, goals, target, rep_scale)
        if self.capture.any:  # a fixed wing that cannot turn onto its goal yet extends
            at_goal = (target == s.goal[idx]).all(axis=1)
            target = self.capture.targets(s.t, idx, pos0[idx], vel0[idx], s.goal[idx], target)
            # ... or, when it could not loiter after flying through it, approaches it on a circle
            target = self.loiter.approach(
                idx, pos0[idx], vel0[idx], s.goal[idx], at_goal, target, self.obstacles
            )
            # ... winning its goal's height first, to pass it level
            target = height_first(self.params, idx, pos0[idx], s.goal[idx], at_goal, target)
        if self.loiter.on.any():  # a point ahead on its circle is a loitering agent's target and goal
            rows = np.flatnonzero(self.loiter.on[idx])
            ahead = self.loiter.targets(idx[rows], pos0[idx[rows]])
            target, goal_idx = np.array(target, dtype=float), goal_idx.copy()
            target[rows] = goal_idx[rows] = ahead
        flyers = Flyers(idx, p_idx, v_idx, goal_idx, target, rep_scale)
        to_go = norm3(s.goal - pos0)
        b = oldest = None
        if self.network is None:
            yields = self.loiter.on.copy() if self.loiter.on.any() else None  # loiterers give way
            swarm = Swarm(pos0, vel0, parked, to_go, yields=yields)
        else:  # each flyer's own beliefs of the others
            # The pairs found with the beliefs reach as far as the field and the braking room
            # look (the oldest state a step older than the last step's oldest).
            look = self._look.radius(self._oldest + self.world.dt)
            near = max(self.apf.agent_reach, look)
            b = self.network.beliefs(
                idx, s.t, pos0, vel0, parked, to_go, near=near, yields=self.loiter.on, reuse=True
            )
            self._oldest = oldest_age(b)
            # Beliefs moved on with the acceleration sent: the truth may be off by twice the
            # doubt of a belief moved on at the velocity sent (that acceleration since reversed).
            doubt = 2.0 * belief_doubt(self.params.max_accel[b.agent], b.age)
            pos_b, vel_b, yields = b.expected_pos, b.expected_vel, (b.yields if b.yields.any() else None)
            swarm = Swarm(pos_b, vel_b, b.parked, b.goal_distance, b.view, b.agent, doubt, yields)
            oldest = self.network.oldest(b, self.apf.agent_reach)
        force = self.apf.forces(flyers, inputs, swarm)
        clearance, normal = self.obstacles.nearest_surface(idx, p_idx, d, g)
        if self._threat_cores is not None:
            cores, radius = self._threat_cores, self.params.radius[idx]
            clearance, normal = nearest_with_cores(clearance, normal, p_idx, radius, cores)
        v_cmd = commanded_velocity(self.params, idx, force, p_idx, goal_idx, clearance, normal, self.world.dt)
        if b is not None:  # room to stop behind the agents ahead, as far as it knows them
            v_cmd = braking_room(self.params, b, v_cmd, self.world.dt, self._look)
        return Commands(v_cmd, p_idx, goal_idx, d, clearance, ended, b, oldest)
