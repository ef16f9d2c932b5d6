"""World files: load, validate and resolve a YAML world into typed, immutable objects.

The contract is ``shared/spec/world-format.md``. Validation collects *every* problem with
its path (``agents[1].start: inside obstacle 'tower'``) and suggests the nearest key for
typos; :class:`WorldError` carries the list.

- :mod:`~swarmplan.world.model`: the frozen dataclasses (``World``, ``Obstacle``, ...)
- :mod:`~swarmplan.world.schema`: raw mapping -> model (``parse_world``)
- :mod:`~swarmplan.world.checks`: placements against bounds, obstacles and terrain
- :mod:`~swarmplan.world.terrain`: the Gaussian-peaks terrain
- :mod:`~swarmplan.world.io`: ``load_world`` from a file
"""

from swarmplan.world.io import load_world
from swarmplan.world.model import AgentSpec, Motion, Obstacle, Peak, Threat, World, WorldError
from swarmplan.world.planner_config import PlannerConfig
from swarmplan.world.schema import parse_world

__all__ = [
    "AgentSpec",
    "Motion",
    "Obstacle",
    "Peak",
    "PlannerConfig",
    "Threat",
    "World",
    "WorldError",
    "load_world",
    "parse_world",
]
