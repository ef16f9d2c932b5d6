"""Refinement planning on top of the potential field: escapes, smoothing, global routes.

:class:`RefinementPlanner` implements the simulation's ``Planner`` protocol
(``swarmplan.sim``): ``on_reset`` asks the global-path planner for routes when
``planner.mode`` is ``global``; ``on_stuck`` plans an escape segment (or a yield in a
deadlock between agents, see :mod:`swarmplan.planner.escape`); ``on_step`` starts yield
segments planned for other agents and curvature-smoothing segments
(:mod:`swarmplan.planner.smoothing`) when ``planner.smoothing.enabled``.
"""

from __future__ import annotations

import numpy as np

from swarmplan.core import PlannedSegment, PlanningContext, StuckOutcome
from swarmplan.planner.escape import EscapePlanner
from swarmplan.planner.smoothing import CurvatureSmoother, fillet_path
from swarmplan.world.model import World, WorldError
from swarmplan.world.planner_config import check_escape, check_global

__all__ = ["RefinementPlanner", "fillet_path", "make_planner", "validate_planner_settings"]


def validate_planner_settings(world: World) -> None:
    """Check ``planner.escape`` and ``planner.global`` of ``world`` again; raise one ``WorldError``
    listing every problem. ``load_world`` / ``parse_world`` already do this; it is for worlds
    whose planner mapping was replaced afterwards (``World.with_overrides``)."""
    problems: list[str] = []
    for check in (check_escape, check_global):
        try:
            check(world.planner)
        except WorldError as exc:
            problems += exc.problems
    if problems:
        raise WorldError(problems)


class RefinementPlanner:
    """The planner the simulation calls; ``optimizer_name`` names the metaheuristic it uses."""

    def __init__(self, world: World, optimizer_name: str):
        self.world = world
        self.optimizer_name = optimizer_name
        self.escape = EscapePlanner(world, optimizer_name)
        self.smoother = CurvatureSmoother(self.escape)
        self.smoothing = world.planner_config.smoothing

    def on_reset(self, sim: PlanningContext) -> dict[int, np.ndarray]:
        self.escape.escapes.clear()
        self.escape.pending.clear()
        self.escape.failures.clear()
        self.escape.stand_downs.clear()
        self.smoother.reset()
        if self.world.planner_config.mode != "global":
            return {}
        # here, not at import: the cost models and encodings are only needed for global plans
        from swarmplan.planner.global_path import plan_global_routes

        return plan_global_routes(sim, self.optimizer_name)

    def on_stuck(self, sim: PlanningContext, agent: int) -> StuckOutcome:
        return self.escape.on_stuck(sim, agent)

    def on_step(self, sim: PlanningContext) -> dict[int, PlannedSegment]:
        out = self.escape.take_pending(sim)
        if self.smoothing:
            for i, seg in self.smoother.on_step(sim).items():
                out.setdefault(i, seg)
        return out


def make_planner(world: World, optimizer: str | None = None) -> RefinementPlanner | None:
    """The planner a run of ``world`` flies: the refinement planner with ``optimizer`` (default:
    the world's ``planner.optimizer.name``), or None for ``'none'`` (pure APF)."""
    name = world.planner_config.optimizer.name if optimizer is None else optimizer
    if name == "none":
        return None
    return RefinementPlanner(world, name)
