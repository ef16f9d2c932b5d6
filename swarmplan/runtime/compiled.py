"""The compiled (numba) kernels, loaded in one place, at their first use.

numba's import and the loading of a kernel module's cached machine code cost ~0.5-1 s of CPU
per process, so no module imports a kernel module (``_*kernel*.py``, ``sweep_kernels.py``) at
its top: the code that runs a kernel asks :func:`kernel_module` for it when it first needs it,
e.g. ``kernel_module("swarmplan.geometry.sweep_kernels")``, and each module is imported once
per process. Whether a computation runs compiled never depends on what a process happens to
have loaded already: the world decides (``swarmplan.geometry.compiled.use_compiled``).
"""

from __future__ import annotations

import importlib
import sys
from functools import cache
from types import ModuleType


@cache
def kernel_module(name: str) -> ModuleType:
    """The compiled kernel module ``name`` (its full dotted name in this package), imported, and
    numba with it, at the first call; the same module afterwards."""
    if not name.startswith("swarmplan."):
        raise ValueError(f"kernel_module: expected a module of swarmplan, got {name!r}")
    return importlib.import_module(name)


def numba_loaded() -> bool:
    """Whether numba is in the process already (then a kernel whose numpy twin gives the same
    bits costs only its own cached code to load, not numba's)."""
    return "numba" in sys.modules
