"""From which swarm size the simulation's per-step field runs compiled (numba), and the lazy
import of the compiled geometry.

Below ``COMPILED_FROM`` agents the numpy paths run: numba's one-time load (its import and
the cached machine code, ~0.9 s CPU per process) costs more than a small world's whole run
saves, and the start-up figure of issue 10 (a 16-agent world to after its first step,
<= 0.5 s) would not hold. From it on (swarm scale) the field, the nearest surfaces, the
agents' clearance are compiled kernels. Both paths give the same bits (the kernels follow
numpy's formulas and order of sums, rotations stay with numpy's BLAS), so a world runs
identically either way (tests/test_field_kernels.py); the choice depends on the world only.
The potential field has one implementation, compiled, for every world (``flight.apf``).
"""

from __future__ import annotations

from functools import cache
from types import ModuleType

COMPILED_FROM = 49
"""Swarm size (agents in the world) from which the compiled geometry kernels run."""


def use_compiled(n_agents: int) -> bool:
    """Whether a world of ``n_agents`` agents runs the compiled per-step field."""
    return n_agents >= COMPILED_FROM


@cache
def field_kernels() -> ModuleType:
    """:mod:`swarmplan.geometry._field_kernels`, imported (and numba with it) at first use."""
    from swarmplan.geometry import _field_kernels

    return _field_kernels
