"""From which swarm size the simulation runs compiled (numba) per-step work, and where it
loads the compiled geometry.

Below ``COMPILED_FROM`` agents the numpy (and FCL) paths run: numba's one-time load (its
import and the cached machine code, ~0.9 s CPU per process) costs more than a small world's
whole run saves, and a 16-agent world would not reach its first step within 0.5 s. From it
on (swarm scale) the field, the nearest surfaces, the agents' clearance and the swept
checks are compiled kernels. Both paths give the same bits (the kernels follow
numpy's formulas and order of sums, rotations stay with numpy's BLAS; the swept checks
decide exactly what FCL decides), so a world runs identically either way
(tests/test_field_kernels.py, tests/test_sweep_kernels.py, tests/test_geometry_neighbours.py).
The choice depends on the world only, never on what a process has loaded before. The
potential field (``flight.apf``) runs its compiled kernel from ``COMPILED_FROM`` agents and,
below, numpy (the same bits) for its first ``FIELD_NUMPY_CALLS`` calls, then the kernel: a
small world reaches its first step without loading numba, and a long run pays numba's load
once instead of numpy's per-call overhead for good (the choice reads the world's size and
the field's own count of calls; and, the bits being the same, the kernel also runs as soon
as numba is in the process for other work, e.g. the guide's kernels).
"""

from __future__ import annotations

from types import ModuleType

from swarmplan.runtime.compiled import kernel_module

COMPILED_FROM = 49
"""Swarm size (agents in the world) from which the compiled geometry kernels run."""

FIELD_NUMPY_CALLS = 600
"""Calls of a world's field that run numpy below ``COMPILED_FROM`` agents before it goes
compiled: numba's load (~0.3 s of CPU with the field's cached kernel) costs about as much as
this many numpy calls of a 16-agent field (0.36-0.5 ms each, against 0.04 ms compiled), so no
run pays more than about twice the cheaper of the two."""

CHECKS_COMPILED_FROM = COMPILED_FROM
"""Swarm size from which the swept checks (``first_hits``, arrivals, near misses, agent
contacts, the braking margin's free distances) run compiled: the same rule as the field. Their
answers are exact on both paths, so this is a speed choice only (its own name lets the tests
run either path)."""


def use_compiled(n_agents: int) -> bool:
    """Whether a world of ``n_agents`` agents runs the compiled per-step field."""
    return n_agents >= COMPILED_FROM


def field_numpy_calls(n_agents: int) -> int:
    """How many calls of the field of a world of ``n_agents`` agents run numpy before it goes
    compiled (none at swarm size)."""
    return 0 if use_compiled(n_agents) else FIELD_NUMPY_CALLS


def use_compiled_checks(n_agents: int) -> bool:
    """Whether a world of ``n_agents`` agents runs the compiled swept checks."""
    return n_agents >= CHECKS_COMPILED_FROM


def field_kernels() -> ModuleType:
    """:mod:`swarmplan.geometry._field_kernels` (numba loads with it at the first call)."""
    return kernel_module("swarmplan.geometry._field_kernels")


def sweep_kernels() -> ModuleType:
    """:mod:`swarmplan.geometry.sweep_kernels` (numba loads with it at the first call)."""
    return kernel_module("swarmplan.geometry.sweep_kernels")
