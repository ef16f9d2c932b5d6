"""The obstacles as the simulation sees them: the FCL world for swept checks, the distance
field for the potential field and clearances, which obstacles move, and their poses."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from swarmplan.core import ObstacleStates
from swarmplan.flight.kinematics import AgentParams
from swarmplan.geometry.batch import ShapeBatch
from swarmplan.geometry.bodies import code_of
from swarmplan.geometry.collision import CollisionWorld
from swarmplan.geometry.neighbours import agent_clearance_indexed
from swarmplan.geometry.rotation import matrix_to_quaternion
from swarmplan.runtime.compiled import kernel_module, use_compiled
from swarmplan.sim.evasion import MoverSurfaces
from swarmplan.world.model import World
from swarmplan.world.motion import max_speed, poses_at


class Obstacles:
    """Everything about a world's obstacles that stays fixed over a run."""

    def __init__(self, world: World, params: AgentParams):
        self.world = world
        self.params = params
        self.collision = CollisionWorld(world)
        # Distances batched by shape type (one array operation per shape, meshes by their grid),
        # equal to ObstacleField's; min_distance stays exact for meshes. Swarm-sized worlds
        # compute the field and the nearest surfaces compiled (runtime.compiled.use_compiled), and
        # so do worlds with fixed wings.
        self.compiled = use_compiled(len(world.agents), bool(params.fixed_wing.any()))
        self.distances = ShapeBatch(world.obstacles, compiled=self.compiled)
        self.moving_mask = np.array([o.moving for o in world.obstacles], dtype=bool)
        self._static_mask = ~self.moving_mask
        self.bounding_radius = np.array([o.bounding_radius for o in world.obstacles])
        self.max_obstacle_speed = max((max_speed(o) for o in world.obstacles), default=0.0)
        self._moving = world.moving_obstacles
        self._moving_idx = np.flatnonzero(self.moving_mask)
        self.mover_ids = tuple(o.id for o in self._moving)
        self.mover_radii = self.bounding_radius[self.moving_mask]  # read every guarded step
        # Movers whose bounding sphere is their surface (spheres): no surface to measure apart.
        self._round_movers = self.distances.code[self.moving_mask] == code_of("sphere")
        self._round_movers.setflags(write=False)
        self._static_pos = np.array([o.position for o in world.obstacles], dtype=float).reshape(-1, 3)
        self._poses: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._at_rest: tuple[np.ndarray, np.ndarray] | None = None  # the poses when nothing moves
        self.moving_quat = [
            matrix_to_quaternion(o.rotation).round(9).tolist() for o in world.moving_obstacles
        ]

    def poses(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Every obstacle's position and velocity at ``t`` (read-only arrays).

        A step asks for its start and end time and the log for the end time again, and the
        next step starts there: the last two answers are kept (exact, a function of ``t``), and
        only the moving obstacles are evaluated (one Python call each)."""
        if not self._moving_idx.size:  # nothing moves: the same poses at every time
            if self._at_rest is None:
                pos, vel = self._static_pos.copy(), np.zeros_like(self._static_pos)
                pos.flags.writeable = vel.flags.writeable = False
                self._at_rest = (pos, vel)
            return self._at_rest
        hit = self._poses.get(t)
        if hit is not None:
            return hit
        pos, vel = self._static_pos.copy(), np.zeros_like(self._static_pos)
        pos[self._moving_idx], vel[self._moving_idx] = poses_at(self._moving, t)
        pos.flags.writeable = vel.flags.writeable = False
        if len(self._poses) >= 2:
            del self._poses[next(iter(self._poses))]
        self._poses[t] = (pos, vel)
        return pos, vel

    def movers(
        self, q: np.ndarray, qv: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
        """The moving obstacles at poses ``q`` moving at ``qv``: centres, velocities, bounding radii, ids."""
        mv = self.moving_mask
        return q[mv], qv[mv], self.mover_radii, self.mover_ids

    def mover_surfaces(self, q: np.ndarray) -> MoverSurfaces:
        """The moving obstacles' surfaces at poses ``q`` (every obstacle's row), for the threat
        test of arrived agents (``swarmplan.sim.evasion``)."""
        cols = self._moving_idx
        batch = self.distances

        def distance(points: np.ndarray, movers: np.ndarray) -> np.ndarray:
            return batch.pair_distance(points, cols[movers], q)

        def nearest(points: np.ndarray, movers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            d, g = batch.query(points, q)
            k, c = np.arange(len(points)), cols[movers]
            return d[k, c], g[k, c]

        return MoverSurfaces(distance, nearest, self._round_movers)

    def surface_of(
        self, pos: np.ndarray, distances: tuple[np.ndarray, np.ndarray]
    ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """``rows -> (clearance, normal)`` of :meth:`nearest_surface` for agents ``rows`` at ``pos``
        with the distances and gradients ``distances`` of every agent to every obstacle."""

        def surface(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return self.nearest_surface(rows, pos[rows], distances[0][rows], distances[1][rows])

        return surface

    def nearest_surface(
        self, idx: np.ndarray, pos: np.ndarray, d: np.ndarray, g: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Clearance and outward normal of the closest static surface (obstacles, terrain) per agent."""
        r = self.params.radius[idx]
        h = self.world.terrain_height(pos[:, :2])
        gh = self.world.terrain_gradient(pos[:, :2])
        if self.compiled:
            clear, normal = np.empty(len(idx)), np.empty((len(idx), 3))
            kernels = kernel_module("swarmplan.geometry._distance_kernels")
            # the heights contiguous whatever the number of agents: one compiled signature
            pz = np.ascontiguousarray(pos[:, 2])
            kernels.nearest_surface(d, g, self._static_mask, r, pz, h, gh, clear, normal)
            return clear, normal
        clear = pos[:, 2] - h - r
        normal = np.stack([-gh[:, 0], -gh[:, 1], np.ones(len(idx))], axis=1)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        static = ~self.moving_mask
        if static.any():
            ds = d[:, static] - r[:, None]
            j = np.argmin(ds, axis=1)
            dj = ds[np.arange(len(idx)), j]
            closer = dj < clear
            clear = np.where(closer, dj, clear)
            normal = np.where(closer[:, None], g[:, static][np.arange(len(idx)), j], normal)
        return clear, normal

    def agent_clearance(self, pos: np.ndarray) -> np.ndarray:
        """Per agent: surface distance to the nearest other agent."""
        # Through a k-d tree: equal to the all-pairs minimum (tests/test_geometry_neighbours.py).
        return agent_clearance_indexed(pos, self.params.radius)

    def clearances(
        self, pos: np.ndarray, q: np.ndarray, d: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per agent at ``pos``: its clearance to the obstacles at poses ``q`` (``d`` their surface
        distances when at hand; exact for meshes too, whose grid is a lower bound; inf without
        obstacles), to the other agents and to the terrain."""
        r = self.params.radius
        if len(self.world.obstacles):
            obstacles = self.distances.min_distance(pos, q, d) - r
        else:
            obstacles = np.full(len(pos), np.inf)
        terrain = pos[:, 2] - self.world.terrain_height(pos[:, :2]) - r
        return obstacles, self.agent_clearance(pos), terrain

    def obstacle_states(self, t: float) -> ObstacleStates | None:
        """The ``/obstacles/state`` entries at ``t`` (None when nothing moves)."""
        moving = self._moving
        if not moving:
            return None
        pos, vel = self.poses(t)
        pos, vel = pos[self._moving_idx], vel[self._moving_idx]
        if self.compiled:  # both roundings in one compiled call (the same bits)
            pos, vel = kernel_module("swarmplan.sim._step_kernels").round6(pos, vel)
            return ObstacleStates(self.mover_ids, pos, self.moving_quat, vel)
        return ObstacleStates(self.mover_ids, np.round(pos, 6), self.moving_quat, np.round(vel, 6))
