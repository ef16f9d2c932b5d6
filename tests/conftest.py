"""Settings for the whole test run: the on-disk cache of the static guide's tables lives in a
fresh folder of its own (never the user's cache, and empty at the start, so the suite computes
the tables once and reads them back after: both paths run). Under pytest-xdist (``-n``) every
worker process has its own folder; the compiled kernels are shared through numba's cache,
whose files are written whole (a temporary file renamed into place), so workers compiling the
same kernel at once both leave a whole entry.

On a cold kernel cache (a fresh clone, or an edited kernel source: a new folder of compiled
code, ``swarmplan.runtime.compiled``) an xdist run first compiles the kernels most tests use,
once, by running the package's own commands on small worlds (:data:`WARM_UP`, its chains side
by side), before the workers start. Otherwise every worker, and every command a test runs in a
process of its own, would compile the same kernels again while the others do (numba's cache
only helps a process that starts after an entry is written), about a third of a fresh run's
CPU time. The tests compute the same with a cold or a warm cache; only who compiles
changes."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_FOLDER: list[str] = []

WARM_UP: tuple[tuple[str, ...], ...] = (
    (  # a small world (field, guide), a fixed wing, an escape (segment costs, decoder), then a
        # sphere of 64 agents flown home (the arrived agents' evasion and swept checks at swarm size)
        "-m swarmplan.run worlds/quickstart.yaml --max-time 1 --out {tmp}/q.mcap --quiet",
        "-m swarmplan.run worlds/fixed_wing.yaml --max-time 1 --out {tmp}/f.mcap --quiet",
        "-m swarmplan.run worlds/traps/u_pocket.yaml --max-time 12 --no-guide --out {tmp}/u.mcap --quiet",
        "-m swarmplan.bench swarm --sizes 64 --seeds 1 --scenarios sphere --out {tmp}/swarm",
    ),
    (  # every optimizer, then a swarm of 64 agents among movers (the swarm-size kernels)
        "-m swarmplan.bench overhead --evals 2000 --repeats 1",
        "-m swarmplan.bench sim --agents 64 --movers 16 --sim-time 1",
    ),
)
"""Chains of commands (``python`` arguments, run in order within a chain, the chains at once) that
compile the kernels of most tests into a cold cache; ``{tmp}`` is a folder removed afterwards."""


def pytest_configure(config) -> None:
    _FOLDER.append(tempfile.mkdtemp(prefix="swarmplan-test-cache-"))
    os.environ["SWARMPLAN_CACHE_DIR"] = _FOLDER[0]
    if not hasattr(config, "workerinput") and getattr(config.option, "numprocesses", None):
        warm_cold_kernel_cache()


def warm_cold_kernel_cache() -> None:
    """In an xdist run's main process, before its workers start: warm a cold kernel cache."""
    from swarmplan.runtime.compiled import PACKAGE_ROOT, use_kernel_cache

    if PACKAGE_ROOT.parent != ROOT:  # the tests import another checkout's package
        return
    folder = use_kernel_cache(PACKAGE_ROOT, "swarmplan")
    if any(folder.rglob("*.nbi")):
        return
    warm_kernel_cache(WARM_UP)


def warm_kernel_cache(chains: tuple[tuple[str, ...], ...]) -> None:
    """Run each chain of commands (``python ARGS``, in the repository) in a thread of its
    own and wait for all. A command that fails is left to the tests to find."""
    tmp = tempfile.mkdtemp(prefix="swarmplan-warm-up-")
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = dict(os.environ, PYTHONPATH=path)

    def run(chain: tuple[str, ...]) -> None:
        for args in chain:
            command = [sys.executable, *(a.format(tmp=tmp) for a in args.split())]
            out = subprocess.DEVNULL
            try:
                subprocess.run(command, cwd=ROOT, env=env, stdout=out, stderr=out, timeout=600, check=False)
            except subprocess.TimeoutExpired:
                return

    threads = [threading.Thread(target=run, args=(chain,)) for chain in chains]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    shutil.rmtree(tmp, ignore_errors=True)


def pytest_unconfigure(config) -> None:
    for folder in _FOLDER:
        shutil.rmtree(folder, ignore_errors=True)
