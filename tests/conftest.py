"""Settings for the whole test run: the on-disk cache of the static guide's tables lives in a
fresh folder of its own (never the user's cache, and empty at the start, so the suite computes
the tables once and reads them back after: both paths run). Under pytest-xdist (``-n``) every
worker process has its own folder; the compiled kernels are shared through numba's cache,
whose files are written whole (a temporary file renamed into place), so workers compiling the
same kernel at once both leave a whole entry."""

from __future__ import annotations

import os
import shutil
import tempfile

_FOLDER: list[str] = []


def pytest_configure(config) -> None:
    _FOLDER.append(tempfile.mkdtemp(prefix="swarmplan-test-cache-"))
    os.environ["SWARMPLAN_CACHE_DIR"] = _FOLDER[0]


def pytest_unconfigure(config) -> None:
    for folder in _FOLDER:
        shutil.rmtree(folder, ignore_errors=True)
