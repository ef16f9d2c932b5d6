"""The typed world: frozen dataclasses a validated world file resolves into.

``World.resolved`` is the same world as a plain mapping (defaults applied, mesh geometry
inlined), but for the planner settings, which the world carries once, typed
(``World.planner_config``): together they make the ``/world`` message of the log
(:meth:`World.to_message`).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmplan import __version__
from swarmplan.geometry import bodies
from swarmplan.world import terrain
from swarmplan.world.comms import Comms, Sensing
from swarmplan.world.errors import WorldError as WorldError  # re-exported: the model module names it too
from swarmplan.world.planner_config import PlannerConfig, planner_config

SHAPES = bodies.NAMES

MOTIONS = ("linear", "waypoints", "circle")

MODELS = ("multirotor", "fixed_wing")

THREAT_KINDS = ("radar", "missile", "artillery", "weather")

PLANNER_MODES = ("reactive", "global")


@dataclass(frozen=True)
class Motion:
    type: str
    velocity: np.ndarray | None = None  # linear
    waypoints: np.ndarray | None = None  # waypoints (k, 3), path starts at the obstacle's position
    speed: float = 0.0
    loop: bool = False
    center: np.ndarray | None = None  # circle
    radius: float = 0.0
    angular_speed: float = 0.0


@dataclass(frozen=True)
class Obstacle:
    id: str
    shape: str
    position: np.ndarray  # centre at t = 0 (mesh: origin of the mesh frame)
    rotation: np.ndarray  # 3x3 matrix, R = Rz(yaw) Ry(pitch) Rx(roll)
    rotation_deg: tuple[float, float, float]
    radius: float = 0.0
    size: np.ndarray | None = None  # box full extents
    height: float = 0.0  # cylinder full height; capsule straight section
    vertices: np.ndarray | None = None  # mesh vertices in the local frame, scale applied
    faces: np.ndarray | None = None
    motion: Motion | None = None
    params: dict[str, Any] | None = None  # the shape's keys as validated (``bodies.Shape.keys``)

    @property
    def moving(self) -> bool:
        return self.motion is not None

    @property
    def shape_params(self) -> dict[str, Any]:
        """The shape's parameters by their world-format keys: ``params``, or for an obstacle
        built without them, its ``radius``, ``size`` and ``height`` as the shape takes them."""
        if self.params is not None:
            return self.params
        return {k.name: getattr(self, k.name) for k in bodies.shape(self.shape).keys}

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about ``position`` containing the whole shape."""
        if self.shape == "mesh":
            return float(np.max(np.linalg.norm(self.vertices, axis=1)))
        return bodies.shape(self.shape).bound(self.shape_params)


@dataclass(frozen=True)
class Peak:
    center: np.ndarray  # (2,)
    height: float
    spread: np.ndarray  # (2,)


@dataclass(frozen=True)
class Threat:
    kind: str
    position: np.ndarray
    r_min: float
    r_max: float
    weight: float
    avoid: bool = False  # local flight keeps out of the core (the ball of radius r_min)


@dataclass(frozen=True)
class AgentSpec:
    id: str
    start: np.ndarray
    goal: np.ndarray
    model: str
    radius: float
    speed_min: float
    speed_max: float
    speed_cruise: float
    max_accel: float
    min_turn_radius: float
    max_climb_angle: float  # radians
    min_altitude: float
    separation: np.ndarray  # (3,)
    roll_rate: float = 0.0  # rad/s, fixed wings (0: none given, a multirotor)
    clearance: float = 0.0  # m from every body, fixed wings (a multirotor: its radius)

    @property
    def field_room(self) -> float:
        """The range of the potential field this agent needs: ``2 v^2 / a`` (four braking
        distances from cruise speed), at least two of its radii (``planner.apf.influence`` left
        out is the largest of a world's agents, ``schema.default_influence``)."""
        return max(2.0 * self.speed_cruise**2 / max(self.max_accel, 1e-9), 2.0 * self.radius)


@dataclass(frozen=True)
class World:
    name: str
    seed: int
    bounds_min: np.ndarray
    bounds_max: np.ndarray
    dt: float
    max_time: float
    goal_tolerance: float
    peaks: tuple[Peak, ...]
    terrain_clearance: float
    obstacles: tuple[Obstacle, ...]
    threats: tuple[Threat, ...]
    agents: tuple[AgentSpec, ...]
    planner_config: PlannerConfig
    log_path: str
    resolved: dict[str, Any] = field(repr=False)  # the /world message but planner (before seed/version)
    source: Path | None = None
    comms: Comms | None = None  # state broadcasts between agents (None: every agent knows the truth)
    sensing: Sensing | None = None  # onboard sensing range (None: unlimited)

    @property
    def planner(self) -> dict[str, Any]:
        """The planner settings as a plain mapping (a copy: ``planner_config.to_dict()``), as the
        world file and the ``/world`` message have them."""
        return self.planner_config.to_dict()

    @property
    def static_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if not o.moving)

    @property
    def moving_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if o.moving)

    def terrain_height(self, xy: np.ndarray) -> np.ndarray:
        """Terrain height z(x, y) (sum of Gaussian peaks); 0 without terrain."""
        return terrain.height(self.peaks, xy)

    def terrain_gradient(self, xy: np.ndarray) -> np.ndarray:
        """(dz/dx, dz/dy) of the terrain at ``xy`` (..., 2)."""
        return terrain.gradient(self.peaks, xy)

    def to_message(self, seed: int) -> dict[str, Any]:
        """The ``/world`` message of a run with ``seed``: the resolved world, seed and version."""
        msg: dict[str, Any] = {}
        for key, value in self.resolved.items():
            msg[key] = value
            if key == "agents":  # the message's order of sections
                msg["planner"] = self.planner_config.to_dict()
        msg["seed"] = seed
        msg["swarmplan_version"] = __version__
        return msg

    def with_overrides(self, **changes: Any) -> World:
        """A copy with ``max_time``, ``planner`` (a mapping, validated into ``planner_config``) or
        ``seed`` replaced; ``resolved`` (the ``/world`` message) follows. Other fields are refused:
        they would leave ``resolved`` out of step."""
        unknown = sorted(set(changes) - {"max_time", "planner", "seed"})
        if unknown:
            raise ValueError(
                f"with_overrides: cannot override {', '.join(unknown)} (max_time, planner, seed)"
            )
        resolved = copy.deepcopy(self.resolved)
        if "max_time" in changes:
            resolved["sim"]["max_time"] = changes["max_time"]
        if "planner" in changes:
            changes["planner_config"] = planner_config(changes.pop("planner"))
        if "seed" in changes:
            resolved["seed"] = changes["seed"]
        return dataclasses.replace(self, resolved=resolved, **changes)
