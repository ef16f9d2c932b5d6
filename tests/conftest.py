"""Settings for the whole test run: the on-disk cache of the static guide's tables lives in a
fresh folder of its own (never the user's cache, and empty at the start, so the suite computes
the tables once and reads them back after: both paths run). Under pytest-xdist (``-n``) the
workers share that folder, made by the process that starts them: a world's tables computed by
one worker are read back by the other (its entries are written whole, a temporary file renamed
into place, so workers writing the same entry at once both leave a whole one). The compiled
kernels are shared the same way, through numba's cache.

Python's bytecode is written and read (``__pycache__`` beside each source, as Python does by
default) even where ``PYTHONDONTWRITEBYTECODE`` is set: the run starts many processes (the
workers, and the commands the tests run) that import the same unchanged sources, and without
bytecode on disk each compiles the package and, in each worker, rewrites the test modules'
asserts afresh (seconds of CPU per process). The clone's ``__pycache__`` folders already hold
the package's compiled kernels, and git ignores them. The setting is made before pytest-xdist
starts its workers, so they and every process a test starts inherit it."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile

_FOLDER: list[str] = []


def pytest_configure(config) -> None:
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.dont_write_bytecode = False
    if hasattr(config, "workerinput") and os.environ.get("SWARMPLAN_CACHE_DIR"):
        return  # a pytest-xdist worker: the folder made by the process that started it
    _FOLDER.append(tempfile.mkdtemp(prefix="swarmplan-test-cache-"))
    os.environ["SWARMPLAN_CACHE_DIR"] = _FOLDER[0]


def pytest_unconfigure(config) -> None:
    for folder in _FOLDER:
        shutil.rmtree(folder, ignore_errors=True)
