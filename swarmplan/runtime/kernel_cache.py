"""Whether numba's machine code for the package's kernels is cached on this machine.

The kernels (``@njit(cache=True)``) compile the first time they run and are cached beside
their sources (``__pycache__/<module>.<function>-<line>.py<version>.nbi``); a source changed
since its index was written compiles again. :func:`uncompiled_kernel_modules` tells, without
importing numba, which kernel modules have no fresh cache, so a first run can say why it takes
a while instead of looking frozen.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
COMPILE_NOTICE = (
    "compiling the numerical kernels for this machine (first run: about 10-30 s, once; "
    "later runs load them in under a second)"
)


_CACHED_KERNEL = re.compile(r"^@njit\(.*cache=True", re.MULTILINE)


def kernel_modules(root: Path = PACKAGE) -> list[Path]:
    """The package's modules with cached compiled kernels."""
    return sorted(p for p in root.rglob("*.py") if _CACHED_KERNEL.search(p.read_text(encoding="utf-8")))


def uncompiled_kernel_modules(modules: list[Path] | None = None) -> list[Path]:
    """Of ``modules`` (default: every kernel module), those without a cache index at least as
    new as their source."""
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    out = []
    for src in kernel_modules() if modules is None else modules:
        indexes = list((src.parent / "__pycache__").glob(f"{src.stem}.*.{tag}.nbi"))
        if not indexes or max(i.stat().st_mtime for i in indexes) < src.stat().st_mtime:
            out.append(src)
    return out
